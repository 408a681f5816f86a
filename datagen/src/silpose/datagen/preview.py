"""Contact sheet of a dataset (``silpose preview DIR``): a few samples x all views.

Each cell shows the silhouette mask (grey), the stored contour (orange, start point marked), and
the 3D joints projected with the stored calibration as a stick figure (non-terminal joints blue
dots, terminal joints red crosses); a motion-capture sample's row names its clip and frame (``m``:
mirrored). Written with matplotlib's Agg backend.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_figure_atomic
from silpose.shared.dataset import iter_shards, list_shards
from silpose.shared.skeleton import BONES, N_JOINTS, TERMINAL_JOINTS

PREVIEW_NAME = "preview.png"


def pick_samples(root: Path, split: str, n_samples: int):
    """The first shard's ``n_samples`` evenly spaced samples, as a DatasetSplit slice; for a
    motion-library dataset the first sample of as many different activity groups as there are
    rows (then evenly spaced ones), so the sheet shows the variety."""
    path, shard = next(iter_shards(root, split, with_masks=True))
    idx = np.linspace(0, len(shard) - 1, min(n_samples, len(shard))).round().astype(int)
    clips = (shard.metadata.get("config", {}).get("motion") or {}).get("clips")
    if clips and all("group" in c for c in clips) and "clip" in shard.gait:
        c = np.asarray(shard.gait["clip"], np.int64)
        group = ["procedural walk" if k == 0 else clips[k]["group"] if 0 <= k < len(clips) else "?" for k in c]
        first = list({g: i for i, g in reversed(list(enumerate(group))) if g != "procedural walk"}.values())[::-1]
        first = sorted(first)[:n_samples]
        idx = np.array(first + [i for i in idx if i not in first][: n_samples - len(first)], int)
    return shard, idx


def _clip_label(shard, i: int) -> str:
    """``"\\n<clip> f<frame>"`` for a motion-capture sample (``m`` when mirrored; a second line for the legs of a
    part-mixed one), else ``""``."""
    clips = (shard.metadata.get("config", {}).get("motion") or {}).get("clips")
    if not clips or "clip" not in shard.gait:
        return ""
    c, f = int(shard.gait["clip"][i]), int(shard.gait["frame"][i])
    name = clips[c]["name"] if 0 <= c < len(clips) else f"clip {c}"
    if 0 <= c < len(clips) and "group" in clips[c]:  # a motion-library dataset: say the activity group too
        if c == 0:
            return "\nprocedural walk"
        name = f"{clips[c]['group']}: {name}"
    label = f"\n{name[:22]} f{f}{' m' if shard.gait.get('mirror', [0] * (i + 1))[i] else ''}"
    legs = int(shard.gait["legs_clip"][i]) if "legs_clip" in shard.gait else -1
    if 0 < legs < len(clips):  # part mixing: the legs of another frame
        label += f"\nlegs {clips[legs]['name'][:16]} f{int(shard.gait['legs_frame'][i])}"
    return label


def write_preview(root: str | Path, out: str | Path | None = None, n_samples: int = 4, split: str | None = None) -> Path:
    """Write the contact sheet PNG (default ``root/preview.png``) and return its path."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    root = Path(root)
    out = Path(out) if out is not None else root / PREVIEW_NAME
    if split is None:
        split = "train" if list_shards(root, "train") else "test"
    shard, idx = pick_samples(root, split, n_samples)
    K = shard.n_views
    px = np.moveaxis(shard.rig.project(shard.joints[idx].astype(np.float64)), 0, 1)  # (S, K, 19, 2)
    w, h = shard.rig.image_size
    fig, axes = plt.subplots(len(idx), K, figsize=(2.4 * K, 1.9 * len(idx)), squeeze=False)
    term = np.zeros(N_JOINTS, bool)
    term[list(TERMINAL_JOINTS)] = True
    for r, i in enumerate(idx):
        for k in range(K):
            ax = axes[r, k]
            ax.imshow(shard.masks[i, k], cmap="gray_r", vmin=0, vmax=3, interpolation="nearest")
            c = shard.contours[i, k]
            ax.plot(np.r_[c[:, 0], c[:1, 0]], np.r_[c[:, 1], c[:1, 1]], color="tab:orange", lw=0.8)
            ax.plot(c[0, 0], c[0, 1], "o", color="tab:orange", ms=3)
            for a, b in BONES:
                ax.plot(px[r, k, [a, b], 0], px[r, k, [a, b], 1], color="tab:blue", lw=0.8)
            ax.plot(px[r, k, ~term, 0], px[r, k, ~term, 1], ".", color="tab:blue", ms=2.5)
            ax.plot(px[r, k, term, 0], px[r, k, term, 1], "x", color="tab:red", ms=2.5)
            ax.set_xlim(-0.5, w - 0.5)
            ax.set_ylim(h - 0.5, -0.5)
            ax.set_xticks([])
            ax.set_yticks([])
            if r == 0:
                ax.set_title(shard.rig.names[k], fontsize=8)
            if k == 0:
                ax.set_ylabel(f"{split} #{int(shard.sample_id[i])}{_clip_label(shard, i)}", fontsize=7)
    fig.suptitle(f"{root.name}: mask, contour (orange), projected joints (blue; terminal x)", fontsize=8)
    fig.tight_layout()
    return write_figure_atomic(fig, out, dpi=110)
