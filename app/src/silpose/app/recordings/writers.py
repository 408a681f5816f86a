"""``joints.parquet`` and ``joints.csv`` of a recording, written as rows arrive (memory does not grow).

One row per person per time step (rows ordered by frame, then person). Columns:

=================== ============================================================================
frame               time step: the frame index of cameras without an offset, on the time grid of the fastest
                    camera (:mod:`.sources`, "Time stamps") (int64)
time                seconds, ``frame / fps`` (NaN when no video states its frame rate)
person              person id, 1, 2, ... (stable over the recording)
status              ``ok`` (joints inferred), ``implausible`` (joints inferred, but the input is below
                    the model's plausibility threshold: not one person, a broken silhouette?), ``no usable view`` (on the floor, but every view
                    merged, cut or missing: no joints), ``not detected`` (the person's track
                    bridged this step without a detection: no joints)
floor_x, floor_y    metres, silpose's frame: where the floor grid found the person (NaN: not detected)
n_views, views      usable views and their camera names (comma-separated)
view_status         per rig camera, why the view was or was not used (``silpose.app.recordings.views``)
view_cut            per rig camera, the share (0-1) of the person's blob cut off as unsupported by the other
                    views before the view was judged (``silpose.app.recordings.hull``; 0: nothing cut; NaN: no
                    blob, or not carved)
log_marginal        the model's log density of the observed views (NaN without joints)
plausibility        that density as a percentile (0-100) of held-out training inputs with the same
                    views (``silpose.model.plausibility``; NaN when the model has no calibration)
hypothesis          the slot (1-based) of the answer among the top-K hypotheses, chosen along the person's
                    track (``silpose.app.recordings.chunk_rows.choose_along_tracks``; 0: none)
hypothesis_probability  its posterior probability
inside              the share (0-1) of the joints, over the views used, that project inside the person's own
                    outline there (2 px of tolerance; ``silhouette_fit.share_inside``): how well the answer agrees
                    with the silhouettes it came from, a check needing no ground truth (NaN without joints)
joints              (19, 3) metres, silpose's frame (z up, floor z = 0): root placed in the room
joints_calibration  (19, 3) the same joints in the calibration's own frame and units
joint_std           (19, 3) metres, the posterior standard deviation per coordinate
root, root_calibration  (3,) the pelvis, both frames
contours_px         (K, n, 2) px, every modelled view's reconstructed contour (missing views projected);
                    only with ``contours=True`` (``--contours``): it is most of the file and of the
                    writing time (~1 ms per row, measured with zstd on this machine)
=================== ============================================================================

Nested columns are fixed-size lists (DuckDB, Polars and pandas read them). The schema metadata key
``silpose_recording`` holds one JSON document: joint and camera names, units, the world transform and
workspace, the frame rate, the model, the per-view statuses' meanings. The CSV has the same rows with the
nested columns flattened (``<joint>_x`` ... in silpose's frame, ``<joint>_cal_x`` ... in the calibration's,
``<joint>_std_x`` ...) and no contours. Both files are written to temporary names and renamed when the
run ends (:mod:`silpose.shared.atomic`), :data:`ROW_GROUP` rows at a time (a Parquet row group; the CSV
through ``pyarrow.csv``).
"""

from __future__ import annotations

import json
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from silpose.shared.atomic import atomic_open, atomic_path
from silpose.shared.skeleton import JOINT_NAMES, N_JOINTS

STATUS_OK = "ok"
STATUS_NO_VIEW = "no usable view"
STATUS_NOT_DETECTED = "not detected"
STATUS_IMPLAUSIBLE = "implausible"
ROW_STATUSES = (STATUS_OK, STATUS_IMPLAUSIBLE, STATUS_NO_VIEW, STATUS_NOT_DETECTED)
#: rows per Parquet row group (with 4 views of 200 contour points, ~4 MB held at most)
ROW_GROUP = 512


@dataclass
class PersonRows:
    """Rows of R (person, step) pairs; arrays lead with R. K rig cameras, V modelled views, n contour points.

    frame (R,) int; person (R,) int; status (R,) str; floor (R, 2); view_status (R, K) str; views_used
    (R, K) bool; view_cut (R, K) float; log_marginal, plausibility (R,); hypothesis (R,) int; hypothesis_probability (R,); joints, joints_calibration, joint_std (R, 19, 3); root,
    root_calibration (R, 3); contours (R, V, n, 2); inside (R,) float.
    """

    frame: np.ndarray
    person: np.ndarray
    status: np.ndarray
    floor: np.ndarray
    view_status: np.ndarray
    views_used: np.ndarray
    view_cut: np.ndarray
    log_marginal: np.ndarray
    plausibility: np.ndarray
    hypothesis: np.ndarray
    hypothesis_probability: np.ndarray
    joints: np.ndarray
    joints_calibration: np.ndarray
    joint_std: np.ndarray
    root: np.ndarray
    root_calibration: np.ndarray
    contours: np.ndarray
    inside: np.ndarray

    def __len__(self) -> int:
        return len(self.frame)

    def take(self, idx) -> "PersonRows":
        return PersonRows(**{f: getattr(self, f)[idx] for f in self.__dataclass_fields__})

    @staticmethod
    def concat(parts: list["PersonRows"]) -> "PersonRows":
        return PersonRows(**{f: np.concatenate([getattr(p, f) for p in parts]) for f in PersonRows.__dataclass_fields__})


def _fixed(a: np.ndarray) -> pa.Array:
    """A nested fixed-size list array of float32 from an (R, d1, d2, ...) array."""
    a = np.ascontiguousarray(a, np.float32)
    arr = pa.array(a.reshape(-1))
    for d in reversed(a.shape[1:]):
        arr = pa.FixedSizeListArray.from_arrays(arr, d)
    return arr


class RecordingWriter:
    """Streams :class:`PersonRows` to ``joints.parquet`` and ``joints.csv`` (module docstring).

    Args:
        parquet, csv_path: output files. cameras: rig camera names; views: the modelled views' names;
        n_points: contour points; fps: frames per second (0: unknown); meta: the metadata document;
        contours: also write the ``contours_px`` column.
    """

    def __init__(self, parquet: Path, csv_path: Path, cameras, views, n_points: int, fps: float, meta: dict,
                 contours: bool = False):
        self.cameras, self.views, self.n_points = list(cameras), list(views), int(n_points)
        self.contours = bool(contours)
        self.fps = float(fps)
        self.n_rows = 0
        self.counts = dict.fromkeys(ROW_STATUSES, 0)
        self._inside = [0.0, 0]  # sum and count of the inside column over rows with joints
        self._stack = ExitStack()
        tmp = self._stack.enter_context(atomic_path(parquet))
        self.schema = self._schema().with_metadata({b"silpose_recording": json.dumps(meta).encode()})
        self._pq = self._stack.enter_context(pq.ParquetWriter(tmp, self.schema, compression="zstd"))
        self._held: list[PersonRows] = []
        head = [("frame", pa.int64()), ("time", pa.float64()), ("person", pa.int32()), ("status", pa.string()),
                ("n_views", pa.int8()), ("views", pa.string()), ("log_marginal", pa.float64()),
                ("plausibility", pa.float32()), ("hypothesis", pa.int8()), ("hypothesis_probability", pa.float32()),
                ("inside", pa.float32()), ("floor_x", pa.float32()), ("floor_y", pa.float32())]
        flat = [f"root_{a}" for a in "xyz"] + [f"root_cal_{a}" for a in "xyz"]
        for tag in ("", "_cal", "_std"):
            flat += [f"{j}{tag}_{a}" for j in JOINT_NAMES for a in "xyz"]
        self.csv_schema = pa.schema(head + [(c, pa.float32()) for c in flat])
        csv_file = self._stack.enter_context(atomic_open(csv_path, "wb"))
        self._csv = self._stack.enter_context(pacsv.CSVWriter(csv_file, self.csv_schema))

    def _schema(self) -> pa.Schema:
        j = pa.list_(pa.list_(pa.float32(), 3), N_JOINTS)
        v3 = pa.list_(pa.float32(), 3)
        fields = [
            ("frame", pa.int64()), ("time", pa.float64()), ("person", pa.int32()), ("status", pa.string()),
            ("floor_x", pa.float32()), ("floor_y", pa.float32()), ("n_views", pa.int8()), ("views", pa.string()),
            ("view_status", pa.list_(pa.string(), len(self.cameras))),
            ("view_cut", pa.list_(pa.float32(), len(self.cameras))), ("log_marginal", pa.float64()),
            ("plausibility", pa.float32()), ("hypothesis", pa.int8()), ("hypothesis_probability", pa.float32()),
            ("inside", pa.float32()), ("joints", j), ("joints_calibration", j), ("joint_std", j), ("root", v3), ("root_calibration", v3),
        ]
        if self.contours:
            fields.append(("contours_px", pa.list_(pa.list_(pa.list_(pa.float32(), 2), self.n_points), len(self.views))))
        return pa.schema(fields)

    def write(self, rows: PersonRows) -> None:
        """Append rows (written :data:`ROW_GROUP` at a time)."""
        if not len(rows):
            return
        self._held.append(rows)
        if sum(len(r) for r in self._held) >= ROW_GROUP:
            self._flush()
        self.n_rows += len(rows)
        ok = np.isfinite(rows.inside)
        self._inside[0] += float(rows.inside[ok].sum())
        self._inside[1] += int(ok.sum())
        for s in rows.status:
            self.counts[str(s)] = self.counts.get(str(s), 0) + 1

    @property
    def inside_mean(self) -> float:
        """The mean of the ``inside`` column over the rows written with joints (NaN: none)."""
        return self._inside[0] / self._inside[1] if self._inside[1] else float("nan")

    def _time(self, rows: PersonRows) -> np.ndarray:
        return rows.frame / self.fps if self.fps > 0 else np.full(len(rows), np.nan)

    def _flush(self) -> None:
        if not self._held:
            return
        rows = PersonRows.concat(self._held)
        self._held = []
        R, K = len(rows), len(self.cameras)
        time = self._time(rows)
        names = np.array(self.cameras)
        views = [",".join(names[u]) for u in rows.views_used]
        n_views = rows.views_used.sum(axis=1).astype(np.int8)
        vs = pa.FixedSizeListArray.from_arrays(pa.array(rows.view_status.reshape(-1).astype(str).tolist()), K)
        frame, person = pa.array(rows.frame.astype(np.int64)), pa.array(rows.person.astype(np.int32))
        status, logm = pa.array(rows.status.astype(str).tolist()), pa.array(rows.log_marginal.astype(np.float64))
        fx, fy = pa.array(rows.floor[:, 0].astype(np.float32)), pa.array(rows.floor[:, 1].astype(np.float32))
        plaus = [pa.array(rows.plausibility.astype(np.float32)), pa.array(rows.hypothesis.astype(np.int8)),
                 pa.array(rows.hypothesis_probability.astype(np.float32)), pa.array(rows.inside.astype(np.float32))]
        table = pa.Table.from_arrays([
            frame, pa.array(time), person, status, fx, fy, pa.array(n_views), pa.array(views), vs,
            _fixed(rows.view_cut), logm, *plaus,
            _fixed(rows.joints), _fixed(rows.joints_calibration), _fixed(rows.joint_std), _fixed(rows.root),
            _fixed(rows.root_calibration),
        ] + ([_fixed(rows.contours)] if self.contours else []), schema=self.schema)
        self._pq.write_table(table)
        flat = np.concatenate([rows.root, rows.root_calibration, rows.joints.reshape(R, -1),
                               rows.joints_calibration.reshape(R, -1), rows.joint_std.reshape(R, -1)], axis=1)
        flat = flat.astype(np.float32)
        self._csv.write_table(pa.Table.from_arrays(
            [frame, pa.array(time), person, status, pa.array(n_views), pa.array(views), logm, *plaus, fx, fy]
            + [pa.array(flat[:, c]) for c in range(flat.shape[1])], schema=self.csv_schema))

    def close(self) -> None:
        """Finish both files (rename them into place)."""
        try:
            self._flush()
        except BaseException:
            self.abort()
            raise
        self._stack.close()

    def abort(self) -> None:
        """Drop both files (the temporary names are removed; nothing appears under the final names)."""
        self._stack.__exit__(RuntimeError, RuntimeError("aborted"), None)
