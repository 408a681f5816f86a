"""E5: example figures like the paper's Figs. 6 and 7.

One figure per chosen example: row 1 the noisy input contours of the given views (the true clean
contour in grey, dotted; views that are not given are marked "withheld"); row 2 the reconstructed
contours of EVERY view (solid; missing views are inferred and placed with their true normalisation)
over the true clean contour (grey, dotted), with each view's Chamfer distance; row 3 the inferred
3D stick figure (solid) against the truth (dotted), root-relative, with abbreviated joint names.
The example shown is the one whose pose error is closest to the median of its condition, so the
figure is typical rather than picked for looks.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from silpose.shared.metrics import chamfer_errors, pose_error_cm
from silpose.shared.skeleton import BONES, JOINT_NAMES, root_relative

from .plots import pyplot, save_figure

__all__ = ["median_example", "example_figure", "default_examples"]


def median_example(df, experiment: str, input_views: str) -> int | None:
    """sample_id of the example whose pose error is closest to the condition's median (None if absent)."""
    g = df[(df["experiment"] == experiment) & (df["input_views"] == input_views)]
    g = g[np.isfinite(g["pose_cm"].to_numpy())]
    if g.empty:
        return None
    med = float(np.median(g["pose_cm"]))
    return int(g.iloc[int(np.argmin(np.abs(g["pose_cm"].to_numpy() - med)))]["sample_id"])


def default_examples(n_views: int) -> list[tuple[str, tuple[int, ...], str]]:
    """(file stem, input views, caption) of the paper-like examples: one view given (Fig. 6, the
    second view) and one view missing (Fig. 7, the third view withheld)."""
    one = (min(1, n_views - 1),)
    missing = min(2, n_views - 1)
    three = tuple(v for v in range(n_views) if v != missing)
    out = [("e5_single_view", one, f"Pose from a single view (view {one[0]} only; cf. paper Fig. 6)")]
    if n_views > 1:
        out.append(("e5_missing_view", three, f"One missing view (view {missing} withheld; cf. paper Fig. 7)"))
    return out


def _abbrev(name: str) -> str:
    side, _, rest = name.partition("_")
    return (side + rest[:3]) if side in ("l", "r") and rest else name[:4]


def _crop(true: np.ndarray, noisy: np.ndarray | None, recon: np.ndarray, width: int, height: int,
          pad: float = 12.0) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) px: a box around the contours (finite points), padded, within the image grown by ``pad``."""
    pts = [true] + ([noisy] if noisy is not None else []) + ([recon] if np.all(np.isfinite(recon)) else [])
    p = np.vstack(pts)
    lo = np.maximum(p.min(0) - pad, -pad)
    hi = np.minimum(p.max(0) + pad, [width - 1 + pad, height - 1 + pad])
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


def _stick(ax, joints: np.ndarray, style: str, color: str, label: str, names: Sequence[str] | None = None) -> None:
    for a, b in BONES:
        ax.plot(*[joints[[a, b], i] for i in range(3)], style, color=color, lw=1.6)
    ax.plot([], [], style, color=color, label=label)
    if names is not None:
        for j, nm in enumerate(names):
            ax.text(*joints[j], _abbrev(nm), fontsize=5, color="dimgray")


def example_figure(evaluation, sample_id: int, input_views: Sequence[int], path: str | Path, title: str) -> Path:
    """Draw one example (see the module docstring) for ``evaluation`` (an Evaluation) and save a PNG."""
    d = evaluation.data
    idx = int(np.flatnonzero(d.test_ids == sample_id)[0])
    K = d.n_views
    noisy = evaluation.noisy(evaluation.config.noise)[idx : idx + 1]
    present = np.zeros((1, K), bool)
    present[0, list(input_views)] = True
    res = evaluation.model.infer(noisy, views_present=present, centroid=d.test_centroid[idx : idx + 1],
                                 scale=d.test_scale[idx : idx + 1])
    recon = np.full((1, K) + res.contours_px.shape[2:], np.nan)
    recon[:, list(res.views)] = res.contours_px
    one, _ = chamfer_errors(d.test_contours[idx : idx + 1], recon, d.image_size)
    pose = float(pose_error_cm(res.joints, d.test_joints[idx : idx + 1])[0])

    plt = pyplot()
    fig = plt.figure(figsize=(2.2 * K, 10.0))
    gs = fig.add_gridspec(3, K, height_ratios=[1, 1, 1.3])
    true = d.test_contours[idx]
    for k in range(K):
        h, w = d.image_size[k]
        for row in range(2):
            ax = fig.add_subplot(gs[row, k])
            x0, y0, x1, y1 = _crop(true[k], noisy[0, k] if present[0, k] else None, recon[0, k], w, h)
            ax.set_xlim(x0, x1)
            ax.set_ylim(y1, y0)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            closed = np.vstack([true[k], true[k][:1]])
            ax.plot(closed[:, 0], closed[:, 1], ":", color="gray", lw=1.2)
            if row == 0:
                if present[0, k]:
                    c = np.vstack([noisy[0, k], noisy[0, k][:1]])
                    ax.plot(c[:, 0], c[:, 1], "-", color="tab:blue", lw=1.0)
                    ax.set_title(f"view {k}: noisy input", fontsize=8)
                else:
                    ax.set_title(f"view {k}: withheld", fontsize=8)
                    ax.text(0.5, 0.03, "not given", transform=ax.transAxes, ha="center", va="bottom", fontsize=9,
                            color="tab:red")
            else:
                c = recon[0, k]
                if np.all(np.isfinite(c)):
                    c = np.vstack([c, c[:1]])
                    ax.plot(c[:, 0], c[:, 1], "-", color="tab:red", lw=1.2)
                tag = "inferred" if not present[0, k] else "reconstructed"
                ax.set_title(f"{tag}, Chamfer {one[0, k]:.1f} px", fontsize=8)
    ax3 = fig.add_subplot(gs[2, :], projection="3d")
    tj = root_relative(d.test_joints[idx])
    _stick(ax3, tj, ":", "black", "true")
    _stick(ax3, res.joints[0], "-", "tab:red", "inferred", JOINT_NAMES)
    pts = np.vstack([tj, res.joints[0]])
    mid = 0.5 * (pts.max(0) + pts.min(0))
    r = 0.5 * float((pts.max(0) - pts.min(0)).max())
    ax3.set_xlim(mid[0] - r, mid[0] + r)
    ax3.set_ylim(mid[1] - r, mid[1] + r)
    ax3.set_zlim(mid[2] - r, mid[2] + r)
    ax3.set_box_aspect((1, 1, 1))
    ax3.set_xlabel("x (m)", fontsize=7)
    ax3.set_ylabel("y (m)", fontsize=7)
    ax3.set_zlabel("z (m)", fontsize=7)
    ax3.tick_params(labelsize=6)
    ax3.legend(loc="upper left", fontsize=8)
    fig.suptitle(f"{title}\nsample {sample_id}: pose error {pose:.1f} cm, mean Chamfer "
                 f"{np.nanmean(one):.1f} px (grey dotted = true clean contour)", fontsize=9)
    return save_figure(fig, path)
