"""The joints files ``silpose infer`` writes, read into one :class:`Motion` for the exporters.

Inputs (recognised by their metadata, not their names):

- a recording's ``joints.parquet`` (schema metadata ``silpose_recording``): one row per person and time step,
  ``joints`` (19, 3) in silpose's frame (metres, z up, floor z = 0) and ``joints_calibration`` in the
  calibration's frame and units; the frame rate from the metadata. ``person`` picks one person (needed when
  there are several);
- a recording's ``joints.csv``: the same rows flattened (``<joint>_x`` ..., ``<joint>_cal_x`` ...), the frame
  rate from the ``time`` column;
- ``silpose infer``'s joints file of a dataset or a folder of silhouette images (Parquet with metadata
  ``silpose_infer``): one row per frame, ``<joint>_x/_y/_z`` root-relative (pelvis at the origin) in metres,
  world orientation; it has no calibration frame and no frame rate (``fps``, default 30). One person's from
  cameras (``--people 1``) also holds the root placed in the room (``root_x/_y/_z``) and the joints in the
  calibration's frame (``<joint>_cal_x`` ...; the transform in the metadata): exported in the room, either frame.

Frames without joints (a person not detected, every view missing) stay in the motion as NaN rows: each
exporter says how it writes them.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from silpose.shared.skeleton import JOINT_NAMES, N_JOINTS

from ..errors import InputError

__all__ = ["Motion", "ExportInputError", "read_motion", "FRAMES", "DEFAULT_FPS", "unit_name"]

#: ``--frame`` values: silpose's world frame, or the calibration's own frame and units (recordings only).
FRAMES = ("silpose", "calibration")
DEFAULT_FPS = 30.0
_UNITS = {1.0: "m", 0.01: "cm", 0.001: "mm"}


class ExportInputError(InputError):
    """A joints file that cannot be exported; one line naming the file (and field or flag)."""


@dataclass(frozen=True)
class Motion:
    """Joints over time, ready to export.

    Attributes:
        joints: (T, 19, 3) float64, in ``units``; NaN rows where a frame has no joints.
        frames: (T,) int64 frame numbers (0-based).
        fps: frames per second.
        units: ``m``, ``cm``, ``mm`` (or ``unit`` for a calibration of another scale).
        up: the up axis, ``z`` (silpose's frame) or as the calibration has it (``+y``, ``-z`` ...).
        frame: ``silpose`` or ``calibration``.
        root_relative: True when the pelvis is at the origin in every frame (a dataset's or PNG folder's joints).
        source: the file read, for messages and file headers.
    """

    joints: np.ndarray
    frames: np.ndarray
    fps: float
    units: str
    up: str
    frame: str
    root_relative: bool
    source: str

    @property
    def names(self) -> tuple[str, ...]:
        return JOINT_NAMES


def unit_name(metres_per_unit: float) -> str:
    return next((n for s, n in _UNITS.items() if np.isclose(metres_per_unit, s, rtol=1e-9)), "unit")


def _up_name(vector) -> str:
    v = np.asarray(vector, float)
    k = int(np.argmax(np.abs(v)))
    return ("+" if v[k] > 0 else "-") + "xyz"[k]


def _meta(path: Path, key: bytes) -> dict | None:
    import pyarrow.parquet as pq

    raw = (pq.read_schema(path).metadata or {}).get(key)
    return None if raw is None else json.loads(raw)


def _pick_person(path: Path, persons: np.ndarray, person: int | None) -> np.ndarray:
    ids = sorted(set(int(p) for p in persons))
    if person is None:
        if len(ids) != 1:
            raise ExportInputError(f"{path}: holds persons {', '.join(map(str, ids))}; choose one (--person)")
        person = ids[0]
    if person not in ids:
        raise ExportInputError(f"{path}: no person {person}; it holds {', '.join(map(str, ids))} (--person)")
    return persons == person


def _recording(path: Path, meta: dict, frame: str, person: int | None) -> Motion:
    import pyarrow.parquet as pq

    col = "joints_calibration" if frame == "calibration" else "joints"
    table = pq.read_table(path, columns=["frame", "person", col])
    keep = _pick_person(path, table.column("person").to_numpy(), person)
    joints = np.asarray(table.column(col).combine_chunks().flatten().flatten().to_numpy(zero_copy_only=False),
                        float).reshape(-1, N_JOINTS, 3)[keep]
    frames = table.column("frame").to_numpy()[keep].astype(np.int64)
    return _recording_motion(path, meta, joints, frames, frame)


def _recording_motion(path: Path, meta: dict, joints, frames, frame: str, fps: float | None = None) -> Motion:
    fps = float(fps if fps is not None else meta.get("fps") or 0.0)
    if not fps > 0:
        raise ExportInputError(f"{path}: the recording states no frame rate; give one (--fps)")
    if frame == "calibration":
        from silpose.shared.rig_frame import WorldTransform

        transform = WorldTransform.from_dict(meta["transform"]) if meta.get("transform") else WorldTransform()
        units, up = unit_name(transform.scale), _up_name(transform.up_in_calibration)
    else:
        units, up = "m", "+z"
    order = np.argsort(frames, kind="stable")
    return Motion(joints[order], frames[order], fps, units, up, frame, False, str(path))


def _csv(path: Path, frame: str, person: int | None, fps: float | None) -> Motion:
    import pyarrow.csv as pacsv

    table = pacsv.read_csv(path)
    names = set(table.column_names)
    suffix = "_cal" if frame == "calibration" else ""
    cols = [f"{j}{suffix}_{a}" for j in JOINT_NAMES for a in "xyz"]
    missing = [c for c in ["frame", "person", *cols] if c not in names]
    if missing:
        raise ExportInputError(f"{path}: not a joints.csv of silpose infer --videos (no column {missing[0]!r})")
    keep = _pick_person(path, table.column("person").to_numpy(), person)
    joints = np.stack([table.column(c).to_numpy(zero_copy_only=False).astype(float) for c in cols], 1)
    frames = table.column("frame").to_numpy().astype(np.int64)[keep]
    if fps is None and "time" in names:
        t, f = table.column("time").to_numpy(zero_copy_only=False).astype(float)[keep], frames
        ok = np.isfinite(t)
        if ok.sum() >= 2 and np.ptp(t[ok]) > 0:
            fps = float(np.ptp(f[ok]) / np.ptp(t[ok]))
    # the CSV has no metadata: its calibration units and up axis are unknown
    meta = {"fps": fps}
    m = _recording_motion(path, meta, joints.reshape(-1, N_JOINTS, 3)[keep], frames, "silpose", fps)
    if frame == "calibration":
        return Motion(m.joints, m.frames, m.fps, "unit", "unknown", "calibration", False, m.source)
    return m


def _infer_file(path: Path, frame: str, fps: float | None) -> Motion:
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    placed = "root_x" in table.column_names  # one person from cameras: the root placed in the room
    if frame == "calibration" and not placed:
        raise ExportInputError(f"{path}: joints of a dataset or image folder are root-relative in silpose's frame; "
                               "there is no calibration frame to export (--frame silpose)")

    def stack(cols):
        return np.stack([table.column(c).to_numpy(zero_copy_only=False).astype(float) for c in cols], 1)

    frames = np.arange(table.num_rows, dtype=np.int64)
    fps = float(fps or DEFAULT_FPS)
    if not placed:
        joints = stack([f"{j}_{a}" for j in JOINT_NAMES for a in "xyz"]).reshape(-1, N_JOINTS, 3)
        return Motion(joints, frames, fps, "m", "+z", "silpose", True, str(path))
    if frame == "calibration":
        joints = stack([f"{j}_cal_{a}" for j in JOINT_NAMES for a in "xyz"]).reshape(-1, N_JOINTS, 3)
    else:
        rel = stack([f"{j}_{a}" for j in JOINT_NAMES for a in "xyz"]).reshape(-1, N_JOINTS, 3)
        joints = rel + stack([f"root_{a}" for a in "xyz"])[:, None]
    return _recording_motion(path, _meta(path, b"silpose_infer") or {}, joints, frames, frame, fps)


def read_motion(path: str | Path, frame: str = "silpose", person: int | None = None,
                fps: float | None = None) -> Motion:
    """The motion in ``path`` (module docstring) in ``frame``; ExportInputError naming the file otherwise."""
    import pyarrow as pa

    path = Path(path)
    if frame not in FRAMES:
        raise ExportInputError(f"--frame: must be silpose or calibration, got {frame!r}")
    if fps is not None and not fps > 0:
        raise ExportInputError(f"the frame rate must be > 0, got {fps:g} (--fps)")
    if not path.is_file():
        raise ExportInputError(f"{path}: no such joints file")
    try:
        if path.suffix.lower() == ".csv":
            motion = _csv(path, frame, person, fps)
        elif path.suffix.lower() == ".parquet":
            rec = _meta(path, b"silpose_recording")
            if rec is not None:
                motion = _recording(path, rec, frame, person) if fps is None else \
                    _recording(path, {**rec, "fps": fps}, frame, person)
            elif _meta(path, b"silpose_infer") is not None:
                motion = _infer_file(path, frame, fps)
            else:
                raise ExportInputError(f"{path}: not a joints file of silpose infer (no silpose metadata)")
        else:
            raise ExportInputError(f"{path}: export reads the .parquet or .csv joints files silpose infer writes")
    except (OSError, ValueError, KeyError, pa.ArrowException) as exc:
        if isinstance(exc, ExportInputError):
            raise
        raise ExportInputError(f"{path}: cannot read it as a silpose joints file ({exc})") from None
    if len(motion.frames) == 0:
        raise ExportInputError(f"{path}: no frames to export")
    return motion
