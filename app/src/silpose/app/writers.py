"""What ``silpose infer`` writes, each file atomically (:mod:`silpose.shared.atomic`):

- joints: Parquet (one row per frame; ``<joint>_x/_y/_z`` and ``<joint>_x_std`` ... in metres,
  root-relative, world orientation; file metadata ``silpose_infer``) or JSON (``.json``). The joints
  are the frame's single answer (``silpose.model.hypotheses.single_answer``): the posterior mean,
  or, where the chosen hypothesis (``hypothesis``, 1-based; its ``heading_deg``) faces the other way,
  that hypothesis; chosen along the frames (``silpose.app.inference.apply_temporal``), the chosen hypothesis. Also per frame: ``status`` (``ok``, ``implausible``,
  ``no silhouette``), ``plausibility`` (percentile, ``silpose.model.plausibility``; NaN when the
  model has no calibration), ``views_trimmed`` (the views whose outline robust inference cut a shadow,
  blob or hole from, ``silpose.model.robust.excursions``; comma-separated, empty when none), ``views_reindexed``
  (the views whose points it slid back along their outline, ``silpose.model.robust.reindex``; the same form), and per hypothesis k ``hyp<k>_probability`` / ``hyp<k>_heading_deg``;
  from cameras (one person: ``--people 1``, ``--frames``), the answer placed in the room: ``root_x/_y/_z``
  (metres, silpose's frame: z up, floor z = 0; the joints above are then relative to it), ``<joint>_cal_x``
  ... (the joints in the calibration's own frame and units) and ``inside`` (the share of the joints that project
  inside the person's outline in the views used, 2 px; ``silpose.app.recordings.silhouette_fit.share_inside``);
- reconstructed contours: ``<out stem>.contours.npz`` (no pickle);
- view status per (frame, camera): ``<out stem>.segmentation.json`` (one person from cameras: ``--people 1``,
  ``--frames``; :mod:`silpose.app.recordings.one_person`).

:func:`claim_outputs` runs before any of them: it refuses to replace a file silpose did not write
(:mod:`silpose.shared.output_dir`).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from silpose.model.hypotheses import heading, single_answer
from silpose.shared.atomic import atomic_open, atomic_path, write_text_atomic
from silpose.shared.output_dir import claim_files, claim_folder
from silpose.shared.skeleton import JOINT_NAMES

from .view_status import VIEW_EMPTY, VIEW_ENDED, VIEW_NO_VIDEO, VIEW_NOT_MODELLED, VIEW_OK, VIEW_TOO_SMALL

UNITS = "metres, root-relative (pelvis at the origin), world orientation"
#: the units of the root and the calibration-frame joints of a placed answer (``write_joints``'s ``world``)
PLACED_UNITS = ("root_x/_y/_z: metres, silpose's frame (z up, floor z = 0); <joint>_cal_x/_y/_z: the joints in the "
                "calibration's own frame and units (metadata 'transform')")


def sibling(out: Path, suffix: str) -> Path:
    """``<out stem><suffix>`` next to the joints file ``out`` (e.g. ``j.parquet`` -> ``j.contours.npz``)."""
    out = Path(out)
    return out.with_name(out.name.rsplit(".", 1)[0] + suffix)


def is_joints_file(path: Path) -> bool:
    """True if ``path`` is a joints file written by :func:`write_joints` (Parquet with the ``silpose_infer``
    metadata, or JSON with its ``units`` and ``joint_names``)."""
    path = Path(path)
    try:
        if path.suffix.lower() == ".json":
            doc = json.loads(path.read_text())
            return isinstance(doc, dict) and doc.get("units") == UNITS and doc.get("joint_names") == list(JOINT_NAMES)
        return b"silpose_infer" in (pq.read_schema(path).metadata or {})
    except (OSError, ValueError, pa.ArrowException):
        return False


def is_infer_output(path: Path) -> bool:
    """True if ``path`` is a file ``silpose infer`` wrote: a joints file, ``<stem>.contours.npz`` with the
    arrays of :func:`write_contours`, or ``<stem>.segmentation.json`` of :func:`write_segmentation`."""
    path = Path(path)
    try:
        if path.name.endswith(".contours.npz"):
            with np.load(path, allow_pickle=False) as z:
                return {"frames", "views", "contours_norm", "contours_px", "views_present"} <= set(z.files)
        if path.name.endswith(".segmentation.json"):
            doc = json.loads(path.read_text())
            return isinstance(doc, dict) and {"frames_dir", "cameras", "statuses", "frames"} <= set(doc)
    except (OSError, ValueError, EOFError, AttributeError, TypeError):  # AttributeError: a bare .npy array
        return False
    return is_joints_file(path)


def claim_outputs(out: Path, *, contours: bool = False, segmentation: bool = False,
                  overlay_dir: Path | None = None) -> None:
    """Refuse (``OutputFolderError``, one line) unless ``silpose infer`` may write the joints file ``out``,
    its ``.contours.npz`` / ``.segmentation.json`` siblings (when written) and the overlay folder: each file
    is new or was written by silpose infer (:func:`is_infer_output`); the folder is new, empty or marked as
    infer's (then created and marked). Writes nothing else."""
    out = Path(out)
    files = [out] + [sibling(out, suffix) for suffix, on in ((".contours.npz", contours),
                                                             (".segmentation.json", segmentation)) if on]
    claim_files(files, "infer", recognise=is_infer_output)
    if overlay_dir is not None:
        claim_folder(overlay_dir, "infer")


def _view_names(result, rig_names) -> list[str]:
    return [rig_names[v] if rig_names else str(v) for v in result.views]


def answer_joints(result) -> np.ndarray:
    """(N, 19, 3) the single answer per frame (:func:`silpose.model.hypotheses.single_answer`): the posterior
    mean, or the chosen hypothesis where it faces the other way."""
    return single_answer(result.joints, result.hypotheses)


def _optional(a, n: int, fill=np.nan) -> np.ndarray:
    return np.full(n, fill) if a is None else np.asarray(a, dtype=np.float64)


def write_joints(path: Path, frames, result, rig_names, sample_id=None, model_path: str = "", status=None,
                 world=None, transform=None, inside=None) -> None:
    """Write the joints of an InferenceResult of N frames (module doc).

    Args:
        path: ``.parquet`` or ``.json``.
        frames: (N,) frame names; result: ``ShapeStructureModel.infer``'s result over the K modelled views.
        rig_names: the rig's camera names (None: views are named by their indices).
        sample_id: optional (N,) dataset sample ids; model_path: recorded in the file.
        status: optional (N,) str frame statuses (``silpose.app.inference.frame_status``).
        world: optional (N, 19, 3) metres, silpose's frame: the answer placed in the room (NaN rows: not placed);
            the file's joints are then its joints relative to its root, and the root is written too.
        transform: with ``world``, the rig's ``WorldTransform`` (silpose's frame -> the calibration's).
        inside: optional (N,) share of the placed joints inside the person's outlines in the views used (NaN: none).
    """
    path = Path(path)
    n = len(frames)
    names = _view_names(result, rig_names)
    joints = answer_joints(result)
    root = cal = None
    if world is not None:
        world = np.asarray(world, dtype=np.float64)
        placed = np.isfinite(world).all(axis=(1, 2))
        root = world[:, 0].copy()
        joints = np.where(placed[:, None, None], world - root[:, None], joints)
        cal = transform.to_calibration(world.reshape(-1, 3)).reshape(world.shape)
    head = np.degrees(heading(joints))
    plaus = _optional(result.plausibility, n)
    hyp = result.hypotheses
    trimmed, reindexed = (np.zeros(result.views_present.shape, dtype=bool) if flags is None else
                          np.asarray(flags, dtype=bool) for flags in (result.excursions_trimmed, result.reindexed))
    if path.suffix.lower() == ".json":
        doc = {
            "model": model_path,
            "units": UNITS,
            **({} if root is None else {"root_units": PLACED_UNITS, "transform": transform.to_dict()}),
            "joint_names": list(JOINT_NAMES),
            "views": names,
            "frames": [
                {
                    "frame": str(frames[i]),
                    **({"sample_id": int(sample_id[i])} if sample_id is not None else {}),
                    "views_present": [names[k] for k in np.flatnonzero(result.views_present[i])],
                    "views_trimmed": [names[k] for k in np.flatnonzero(trimmed[i])],
                    "views_reindexed": [names[k] for k in np.flatnonzero(reindexed[i])],
                    **({"status": str(status[i])} if status is not None else {}),
                    "plausibility": None if not np.isfinite(plaus[i]) else float(plaus[i]),
                    "heading_deg": None if not np.isfinite(head[i]) else float(head[i]),
                    "joints": joints[i].round(6).tolist(),
                    **({} if root is None else {
                        "root": None if not np.isfinite(root[i]).all() else root[i].round(6).tolist(),
                        "joints_calibration": None if not np.isfinite(cal[i]).all() else cal[i].round(6).tolist()}),
                    **({} if inside is None else {
                        "inside": None if not np.isfinite(inside[i]) else round(float(inside[i]), 4)}),
                    "joint_std": result.joint_std[i].round(6).tolist(),
                    "log_marginal": float(result.log_marginal[i]),
                    "component": int(np.argmax(result.responsibilities[i])),
                    **({} if hyp is None else {
                        "hypothesis": int(hyp.chosen[i]) + 1,
                        "hypotheses": [{"probability": float(hyp.probability[i, k]),
                                        "heading_deg": float(np.degrees(hyp.heading[i, k])),
                                        "joints": hyp.joints[i, k].round(6).tolist()}
                                       for k in range(hyp.k) if hyp.component[i, k] >= 0]}),
                }
                for i in range(n)
            ],
        }
        write_text_atomic(path, json.dumps(doc, indent=1))
        return
    cols: dict = {"frame": pa.array([str(f) for f in frames])}
    if sample_id is not None:
        cols["sample_id"] = pa.array(np.asarray(sample_id, dtype=np.int64))
    cols["n_views_present"] = pa.array(result.views_present.sum(1).astype(np.int32))
    cols["views_present"] = pa.array([",".join(names[k] for k in np.flatnonzero(r)) for r in result.views_present])
    cols["views_trimmed"] = pa.array([",".join(names[k] for k in np.flatnonzero(r)) for r in trimmed])
    cols["views_reindexed"] = pa.array([",".join(names[k] for k in np.flatnonzero(r)) for r in reindexed])
    if status is not None:
        cols["status"] = pa.array([str(x) for x in status])
    cols["plausibility"] = pa.array(plaus.astype(np.float32))
    cols["log_marginal"] = pa.array(result.log_marginal)
    cols["component"] = pa.array(np.argmax(np.nan_to_num(result.responsibilities, nan=-1.0), axis=1).astype(np.int32))
    cols["heading_deg"] = pa.array(head.astype(np.float32))
    if hyp is not None:
        cols["hypothesis"] = pa.array((hyp.chosen + 1).astype(np.int32))
        for k in range(hyp.k):
            cols[f"hyp{k + 1}_probability"] = pa.array(hyp.probability[:, k])
            cols[f"hyp{k + 1}_heading_deg"] = pa.array(np.degrees(hyp.heading[:, k]).astype(np.float32))
    for j, jn in enumerate(JOINT_NAMES):
        for a, axis in enumerate("xyz"):
            cols[f"{jn}_{axis}"] = pa.array(joints[:, j, a].astype(np.float32))
    for j, jn in enumerate(JOINT_NAMES):
        for a, axis in enumerate("xyz"):
            cols[f"{jn}_{axis}_std"] = pa.array(result.joint_std[:, j, a].astype(np.float32))
    if root is not None:
        for a, axis in enumerate("xyz"):
            cols[f"root_{axis}"] = pa.array(root[:, a].astype(np.float32))
        for j, jn in enumerate(JOINT_NAMES):
            for a, axis in enumerate("xyz"):
                cols[f"{jn}_cal_{axis}"] = pa.array(cal[:, j, a])
    if inside is not None:
        cols["inside"] = pa.array(np.asarray(inside, np.float32))
    meta = {"model": model_path, "units": UNITS, "joint_names": list(JOINT_NAMES), "views": names}
    if root is not None:
        meta["root_units"] = PLACED_UNITS
        meta["transform"] = transform.to_dict()
    table = pa.table(cols).replace_schema_metadata({b"silpose_infer": json.dumps(meta).encode()})
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, compression="zstd")


def write_contours(path: Path, frames, result, rig_names) -> None:
    """Reconstructed contours (.npz, no pickle): frames (N,) str, views (K,) str, contours_norm / contours_px
    (N, K, n, 2) (px NaN where the view's normalisation is unknown), views_present (N, K)."""
    names = np.array(_view_names(result, rig_names))
    with atomic_open(path, "wb") as f:
        np.savez(f, frames=np.asarray(frames).astype(str), views=names, contours_norm=result.contours_norm,
                 contours_px=result.contours_px, views_present=result.views_present)


def write_segmentation(path: Path, fr, root: Path, min_area: str) -> None:
    """Per (frame, camera) view status (:mod:`.view_status`) and blob area as JSON.

    fr: the one-person run's result (frames (N,), cameras (K,), status (N, K) str, area (N, K) px);
    min_area: the minimum blob area, as the file explains ``too small``.
    """
    meaning = {VIEW_OK: "used", VIEW_NO_VIDEO: "no frames or video for this camera (missing view)",
               VIEW_EMPTY: "segmentation found no foreground (missing view for this frame)",
               VIEW_TOO_SMALL: f"largest blob under {min_area} (missing view for this frame)",
               VIEW_ENDED: "the camera's video ended before the others (missing view from there on)",
               VIEW_NOT_MODELLED: "the model does not use this camera"}
    doc = {
        "frames_dir": str(root),
        "cameras": list(fr.cameras),
        "statuses": meaning,
        "counts": {c: {s: int((fr.status[:, k] == s).sum()) for s in meaning} for k, c in enumerate(fr.cameras)},
        "frames": [{"frame": str(f), "status": [str(s) for s in fr.status[i]], "area_px": fr.area[i].tolist()}
                   for i, f in enumerate(fr.frames)],
    }
    write_text_atomic(path, json.dumps(doc, indent=1))
