"""The camera-frames evaluation's example figure (``frames_example.png``), in the style of the paper's Fig. 9.

One PNG, one column per camera of the model's rig:

- row 1, the camera frame (as recorded);
- row 2, the extracted silhouette (grey; cropped around it) with the model's reconstructed contour over it (red);
  views not used for this frame (no camera folder, empty or too small segmentation) are marked
  with the reason and left out, as in the paper's figure;
- row 3, the inferred 3D stick figure (root-relative) seen from that camera's orientation
  (orthographic: the joints rotated by the camera's R, x right and y down), so it lines up with the
  frame above it. The paper picked such viewpoints by hand; the rig gives them exactly.

matplotlib (heavy) is imported when a figure is drawn, with the non-interactive Agg backend (:func:`.plots.pyplot`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_figure_atomic
from silpose.shared.skeleton import BONES

from silpose.app.view_status import VIEW_OK

from .plots import pyplot


def _crop(mask, recon: np.ndarray, width: int, height: int, pad: float = 15.0) -> tuple[float, float, float, float]:
    """(x0, y0, x1, y1) px: the silhouette and reconstruction, padded, as a 4:3 box (whole image if neither)."""
    pts = [recon[np.all(np.isfinite(recon), axis=1)]]
    if mask is not None and mask.any():
        ys, xs = np.nonzero(mask)
        pts.append(np.array([[xs.min(), ys.min()], [xs.max(), ys.max()]], float))
    p = np.vstack(pts)
    if not len(p):
        return -0.5, -0.5, width - 0.5, height - 0.5
    lo, hi = p.min(0) - pad, p.max(0) + pad
    c, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    half = np.minimum(np.maximum(half, [half[1] * 4 / 3, half[0] * 3 / 4]), [width / 2, height / 2])
    c = np.clip(c, half - 0.5, np.array([width, height]) - 0.5 - half)  # slide the box inside the image
    return float(c[0] - half[0]), float(c[1] - half[1]), float(c[0] + half[0]), float(c[1] + half[1])


def overlay_figure(path, images: list, masks: list, recon_px: np.ndarray, status, joints: np.ndarray, rig,
                   title: str) -> Path:
    """Draw and save one frame's figure (see the module docstring).

    Args:
        path: PNG file to write (atomically: temporary name, then renamed).
        images: per rig camera a (H, W, 3) uint8 BGR frame, or None (no camera).
        masks: per rig camera a (H, W) bool silhouette, or None.
        recon_px: (K, n, 2) reconstructed contours in px, rig order (NaN rows: not drawn).
        status: (K,) per camera "ok" or the reason the view was not used.
        joints: (19, 3) inferred root-relative joints, metres (NaN: no pose).
        rig: the model's rig (camera names and rotations).
        title: figure title.
    """
    plt = pyplot()
    K = len(rig)
    fig, axes = plt.subplots(3, K, figsize=(2.3 * K, 6.2), squeeze=False,
                             gridspec_kw={"height_ratios": [1, 1, 1.1]})
    lim = 1.0
    finite = np.all(np.isfinite(joints))
    if finite:
        lim = 1.1 * float(np.max(np.abs(joints))) + 0.05
    for k, cam in enumerate(rig):
        a0, a1, a2 = axes[0, k], axes[1, k], axes[2, k]
        for ax in (a0, a1, a2):
            ax.set_xticks([])
            ax.set_yticks([])
        if images[k] is not None:
            a0.imshow(images[k][..., ::-1])
        else:
            a0.imshow(np.full((cam.height, cam.width, 3), 235, np.uint8))
        a0.set_title(cam.name, fontsize=8)
        if masks[k] is not None:
            a1.imshow(masks[k], cmap="gray", vmin=0, vmax=1.6)
        else:
            a1.imshow(np.zeros((cam.height, cam.width)), cmap="gray", vmin=0, vmax=1.6)
        if status[k] == VIEW_OK:
            c = recon_px[k]
            if np.all(np.isfinite(c)):
                c = np.vstack([c, c[:1]])
                a1.plot(c[:, 0], c[:, 1], "-", color="tab:red", lw=1.0)
            a1.set_title("silhouette + reconstruction", fontsize=7)
        else:
            a1.set_title(f"not used: {status[k]}", fontsize=7, color="tab:red")
        x0, y0, x1, y1 = _crop(masks[k], recon_px[k], cam.width, cam.height)
        a1.set_xlim(x0, x1)
        a1.set_ylim(y1, y0)
        if finite:
            p = joints @ np.asarray(cam.R).T  # camera orientation: x right, y down, z forward
            for a, b in BONES:
                a2.plot(p[[a, b], 0], p[[a, b], 1], "-", color="tab:red", lw=1.5)
            a2.plot(p[:, 0], p[:, 1], ".", color="black", ms=2)
        else:
            a2.text(0.5, 0.5, "no pose\n(no usable view)", ha="center", va="center", transform=a2.transAxes, fontsize=8)
        a2.set_xlim(-lim, lim)
        a2.set_ylim(lim, -lim)
        a2.set_aspect("equal")
        a2.set_title(f"inferred pose, {cam.name}'s view", fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return write_figure_atomic(fig, path, dpi=90)

