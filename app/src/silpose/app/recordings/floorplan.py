"""The floor plan of a recording: every person's track seen from above (``<out>/floorplan.png``).

Top view in silpose's frame (metres, x right, y up the page): the workspace (dashed), the cameras (their
centres and viewing directions, named), each person's floor positions joined in time order in the person's
colour (the placed root, or the floor grid's position in frames without joints), a circle where the track
starts and the id where it ends, and, for a rig with a calibration frame, that frame's origin and x / y axes
(where the lab's own coordinates start). matplotlib is imported when the plot is drawn (Agg).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_figure_atomic

from .overlay_video import person_colour


def write_floorplan(path: Path, tracks: dict[int, np.ndarray], rig, transform, workspace, title: str) -> Path:
    """Draw and save the floor plan.

    tracks: {person: (T, 3) array of (frame, x, y)}, metres; rig: cameras; transform, workspace: the room
    (``Rig.transform``, ``Rig.workspace``).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 6.4))
    (x0, x1), (y0, y1) = workspace.bounds
    ax.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "--", color="0.5", lw=1, label="workspace")
    pts = [np.array([[x0, y0], [x1, y1]])]
    for cam in rig:
        c = cam.center
        d = cam.R[2, :2]
        d = d / (np.linalg.norm(d) or 1.0)
        ax.plot(c[0], c[1], "k^", ms=7)
        ax.annotate("", xy=(c[0] + 0.6 * d[0], c[1] + 0.6 * d[1]), xytext=(c[0], c[1]),
                    arrowprops=dict(arrowstyle="->", color="k", lw=1))
        ax.text(c[0], c[1] - 0.25, cam.name, ha="center", va="top", fontsize=8)
        pts.append(c[None, :2])
    if not transform.is_identity:  # where the lab's own coordinates start, and their x / y axes
        origin = transform.to_silpose(np.zeros(3))
        axes = transform.to_silpose(np.diag([1.0, 1.0, 0.0]) / transform.scale) - origin  # 1 m along calib x, y
        for vec, name in zip(axes[:2], ("x", "y")):
            ax.annotate("", xy=(origin[0] + 0.6 * vec[0], origin[1] + 0.6 * vec[1]), xytext=(origin[0], origin[1]),
                        arrowprops=dict(arrowstyle="->", color="tab:red", lw=1.2))
            ax.text(origin[0] + 0.65 * vec[0], origin[1] + 0.65 * vec[1] - (0.12 if abs(vec[1]) > abs(vec[0]) else 0),
                    f"calib {name}", color="tab:red", fontsize=7,
                    ha="left" if abs(vec[0]) > abs(vec[1]) else "center", va="center" if abs(vec[0]) > abs(vec[1]) else "top")
        ax.plot(origin[0], origin[1], "o", color="tab:red", ms=4)
        ax.annotate("calibration origin", (origin[0], origin[1]), textcoords="offset points", xytext=(-6, 8),
                    color="tab:red", fontsize=7, ha="center")
        pts.append(origin[None, :2])
    for person, tr in sorted(tracks.items()):
        if not len(tr):
            continue
        col = np.array(person_colour(person)[::-1]) / 255.0
        ax.plot(tr[:, 1], tr[:, 2], "-", color=col, lw=1.5)
        ax.plot(tr[0, 1], tr[0, 2], "o", color=col, ms=6)
        ax.annotate(f"#{person}", (tr[-1, 1], tr[-1, 2]), textcoords="offset points", xytext=(6, 8), color=col,
                    fontsize=10, weight="bold", bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.8))
        pts.append(tr[:, 1:3])
    allp = np.vstack(pts)
    lo, hi = allp.min(0) - 0.6, allp.max(0) + 0.6
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m, silpose frame)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    # fixed margins that fit the labels of a 6.4 in square plot (tight_layout measured every text: ~0.3 s of a
    # run's end on a loaded 2-core machine, a run of 150 steps taking ~2 s)
    fig.subplots_adjust(left=0.1, right=0.97, bottom=0.08, top=0.95)
    return write_figure_atomic(fig, path, dpi=100)
