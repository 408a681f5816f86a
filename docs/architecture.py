"""Draw docs/images/architecture.png: the workspace packages, their layers and declared dependencies.

Reads each member's pyproject.toml (so the picture follows the code), lays the packages out by layer
(docs/conventions.md, "Layers") and draws one arrow per declared silpose dependency, plus the data path
through the application layer. Run: ``.venv/bin/python docs/architecture.py``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyArrowPatch, FancyBboxPatch  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "images" / "architecture.png"

#: package -> (x, y) centre in axes units, one row per layer (bottom = lowest layer)
POSITION = {
    "shared": (0.50, 0.10),
    "datagen": (0.17, 0.38),
    "model": (0.50, 0.38),
    "segment": (0.83, 0.38),
    "app": (0.50, 0.62),
    "eval": (0.50, 0.86),
}
ROLE = {
    "shared": "conventions, rig + world frame, skeleton, contours,\ndataset format, metrics, atomic writes, seeds",
    "datagen": "Blender bodies, walk / mocap poses,\nrenderers, sharded Parquet datasets",
    "model": "MPPCA (EM), shape+structure model,\nconditioning, stature, model files",
    "segment": "background subtraction\n(NCC shadows, cleanup)",
    "app": "train / infer / rig / recordings:\nframes -> segment -> contours -> model -> joints",
    "eval": "paper experiments, baselines,\ntables and figures",
}
BOX_W, BOX_H = 0.30, 0.15


def declared_dependencies() -> dict[str, list[str]]:
    """package folder -> silpose packages it declares (from its pyproject.toml)."""
    deps = {}
    for name in POSITION:
        project = tomllib.loads((ROOT / name / "pyproject.toml").read_text())["project"]
        deps[name] = sorted(
            d.split("[")[0].removeprefix("silpose-")
            for d in project.get("dependencies", [])
            if d.startswith("silpose-")
        )
    return deps


def main() -> Path:
    fig, ax = plt.subplots(figsize=(10, 7.2))
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.08)
    ax.axis("off")
    for name, (x, y) in POSITION.items():
        ax.add_patch(FancyBboxPatch((x - BOX_W / 2, y - BOX_H / 2), BOX_W, BOX_H, boxstyle="round,pad=0.01",
                                    fc="#eef4fb" if name != "app" else "#fdf1e3", ec="#345", lw=1.4, zorder=2))
        ax.text(x, y + 0.035, f"{name}/  silpose.{name}", ha="center", va="center", fontsize=11, weight="bold", zorder=3)
        ax.text(x, y - 0.025, ROLE[name], ha="center", va="center", fontsize=8, zorder=3)
    for name, targets in declared_dependencies().items():
        for t in targets:
            (x0, y0), (x1, y1) = POSITION[name], POSITION[t]
            ax.add_patch(FancyArrowPatch((x0, y0 - BOX_H / 2), (x1, y1 + BOX_H / 2), arrowstyle="-|>",
                                         mutation_scale=12, color="#678", lw=1, zorder=1))
    ax.text(0.0, 1.06, "silpose: packages by layer; an arrow = a declared dependency (imports only go down)",
            fontsize=10, va="top")
    ax.text(0.0, 1.025, "benchmarks/ (not installed) measures all of them; the `silpose` command gathers each "
            "package's subcommands", fontsize=8.5, va="top", color="#444")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return OUT


if __name__ == "__main__":
    print(main())
