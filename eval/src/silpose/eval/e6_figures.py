"""E6 figures: a flip resolved, a masked input before/after robust inference, flagged garbage inputs.

Each figure states how its example was chosen (never the best case silently):

- ``e6_flip_resolved.png``: among the test examples (4 views, standard noise) whose most probable
  hypothesis is flipped and whose view-pair consensus choice (``infer(consensus=True)``) is not, the one with the
  median pose-error gain. Row 1: the noisy inputs over the true clean contours; row 2: the floor plane
  seen from above (true skeleton, the flipped top-1 hypothesis, the chosen one; arrows = facing) and
  the three skeletons in 3D.
- ``e6_robust_mask.png``: "mask strong", 4 views; the example at the 75th percentile of the pose-error
  gain of robust over Gaussian inference. Per view: the corrupted input, where robust inference cut
  loops from it the input it used (``silpose.model.robust.excursions``), the points it down-weighted below 0.5,
  the Gaussian and the robust reconstructions over the true clean contour; below, the skeletons.
- ``e6_garbage.png``: the first input of three garbage kinds (``silpose.eval.e6_garbage``: two people
  merged, a box, an all-white frame), every view's mask with its contour and the model's
  reconstruction, titled with the plausibility percentile and whether ``silpose infer`` flags it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.model.hypotheses import heading, is_flip
from silpose.shared.metrics import pose_error_cm
from silpose.shared.skeleton import BONES, root_relative

from .plots import pyplot, save_figure

__all__ = ["write_e6_figures", "flip_figure", "robust_figure", "garbage_figure"]

GARBAGE_SHOWN = ("two people merged", "box", "all-white")


def _closed(c: np.ndarray) -> np.ndarray:
    return np.vstack([c, c[:1]])


def _contour_axes(ax, contours: list[tuple[np.ndarray, str, str, str]], title: str) -> None:
    """Plot (points (n, 2) px, style, colour, label) tuples on an image-coordinate axis."""
    pts = np.vstack([c for c, *_ in contours if np.all(np.isfinite(c))])
    lo, hi = pts.min(0) - 6, pts.max(0) + 6
    for c, style, color, label in contours:
        if np.all(np.isfinite(c)):
            cl = _closed(c)
            ax.plot(cl[:, 0], cl[:, 1], style, color=color, lw=1.0, label=label)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(hi[1], lo[1])
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=8)


def _stick3d(ax, skeletons: list[tuple[np.ndarray, str, str, str]]) -> None:
    for joints, style, color, label in skeletons:
        for a, b in BONES:
            ax.plot(*[joints[[a, b], i] for i in range(3)], style, color=color, lw=1.4)
        ax.plot([], [], style, color=color, label=label)
    pts = np.vstack([j for j, *_ in skeletons])
    mid, r = 0.5 * (pts.max(0) + pts.min(0)), 0.5 * float((pts.max(0) - pts.min(0)).max())
    ax.set_xlim(mid[0] - r, mid[0] + r)
    ax.set_ylim(mid[1] - r, mid[1] + r)
    ax.set_zlim(mid[2] - r, mid[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.tick_params(labelsize=6)
    ax.legend(loc="upper left", fontsize=7)


def _floor_plane(ax, skeletons: list[tuple[np.ndarray, str, str, str]]) -> None:
    """Skeletons seen from above (x right, y up), with an arrow along each one's facing direction."""
    for joints, style, color, label in skeletons:
        for a, b in BONES:
            ax.plot(joints[[a, b], 0], joints[[a, b], 1], style, color=color, lw=1.2)
        h = float(heading(joints))
        ax.annotate("", xy=(0.35 * np.cos(h), 0.35 * np.sin(h)), xytext=(0.0, 0.0),
                    arrowprops={"arrowstyle": "->", "color": color, "lw": 2.0})
        ax.plot([], [], style, color=color, label=f"{label}: facing {np.degrees(h):.0f}°")
    ax.set_aspect("equal")
    ax.set_xlim(-0.5, 0.5)
    ax.set_ylim(-0.5, 0.5)
    ax.set_xlabel("x (m)", fontsize=7)
    ax.set_ylabel("y (m)", fontsize=7)
    ax.tick_params(labelsize=6)
    ax.legend(loc="lower left", fontsize=7)
    ax.set_title("seen from above (pelvis at 0)", fontsize=8)


def flip_figure(ev, path: Path) -> Path | None:
    """``e6_flip_resolved.png`` (module doc); None when no example qualifies."""
    d, K = ev.data, ev.data.n_views
    noisy = ev.noisy(ev.config.noise)
    res = ev.model.infer(noisy, hypotheses=3, consensus=True)
    hyp = res.hypotheses
    truth = root_relative(d.test_joints)
    top1, chosen = hyp.joints[:, 0], hyp.best_joints
    ok = np.flatnonzero(is_flip(top1, truth) & ~is_flip(chosen, truth))
    if ok.size == 0:
        return None
    gain = pose_error_cm(top1[ok], truth[ok]) - pose_error_cm(chosen[ok], truth[ok])
    i = int(ok[np.argsort(gain)[len(gain) // 2]])
    plt = pyplot()
    fig = plt.figure(figsize=(2.4 * K, 8.0))
    gs = fig.add_gridspec(2, K, height_ratios=[1, 1.25])
    for k in range(K):
        _contour_axes(fig.add_subplot(gs[0, k]), [(d.test_contours[i, k], ":", "gray", "true clean"),
                                                  (noisy[i, k], "-", "tab:blue", "noisy input")], f"view {k}: input")
    handles = {h.get_label(): h for ax in fig.axes for h in ax.get_lines()}
    fig.axes[0].legend(handles.values(), handles.keys(), loc="lower left", fontsize=6)
    half = max(1, K // 2)
    skel = [(truth[i], ":", "black", "truth"), (root_relative(top1[i]), "-", "tab:red", "top-1 (flipped)"),
            (root_relative(chosen[i]), "-", "tab:green", f"view-pair consensus (hypothesis {int(hyp.chosen[i]) + 1})")]
    _floor_plane(fig.add_subplot(gs[1, :half]), skel)
    _stick3d(fig.add_subplot(gs[1, half:], projection="3d"), skel)
    p = hyp.probability[i]
    fig.suptitle(f"A flip resolved: sample {int(d.test_ids[i])}, 4 views, {ev.config.noise.label} noise. Top-1 hypothesis "
                 f"(p = {p[0]:.3g}) faces the wrong way: {pose_error_cm(top1[i:i + 1], truth[i:i + 1])[0]:.1f} cm; the "
                 f"vote of the view pairs picks hypothesis {int(hyp.chosen[i]) + 1} (p = {p[hyp.chosen[i]]:.3g}): "
                 f"{pose_error_cm(chosen[i:i + 1], truth[i:i + 1])[0]:.1f} cm.\n{ok.size} of {len(truth)} examples are "
                 f"resolved this way; shown: the median gain among them.", fontsize=8)
    return save_figure(fig, path)


def robust_figure(ev, path: Path, label: str = "mask strong") -> Path | None:
    """``e6_robust_mask.png`` (module doc); None without the mask-level setting or its masks."""
    d, K = ev.data, ev.data.n_views
    spec = {s.label: s for s in ev.config.sweep}.get(label)
    if spec is None or (spec.needs_masks and d.test_masks is None):
        return None
    noisy = ev.noisy(spec)
    gauss = ev.model.infer(noisy, centroid=d.test_centroid, scale=d.test_scale)
    rob = ev.model.infer(noisy, centroid=d.test_centroid, scale=d.test_scale, robust=True)
    truth = root_relative(d.test_joints)
    eg, er = pose_error_cm(gauss.joints, truth), pose_error_cm(rob.joints, truth)
    gain = eg - er
    order = np.argsort(gain)
    i = int(order[int(0.75 * (len(order) - 1))])
    plt = pyplot()
    fig = plt.figure(figsize=(2.4 * K, 8.0))
    gs = fig.add_gridspec(2, K, height_ratios=[1.2, 1])
    for k in range(K):
        ax = fig.add_subplot(gs[0, k])
        _contour_axes(ax, [(d.test_contours[i, k], ":", "gray", "true clean"), (noisy[i, k], "-", "black", "corrupted input"),
                           (gauss.contours_px[i, k], "-", "tab:red", "Gaussian"),
                           (rob.contours_px[i, k], "-", "tab:green", "robust")], f"view {k}")
        used = rob.robust_input_px[i, k]  # the input with its excursions cut (silpose.model.robust.excursions)
        if rob.excursions_trimmed[i, k]:
            ax.plot(*np.vstack([used, used[:1]]).T, "--", color="tab:blue", lw=0.9, label="input, loops cut")
        low = rob.robust_weights[i, k] < 0.5
        ax.plot(used[low, 0], used[low, 1], "x", color="tab:orange", ms=3, label="weight < 0.5")
    handles = {h.get_label(): h for ax in fig.axes for h in ax.get_lines()}
    fig.axes[0].legend(handles.values(), handles.keys(), loc="lower left", fontsize=6)
    _stick3d(fig.add_subplot(gs[1, :], projection="3d"),
             [(truth[i], ":", "black", "truth"), (root_relative(gauss.joints[i]), "-", "tab:red", f"Gaussian {eg[i]:.1f} cm"),
              (root_relative(rob.joints[i]), "-", "tab:green", f"robust {er[i]:.1f} cm")])
    fig.suptitle(f"Robust inference on a masked input ('{label}': holes, blobs, a shadow at the feet): sample "
                 f"{int(d.test_ids[i])}, 4 views.\nShown: the 75th percentile of the pose-error gain over the test set "
                 f"(mean {eg.mean():.2f} -> {er.mean():.2f} cm; gain > 0 on {100 * np.mean(gain > 0):.0f} % of examples).",
                 fontsize=8)
    return save_figure(fig, path)


def garbage_figure(ev, path: Path) -> Path | None:
    """``e6_garbage.png`` (module doc); None when E6 did not run the plausibility part."""
    examples = getattr(ev, "e6_garbage_examples", None) or {}
    kinds = [k for k in GARBAGE_SHOWN if k in examples]
    if not kinds:
        return None
    K = ev.data.n_views
    plt = pyplot()
    fig, axes = plt.subplots(len(kinds), K, figsize=(2.4 * K, 2.9 * len(kinds)), squeeze=False)
    missed = []
    for r, kind in enumerate(kinds):
        masks, contours, present = examples[kind]
        res = ev.model.infer(contours, present) if present.any() else None
        pct = float(res.plausibility[0]) if res is not None and res.plausibility is not None else float("nan")
        flagged = bool(res.implausible[0]) if res is not None and res.implausible is not None else True
        for k in range(K):
            ax = axes[r, k]
            ax.imshow(masks[0, k], cmap="Greys", vmin=0, vmax=2, interpolation="nearest")
            if present[0, k]:
                ax.plot(*_closed(contours[0, k]).T, "-", color="tab:blue", lw=1.0, label="input contour")
                ax.plot(*_closed(res.contours_px[0, k]).T, "-", color="tab:red", lw=1.0, label="reconstruction")
            h, w = masks.shape[2:]
            ax.set_xlim(-0.5, w - 0.5)
            ax.set_ylim(h - 0.5, -0.5)
            ax.set_xticks([])
            ax.set_yticks([])
            if k == 0:
                ax.set_ylabel(kind, fontsize=8)
        axes[r, 0].set_title(f"{kind}: plausibility {pct:.1f} percentile -> {'FLAGGED' if flagged else 'not flagged'}",
                             fontsize=8, loc="left")
        if not flagged:
            missed.append(kind)
    axes[0, 0].legend(loc="lower left", fontsize=6)
    fig.suptitle("Inputs that are not a person: the first input of each kind (silpose.eval.e6_garbage), all views, with the "
                 "model's reconstruction (it always draws a walker).\nEach row: the plausibility percentile and whether "
                 "silpose infer flags the frame (below the model's plausibility threshold, or convex in every view); "
                 + (f"not flagged: {', '.join(missed)}." if missed else "every one shown is flagged."), fontsize=8)
    return save_figure(fig, path)


def write_e6_figures(ev, out: Path) -> dict[str, Path]:
    """Draw the E6 figures into ``out``; returns {name: path} of those drawn."""
    written = {}
    for name, fn in (("e6_flip_resolved", flip_figure), ("e6_robust_mask", robust_figure), ("e6_garbage", garbage_figure)):
        p = fn(ev, Path(out) / f"{name}.png")
        if p is not None:
            written[name] = p
    return written
