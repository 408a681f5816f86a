"""``silpose rig show``: a rig in words (each camera in silpose's convention, the workspace) and in a picture.

The picture is one check at a glance: on the left a top view of the floor with the workspace, each
camera, its viewing wedge (the left and right image edges) and its floor footprint (where the image
border meets the floor); on the right each camera's image frame with the workspace box (the floor
rectangle up to the tallest person's height) and a 1.75 m stick figure at the workspace centre,
facing that camera, projected with the camera's own model (distortion included).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_figure_atomic
from silpose.shared.camera import Camera, Rig
from silpose.shared.rig_frame import PERSON_HEIGHT_M

__all__ = ["describe_rig", "draw_rig", "camera_row", "stick_figure", "FIGURE_HEIGHT_M"]

#: Height (m) of the stick figure drawn in each camera's image.
FIGURE_HEIGHT_M = 1.75


def _view(cam: Camera) -> tuple[np.ndarray, float, float]:
    """(forward (3,), azimuth deg counter-clockwise from +x, elevation deg, negative = looking down)."""
    f = cam.R[2]
    return f, float(np.degrees(np.arctan2(f[1], f[0]))), float(np.degrees(np.arcsin(np.clip(f[2], -1, 1))))


def _sees(cam: Camera, rig: Rig, height: float) -> str:
    corners = np.concatenate([rig.workspace.corners(0.0), rig.workspace.corners(height)])
    depth = cam.to_camera(corners)[:, 2]
    ok = (depth > 0) & cam.in_image(cam.project(corners))
    return "yes" if ok.all() else f"no ({int((~ok).sum())} of 8 corners)"


def camera_row(cam: Camera, rig: Rig, height: float = PERSON_HEIGHT_M) -> dict[str, str]:
    """One camera in silpose's convention, as printable columns."""
    c = cam.center
    f, az, el = _view(cam)
    cx, cy = rig.workspace.center
    person = np.array([[cx, cy, 0.0], [cx, cy, FIGURE_HEIGHT_M]])
    feet, head = cam.project(person)
    # not in view: behind the camera, or beyond its lens model (project() gives NaN there)
    person_px = float(np.linalg.norm(head - feet)) if np.all(cam.to_camera(person)[:, 2] > 0) else float("nan")
    dist = "none" if not np.any(cam.dist) else " ".join(f"{v:.4g}" for v in cam.dist)
    if cam.fisheye:
        dist = f"fisheye k1..k4 {dist}"
    return {
        "camera": cam.name,
        "centre x, y, z (m)": f"{c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f}",
        "looking (x, y, z)": f"{f[0]:+.3f}, {f[1]:+.3f}, {f[2]:+.3f}",
        "azimuth, elevation": f"{az:.1f}, {el:.1f} deg",
        "fx, fy (px)": f"{cam.K[0, 0]:.1f}, {cam.K[1, 1]:.1f}",
        "cx, cy (px)": f"{cam.K[0, 2]:.1f}, {cam.K[1, 2]:.1f}",
        "image": f"{cam.width}x{cam.height}",
        "distortion": dist,
        f"sees workspace to {height:g} m": _sees(cam, rig, height),
        f"{FIGURE_HEIGHT_M:g} m person at centre": f"{person_px:.0f} px" if np.isfinite(person_px) else "not in view",
    }


def describe_rig(rig: Rig, name: str | None = None, height: float = PERSON_HEIGHT_M,
                 imported_from: str | None = None) -> str:
    """The text ``silpose rig show`` prints: frame, workspace, one row per camera."""
    tr, ws = rig.transform, rig.workspace
    (x0, x1), (y0, y1) = ws.bounds
    origin = imported_from if imported_from is not None else rig.source
    lines = [f"{name or rig.where}: {len(rig)} camera(s)" + (f", imported from {origin}" if origin and
                                                              origin != name else ""),
             "frame: silpose's world (right-handed, z up, metres, floor at z = 0, walkers inside the workspace)"]
    if tr.is_identity:
        lines.append("calibration frame: the same (identity transform)")
    else:
        up = tr.up_in_calibration
        origin = tr.to_calibration(np.zeros(3))
        lines.append(f"calibration frame -> silpose: X = {tr.scale:g} * A X_calibration + b; up is "
                     f"{np.round(up, 6).tolist()} in the calibration's axes; silpose's origin is the calibration point "
                     f"({', '.join(f'{v:.4g}' for v in origin)}); A = {np.round(tr.rotation, 6).tolist()}, "
                     f"b = {np.round(tr.offset, 6).tolist()} m")
    lines.append(f"workspace: {ws.describe()}: x in [{x0:.3f}, {x1:.3f}] m, y in [{y0:.3f}, {y1:.3f}] m")
    rows = [camera_row(c, rig, height) for c in rig]
    cols = list(rows[0])
    widths = [max(len(col), *(len(r[col]) for r in rows)) for col in cols]
    lines.append("  ".join(col.ljust(w) for col, w in zip(cols, widths)))
    lines += ["  ".join(r[col].ljust(w) for col, w in zip(cols, widths)) for r in rows]
    return "\n".join(line.rstrip() for line in lines)


def stick_figure(centre_xy, facing: np.ndarray, height: float = FIGURE_HEIGHT_M) -> list[np.ndarray]:
    """Polylines (each (n, 3), metres) of a standing stick figure ``height`` tall at ``centre_xy``,
    its chest facing the horizontal direction ``facing`` (proportions: Winter's fractions of stature)."""
    f = np.array([facing[0], facing[1], 0.0])
    f = f / (np.linalg.norm(f) or 1.0)
    left = np.array([-f[1], f[0], 0.0])
    s = height / 1.75
    base = np.array([centre_xy[0], centre_xy[1], 0.0])

    def p(side, up, fwd=0.0):
        return base + s * (side * left + up * np.array([0, 0, 1.0]) + fwd * f)

    lines = [np.array([p(0, 0.93), p(0, 1.25), p(0, 1.50)])]  # spine, neck
    for sd in (-1, 1):
        lines.append(np.array([p(0, 1.43), p(sd * 0.20, 1.43), p(sd * 0.24, 1.15), p(sd * 0.25, 0.88)]))  # arm
        lines.append(np.array([p(0, 0.93), p(sd * 0.10, 0.93), p(sd * 0.11, 0.50), p(sd * 0.11, 0.06),
                               p(sd * 0.11, 0.02, 0.13)]))  # leg and foot
    a = np.linspace(0, 2 * np.pi, 25)
    lines.append(np.stack([p(0.11 * np.cos(t), 1.64 + 0.11 * np.sin(t)) for t in a]))  # head
    return lines


def _project_polyline(cam: Camera, pts: np.ndarray) -> np.ndarray:
    """(n, 2) pixels, NaN where a point is behind the camera."""
    depth = cam.to_camera(pts)[:, 2]
    px = cam.project(np.where((depth > 0.05)[:, None], pts, cam.center + cam.R[2]))
    px[depth <= 0.05] = np.nan
    return px


def _dense(a: np.ndarray, b: np.ndarray, n: int = 40) -> np.ndarray:
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def _floor_footprint(cam: Camera, reach: float, samples: int = 30) -> np.ndarray | None:
    """(n, 2) floor points where the image border's rays meet z = 0 within ``reach`` metres (None: none)."""
    W, H = cam.width, cam.height
    s = np.linspace(0, 1, samples)
    border = np.concatenate([np.stack([s * (W - 1), np.zeros_like(s)], 1),
                             np.stack([np.full_like(s, W - 1), s * (H - 1)], 1),
                             np.stack([(1 - s) * (W - 1), np.full_like(s, H - 1)], 1),
                             np.stack([np.zeros_like(s), (1 - s) * (H - 1)], 1)])
    n = cam.normalised(border)
    rays = np.concatenate([n, np.ones((len(n), 1))], 1) @ cam.R  # world directions (R^T d)
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    c = cam.center
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = -c[2] / rays[:, 2]
    lam = np.where((rays[:, 2] < 0) & (lam > 0), np.minimum(lam, reach), reach)
    pts = c + lam[:, None] * rays
    return pts[:, :2]


def draw_rig(rig: Rig, out: str | Path, title: str | None = None, height: float = PERSON_HEIGHT_M) -> Path:
    """Write the picture of the module docstring to ``out`` (PNG); returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon, Rectangle

    k = len(rig)
    ncols = 1 if k == 1 else 2 if k <= 4 else 3
    nrows = int(np.ceil(k / ncols))
    W0, H0 = rig[0].width, rig[0].height
    aspect = H0 / W0
    fig = plt.figure(figsize=(6.0 + 3.4 * ncols, max(5.5, nrows * 3.4 * aspect + 1.2)))
    gs = fig.add_gridspec(nrows, 1 + ncols, width_ratios=[1.8] + [1.0] * ncols)
    top = fig.add_subplot(gs[:, 0])
    ws = rig.workspace
    (x0, x1), (y0, y1) = ws.bounds
    colours = plt.get_cmap("tab10")
    far = max(np.linalg.norm(ws.corners(0.0) - c.center, axis=1).max() for c in rig)
    reach = 1.25 * far
    top.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor="#b6e3b6", edgecolor="#2e7d32", lw=2, zorder=2,
                            label=f"workspace {ws.size[0]:.2f} x {ws.size[1]:.2f} m"))
    for i, cam in enumerate(rig):
        col = colours(i % 10)
        c = cam.center
        mid = (cam.height - 1) / 2
        edge = cam.normalised(np.array([[0.0, mid], [cam.width - 1.0, mid]]))
        rays = np.concatenate([edge, np.ones((2, 1))], 1) @ cam.R
        rays[:, 2] = 0.0
        rays /= np.linalg.norm(rays, axis=1, keepdims=True) + 1e-12
        wedge = np.array([c[:2], c[:2] + reach * rays[0, :2], c[:2] + reach * rays[1, :2]])
        top.add_patch(Polygon(wedge, closed=True, facecolor=(*col[:3], 0.06), edgecolor=(*col[:3], 0.5), lw=1,
                              zorder=1))
        foot = _floor_footprint(cam, reach)
        if foot is not None:
            top.plot(*np.vstack([foot, foot[:1]]).T, color=col, lw=1, ls=":", zorder=3)
        f = cam.R[2]
        top.plot(c[0], c[1], marker="o", ms=8, color=col, zorder=4)
        top.annotate("", xy=(c[0] + 0.8 * f[0], c[1] + 0.8 * f[1]), xytext=(c[0], c[1]),
                     arrowprops=dict(arrowstyle="->", color=col, lw=2), zorder=4)
        away = c[:2] - ws.center
        away = away / (np.linalg.norm(away) or 1.0)
        top.annotate(f"{cam.name}\n{c[2]:.2f} m up", (c[0], c[1]), textcoords="offset points",
                     xytext=(16 * away[0], 16 * away[1]), ha="left" if away[0] >= 0 else "right",
                     va="bottom" if away[1] >= 0 else "top", fontsize=8, color=col, zorder=5)
    top.plot(*ws.center, marker="*", ms=12, color="k", zorder=5, label=f"{FIGURE_HEIGHT_M:g} m figure (right)")
    pts = np.concatenate([[c.center[:2] for c in rig], ws.corners(0.0)[:, :2]])
    lo, hi = pts.min(0) - 1.5, pts.max(0) + 1.5
    top.set_xlim(lo[0], hi[0])
    top.set_ylim(lo[1], hi[1])
    top.set_aspect("equal")
    top.grid(True, alpha=0.3)
    top.set_xlabel("x (m)")
    top.set_ylabel("y (m)")
    top.set_title("top view: cameras, viewing wedges, floor footprints (dotted), workspace", fontsize=9)
    top.legend(loc="upper left", fontsize=8, framealpha=0.9)

    box = [ws.corners(0.0), ws.corners(height)]
    for i, cam in enumerate(rig):
        ax = fig.add_subplot(gs[i // ncols, 1 + i % ncols])
        col = colours(i % 10)
        ax.add_patch(Rectangle((-0.5, -0.5), cam.width, cam.height, facecolor="#f4f4f4", edgecolor="k", lw=1))
        for j in range(4):
            a, b = j, (j + 1) % 4
            for level, style in ((0, "-"), (1, "--")):
                px = _project_polyline(cam, _dense(box[level][a], box[level][b]))
                ax.plot(px[:, 0], px[:, 1], color="#2e7d32", lw=1.5 if level == 0 else 1.0, ls=style)
            px = _project_polyline(cam, _dense(box[0][j], box[1][j]))
            ax.plot(px[:, 0], px[:, 1], color="#2e7d32", lw=0.8, ls=":")
        to_cam = cam.center[:2] - ws.center
        for line in stick_figure(ws.center, to_cam):
            px = _project_polyline(cam, line)
            ax.plot(px[:, 0], px[:, 1], color=col, lw=2)
        ax.set_xlim(-0.5 - 0.04 * cam.width, cam.width - 0.5 + 0.04 * cam.width)
        ax.set_ylim(cam.height - 0.5 + 0.04 * cam.height, -0.5 - 0.04 * cam.height)
        ax.set_aspect("equal")
        ax.set_xticks([0, cam.width // 2, cam.width - 1])
        ax.set_yticks([0, cam.height // 2, cam.height - 1])
        ax.tick_params(labelsize=7)
        ax.set_title(f"{cam.name} ({cam.width}x{cam.height}): workspace box to {height:g} m", fontsize=8, color=col)
    parts = [Path(part) for part in rig.where.split(", ")]
    names = [q.name for q in parts]
    if len(set(names)) < len(names):  # cam1/config.xml, cam2/config.xml ...: keep the folders
        names = [f"{q.parent.name}/{q.name}" for q in parts]
    files = ", ".join(names)
    fig.suptitle(title or f"{files}: {k} camera(s), workspace {ws.describe()}", fontsize=10)
    fig.tight_layout()
    return write_figure_atomic(fig, out, dpi=110)
