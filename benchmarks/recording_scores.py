"""Score a recording's output (``silpose infer --videos``) against the people's true joints.

Truth: joints (T, P, 19, 3) metres in silpose's frame for P people over T frames (e.g. the lab recording of
``silpose.datagen.lab``). Output: ``joints.parquet`` (``silpose.app.recordings.writers``).

Matching, frame by frame: the output rows on the floor (status other than ``not detected``) and the true
people are paired by the Hungarian algorithm on the floor distance (row ``floor_x/floor_y`` against the
true pelvis), pairs more than ``gate`` metres apart left unpaired. Then:

- identity switches: over each true person's frames, the number of times the person id paired with them
  changes (frames where they are unpaired are skipped);
- errors, on paired rows with joints (status ``ok``): the root error (pelvis, metres), the world-frame
  joint error (mean over the 19 joints of the Euclidean distance, no alignment) and the root-relative
  joint error (the paper's protocol);
- views: among paired rows, the fraction with at least 1, 2, 3, 4 usable views;
- joints inside silhouettes (:func:`joints_inside`): the share of a paired row's 19 joints that project inside
  the true person's own silhouette (their clean mask, dilated by ``tolerance_px``) in each view the row used.

:func:`clean_reference` is the comparison the tests and benchmark make: the same people inferred from
each person's own clean masks in every view, through the same floor grid, model and placement.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
from scipy.optimize import linear_sum_assignment

from silpose.app.inference import infer_rows
from silpose.app.recordings.floor import FloorGrid
from silpose.app.recordings.placement import place_roots
from silpose.shared.contours import EmptyMaskError, extract_contour


def read_rows(path: Path) -> dict:
    """The columns of a ``joints.parquet`` scoring needs, as numpy arrays."""
    t = pq.read_table(path)
    n = t.num_rows

    def nested(name, shape):
        col = t.column(name).combine_chunks()
        for _ in shape:
            col = col.flatten()
        return col.to_numpy(zero_copy_only=False).reshape((n,) + shape).astype(float)

    return {
        "frame": t.column("frame").to_numpy(), "person": t.column("person").to_numpy(),
        "status": np.array(t.column("status").to_pylist(), dtype=object),
        "floor": np.stack([t.column("floor_x").to_numpy(), t.column("floor_y").to_numpy()], axis=1).astype(float),
        "n_views": t.column("n_views").to_numpy().astype(int), "joints": nested("joints", (19, 3)),
        "root": nested("root", (3,)),
    }


def score_rows(rows: dict, truth: np.ndarray, gate: float = 0.5) -> dict:
    """Scores (module docstring) of output ``rows`` (:func:`read_rows`) against truth joints (T, P, 19, 3)."""
    T, P = truth.shape[:2]
    on_floor = rows["status"] != "not detected"
    paired = np.full(len(rows["frame"]), -1)
    for f in np.unique(rows["frame"][on_floor]):
        if not 0 <= f < T:
            continue
        idx = np.flatnonzero(on_floor & (rows["frame"] == f))
        cost = np.linalg.norm(rows["floor"][idx, None] - truth[f, None, :, 0, :2], axis=2)
        r, c = linear_sum_assignment(cost)
        ok = cost[r, c] <= gate
        paired[idx[r[ok]]] = c[ok]
    switches = 0
    for p in range(P):
        sel = np.flatnonzero(paired == p)
        ids = rows["person"][sel[np.argsort(rows["frame"][sel])]]
        switches += int(np.sum(ids[1:] != ids[:-1]))
    good = (paired >= 0) & (rows["status"] == "ok")
    tj = truth[rows["frame"][good], paired[good]]
    j = rows["joints"][good]
    root_err = np.linalg.norm(rows["root"][good] - tj[:, 0], axis=1)
    world_err = np.linalg.norm(j - tj, axis=2).mean(axis=1)
    rel_err = np.linalg.norm((j - j[:, :1]) - (tj - tj[:, :1]), axis=2).mean(axis=1)
    nv = rows["n_views"][paired >= 0]
    return {
        "person_frames": int(T * P), "paired": int((paired >= 0).sum()), "with_joints": int(good.sum()),
        "false_rows": int((on_floor & (paired < 0)).sum()), "persons": int(len(np.unique(rows["person"]))),
        "identity_switches": switches,
        "root_error_cm": 100 * float(root_err.mean()) if good.any() else float("nan"),
        "world_error_cm": 100 * float(world_err.mean()) if good.any() else float("nan"),
        "relative_error_cm": 100 * float(rel_err.mean()) if good.any() else float("nan"),
        "views_at_least": {k: float((nv >= k).mean()) if len(nv) else float("nan") for k in (1, 2, 3, 4)},
        "per_row": {"paired": paired, "world_error_m": world_err, "root_error_m": root_err},
    }


def read_view_status(path: Path) -> np.ndarray:
    """(R, K) str: ``view_status`` of every row of a ``joints.parquet``."""
    return np.array(pq.read_table(path, columns=["view_status"]).column("view_status").to_pylist(), dtype=object)


def joints_inside(rows: dict, view_status: np.ndarray, paired: np.ndarray, masks: np.ndarray, cameras,
                  tolerance_px: int = 2) -> dict:
    """The share of joints inside the true silhouettes (module docstring).

    Args:
        rows: :func:`read_rows`; view_status: (R, K) :func:`read_view_status`; paired: (R,) true person of each row
            or -1 (:func:`score_rows`' ``per_row``).
        masks: (T, P, K, H, W) bool, each true person's clean mask per camera.
        cameras: the K cameras (``project``).
        tolerance_px: a joint within this many pixels of the mask counts as inside.
    Returns:
        {"share": inside / joints tested, "joints": joints tested, "per_joint": (19,) shares}.
    """
    import cv2

    kernel = np.ones((2 * tolerance_px + 1, 2 * tolerance_px + 1), np.uint8)
    inside = np.zeros(19)
    tested = np.zeros(19)
    for i in np.flatnonzero((paired >= 0) & (rows["status"] == "ok")):
        f, p = int(rows["frame"][i]), int(paired[i])
        for k, cam in enumerate(cameras):
            if view_status[i][k] != "ok":
                continue
            grown = cv2.dilate(masks[f, p, k].view(np.uint8), kernel) > 0
            u = np.round(cam.project(rows["joints"][i])).astype(int)
            h, w = grown.shape
            seen = (u[:, 0] >= 0) & (u[:, 0] < w) & (u[:, 1] >= 0) & (u[:, 1] < h)
            hit = np.zeros(19, bool)
            hit[seen] = grown[u[seen, 1], u[seen, 0]]
            inside += hit
            tested += 1
    total = tested.sum()
    return {"share": float(inside.sum() / total) if total else float("nan"), "joints": int(total),
            "per_joint": np.where(tested > 0, inside / np.maximum(tested, 1), np.nan)}


def clean_reference(model, masks: np.ndarray, noise_variance: float | None = None) -> dict:
    """The people's joints inferred from their own clean masks in every view.

    masks: (T, P, K, H, W) bool per-person masks in the model's rig cameras. Per frame and person: the floor
    grid on that person's masks alone gives the floor position (the placement's prior), every non-empty view
    not touching the border is used, the model infers and :func:`~silpose.app.recordings.placement.place_roots`
    places the root. Returns ``joints`` (T, P, 19, 3) metres (NaN where nothing was seen) and ``root``.
    """
    rig = model.rig_
    workspace = rig.workspace
    grid = FloorGrid(list(rig), workspace.bounds)
    lay = model.fitted_layout()
    T, P, K = masks.shape[:3]
    n_pts = lay.n_points
    contours = np.full((T * P, K, n_pts, 2), np.nan)
    present = np.zeros((T * P, K), bool)
    floor = np.full((T * P, 2), np.nan)
    for f in range(T):
        for p in range(P):
            i = f * P + p
            m = [masks[f, p, k].view(np.uint8) for k in range(K)]
            det = grid.locate([x if x.any() else None for x in m])
            if not len(det.positions):
                continue
            floor[i] = det.positions[int(np.argmax(det.scores))]
            for k in range(K):
                try:
                    c = extract_contour(m[k], n_pts)
                except EmptyMaskError:
                    continue
                if not c.touches_border:
                    contours[i, k], present[i, k] = c.points, True
    joints = np.full((T * P, 19, 3), np.nan)
    root = np.full((T * P, 3), np.nan)
    ok = present.any(axis=1) & np.isfinite(floor).all(axis=1)
    if ok.any():
        res = infer_rows(model, contours[ok], present[ok], noise_variance)
        r = place_roots(res.joints, res.centroid, res.views_present, [rig[v] for v in res.views], floor[ok])
        joints[ok] = res.joints + r[:, None]
        root[ok] = r
    return {"joints": joints.reshape(T, P, 19, 3), "root": root.reshape(T, P, 3)}


def score_reference(reference: dict, truth: np.ndarray) -> dict:
    """World / root / root-relative errors (cm) of :func:`clean_reference`'s joints against the truth."""
    j, tj = reference["joints"], truth
    ok = np.isfinite(j).all(axis=(2, 3))
    world = np.linalg.norm(j[ok] - tj[ok], axis=2).mean(axis=1)
    root = np.linalg.norm(reference["root"][ok] - tj[ok][:, 0], axis=1)
    rel = np.linalg.norm((j[ok] - j[ok][:, :1]) - (tj[ok] - tj[ok][:, :1]), axis=2).mean(axis=1)
    return {"with_joints": int(ok.sum()), "world_error_cm": 100 * float(world.mean()),
            "root_error_cm": 100 * float(root.mean()), "relative_error_cm": 100 * float(rel.mean())}
