"""A picture of one clip of a motion library (``silpose motions show``): stick figures of evenly spaced
frames, seen from the front and from the side, standing on the floor, so a user sees what an import made of a
file (a wrong joint map, a lying clip, a swapped left and right) before generating data with it.

Each frame is posed as generation poses it (:mod:`.library`'s role positions, metres, z up), then turned about
the vertical so that its hip line points along +x (the figure faces -y, towards the viewer of the front row),
moved so that the pelvis is above the origin and lowered or lifted so that its lowest foot role touches the
floor (z = 0). Left-side bones are drawn blue, right-side orange, the trunk grey. Written with matplotlib's Agg
backend, atomically (``silpose.shared.atomic``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_figure_atomic

from .library import N_ROLES, PARENTS, ROLES, Library
from .retarget import FOOT_ROLES

#: Frames drawn by default.
N_FRAMES = 8
_FEET = [ROLES.index(r) for r in FOOT_ROLES if r in ROLES]
_L, _R = ROLES.index("l_hip"), ROLES.index("r_hip")


def find_clip(lib: Library, clip_id: str) -> int:
    """The index of clip ``clip_id`` in ``lib``; KeyError naming a few ids when there is none."""
    ids = [c["id"] for c in lib.clips]
    if clip_id in ids:
        return ids.index(clip_id)
    near = [i for i in ids if clip_id.lower() in i.lower()][:5] or ids[:5]
    raise KeyError(f"{lib.folder}: no clip {clip_id!r} ({len(ids)} clips; e.g. {', '.join(near)})")


def sheet_poses(lib: Library, c: int, n: int = N_FRAMES) -> tuple[np.ndarray, np.ndarray]:
    """``(frames (k,), poses (k, 21, 3))``: ``k = min(n, frames)`` evenly spaced kept frames of clip ``c`` (their
    source frame numbers) and their role positions facing -y, pelvis above the origin, lowest foot on the floor
    (module docstring), metres."""
    P = lib.positions(c)
    rows = lib.rows(c)
    pick = np.unique(np.linspace(0, len(P) - 1, min(n, len(P))).round().astype(int))
    out = []
    for p in P[pick]:
        lateral = p[_L] - p[_R]
        a = -np.arctan2(lateral[1], lateral[0])  # turn the hip line onto +x
        R = np.array([[np.cos(a), -np.sin(a), 0.0], [np.sin(a), np.cos(a), 0.0], [0.0, 0.0, 1.0]])
        q = (p - [p[0, 0], p[0, 1], 0.0]) @ R.T
        q[:, 2] -= np.nanmin(q[_FEET, 2])
        out.append(q)
    return lib.frame[rows][pick], np.array(out).reshape(-1, N_ROLES, 3)


def _colour(role: str) -> str:
    return "#1f77b4" if role.startswith("l_") else "#ff7f0e" if role.startswith("r_") else "#555555"


def write_clip_sheet(lib: Library, clip_id: str, out: str | Path, n: int = N_FRAMES) -> Path:
    """Draw clip ``clip_id`` of ``lib`` (module docstring) into the PNG ``out``; returns its path.

    Raises:
        KeyError: no such clip (:func:`find_clip`).
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    c = find_clip(lib, clip_id)
    frames, poses = sheet_poses(lib, c, n)
    info = lib.clips[c]
    top = max(2.0, float(np.nanmax(poses[..., 2])) + 0.1)
    fig, axes = plt.subplots(2, len(poses), figsize=(1.1 * len(poses) + 0.5, 2 * 1.1 * (top + 0.05) / 1.8 + 0.8), squeeze=False,
                             sharey=True, layout="constrained")
    for k, (frame, q) in enumerate(zip(frames, poses)):
        for row, (h, name) in enumerate(((0, "front"), (1, "side"))):
            ax = axes[row, k]
            for j in range(1, N_ROLES):
                p = PARENTS[j]
                ax.plot([q[p, h], q[j, h]], [q[p, 2], q[j, 2]], color=_colour(ROLES[j]), lw=2, solid_capstyle="round")
            ax.axhline(0.0, color="#999999", lw=0.8)
            ax.set_xlim(-0.9, 0.9)
            ax.set_ylim(-0.05, top)
            ax.set_aspect("equal")
            ax.set_xticks([])
            if k == 0:
                ax.set_ylabel(f"{name} (m)", fontsize=8)
            if row == 0:
                ax.set_title(f"frame {int(frame)}", fontsize=8)
    turned = f", turned upright from {info['rest_up']}" if info.get("rest_up") else ""
    fig.suptitle(f"{info['id']}: {info.get('group', '')}, subject {info.get('subject') or '-'}, {info.get('split', '')}, "
                 f"{info['frames']} frames at {lib.manifest.get('fps', '?')} fps, map {info.get('joint_map', '?')}"
                 f"{turned}\nleft blue, right orange; each frame turned to face the front row, feet on the floor",
                 fontsize=8)
    return write_figure_atomic(fig, out, dpi=100)
