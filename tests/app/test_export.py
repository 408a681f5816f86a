"""``silpose export``: the joints of a recording and of a dataset's inference, written as TRC, C3D and BVH and
read back by independent readers (a TRC parser written here from OpenSim's layout, the ``c3d`` library's
reader, Blender's own BVH importer in a spawned worker) equal to the joints within 0.1 mm, with the units,
axes and frame rate the file states."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from silpose.app.export.formats import EXPORTERS, get_exporter
from silpose.app.export.motion import ExportInputError, read_motion
from silpose.shared.cli import build_app
from silpose.shared.rig_frame import WorldTransform
from silpose.shared.skeleton import JOINT_NAMES

TOL_M = 1e-4  # 0.1 mm
FPS = 25.0
ROT = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])  # calibration frame: y down-ish, z forward
TRANSFORM = WorldTransform(ROT, 0.001, np.array([0.5, -0.2, 0.0]))  # millimetres


def _fixed(a):
    arr = pa.array(np.ascontiguousarray(a, np.float32).reshape(-1))
    for d in reversed(a.shape[1:]):
        arr = pa.FixedSizeListArray.from_arrays(arr, d)
    return arr


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A recording's joints.parquet in the layout of silpose.app.recordings.writers: 2 persons, 12 steps,
    person 1 without joints at step 4."""
    rng = np.random.default_rng(3)
    base = rng.normal(0, 0.3, (19, 3)) + [0, 0, 1.0]
    t = np.arange(12)
    frames, persons, world = [], [], []
    for p in (1, 2):
        for k in t:
            j = base + [0.05 * k, 0.3 * p, 0.02 * np.sin(k)] + rng.normal(0, 0.01, (19, 3))
            if p == 1 and k == 4:
                j = np.full((19, 3), np.nan)
            frames.append(k), persons.append(p), world.append(j)
    world = np.array(world)
    cal = np.array([TRANSFORM.to_calibration(w) for w in world])
    meta = {"fps": FPS, "joint_names": list(JOINT_NAMES), "transform": TRANSFORM.to_dict()}
    table = pa.table({"frame": pa.array(frames, pa.int64()), "person": pa.array(persons, pa.int32()),
                      "joints": _fixed(world), "joints_calibration": _fixed(cal)})
    path = tmp_path_factory.mktemp("rec") / "joints.parquet"
    pq.write_table(table.replace_schema_metadata({b"silpose_recording": json.dumps(meta).encode()}), path)
    return path, world.reshape(2, 12, 19, 3), cal.reshape(2, 12, 19, 3)


def read_trc(path):
    """An independent TRC reader (OpenSim's layout): header values by name, marker names, coordinates."""
    lines = path.read_text().split("\n")
    assert lines[0].split("\t")[:3] == ["PathFileType", "4", "(X/Y/Z)"]
    header = dict(zip(lines[1].split("\t"), lines[2].split("\t")))
    names = [n for n in lines[3].split("\t")[2:] if n]
    rows = [ln.split("\t") for ln in lines[6:] if ln.strip()]
    xyz = np.array([[float(v) if v else np.nan for v in r[2:]] for r in rows]).reshape(len(rows), len(names), 3)
    times = np.array([float(r[1]) for r in rows])
    return header, names, xyz, times


def test_trc_reads_back_in_opensim_axes(recording, tmp_path):
    path, world, _ = recording
    res = CliRunner().invoke(build_app(), ["export", str(path), "--to", "trc", "--person", "1", "-o",
                                           str(tmp_path / "p1.trc")])
    assert res.exit_code == 0, res.output
    header, names, xyz, times = read_trc(tmp_path / "p1.trc")
    assert names == list(JOINT_NAMES) and header["Units"] == "m" and float(header["DataRate"]) == FPS
    assert int(header["NumFrames"]) == 12 and int(header["NumMarkers"]) == 19
    np.testing.assert_allclose(times, np.arange(12) / FPS, atol=1e-6)
    expected = np.stack([world[0][..., 0], world[0][..., 2], -world[0][..., 1]], -1)  # Y up
    assert np.isnan(xyz[4]).all()
    ok = np.arange(12) != 4
    assert np.abs(xyz[ok] - expected[ok]).max() < TOL_M


@pytest.mark.parametrize("fmt, person", [("trc", 1), ("c3d", 2)])
def test_an_export_is_a_motion_clip(recording, tmp_path, fmt, person):
    """``silpose export --to trc|c3d`` then ``silpose motions import``'s keypoint reader: the joints come back in
    silpose's frame (TRC: Y up; C3D: its screen axes), a frame without joints filled from its neighbours."""
    from silpose.datagen.motion.keypoint_clips import read_keypoint_clip

    path, world, _ = recording
    out = tmp_path / f"p{person}.{fmt}"
    res = CliRunner().invoke(build_app(), ["export", str(path), "--to", fmt, "--person", str(person), "-o", str(out)])
    assert res.exit_code == 0, res.output
    meta, heads, _ = read_keypoint_clip(out)
    assert meta["frame_time"] == pytest.approx(1 / FPS) and meta["frames"] == 12
    truth = world[person - 1].copy()
    if person == 1:  # step 4 has no joints: filled halfway between its neighbours
        truth[4] = 0.5 * (truth[3] + truth[5])
    for i, role in enumerate(meta["names"]):
        assert np.abs(heads[:, i] - truth[:, JOINT_NAMES.index(role)]).max() < TOL_M


def test_trc_in_the_calibration_frame_and_units(recording, tmp_path):
    path, _, cal = recording
    out = tmp_path / "p2.trc"
    res = CliRunner().invoke(build_app(), ["export", str(path), "--to", "trc", "--person", "2", "--frame",
                                           "calibration", "-o", str(out)])
    assert res.exit_code == 0, res.output
    header, _, xyz, _ = read_trc(out)
    assert header["Units"] == "mm"
    assert np.abs(xyz - cal[1]).max() < TOL_M * 1000  # 0.1 mm in millimetres


def test_c3d_reads_back_with_the_c3d_library(recording, tmp_path):
    import c3d

    path, world, _ = recording
    out = tmp_path / "p1.c3d"
    res = CliRunner().invoke(build_app(), ["export", str(path), "--to", "c3d", "--person", "1", "-o", str(out)])
    assert res.exit_code == 0, res.output
    with open(out, "rb") as handle:
        reader = c3d.Reader(handle)
        labels = [s.strip() for s in reader.point_labels]
        units = reader.get("POINT:UNITS").string_value.strip()
        rate, y_screen = reader.point_rate, reader.get("POINT:Y_SCREEN").string_value.strip()
        frames = [(points.copy()) for _, points, _ in reader.read_frames()]
    points = np.array(frames)
    assert labels == list(JOINT_NAMES) and units == "m" and rate == FPS and y_screen == "+Z"
    assert (points[4, :, 3] < 0).all() and (np.delete(points, 4, 0)[:, :, 3] >= 0).all()  # frame 4 invalid
    ok = np.arange(12) != 4
    assert np.abs(points[ok, :, :3] - world[0][ok]).max() < TOL_M


def test_bvh_reads_back_with_blenders_importer(recording, tmp_path):
    from silpose.datagen.blender.bvh import import_clip
    from silpose.datagen.executor import spawned_map

    path, world, _ = recording
    out = tmp_path / "p2.bvh"
    res = CliRunner().invoke(build_app(), ["export", str(path), "--to", "bvh", "--person", "2", "-o", str(out)])
    assert res.exit_code == 0, res.output
    [(_, (meta, heads, _tails))] = list(spawned_map(import_clip, [(0, str(out))], workers=1))
    got = heads[:, [meta["names"].index(n) for n in JOINT_NAMES]]  # Blender's z up = silpose's frame
    assert got.shape == (12, 19, 3)
    assert meta["frame_time"] == pytest.approx(1 / FPS, abs=1e-6)
    assert np.abs(got - world[1]).max() < TOL_M
    assert "Yposition" in out.read_text().split("MOTION")[0]


def test_inputs_and_errors(recording, tmp_path):
    path, _, _ = recording
    with pytest.raises(ExportInputError, match=r"persons 1, 2; choose one \(--person\)"):
        read_motion(path)
    with pytest.raises(ExportInputError, match=r"unknown format 'fbx'; choose one of trc, c3d, bvh \(--to\)"):
        get_exporter("fbx")
    assert [e.name for e in EXPORTERS] == ["trc", "c3d", "bvh"]
    notes = tmp_path / "notes.txt"
    notes.write_text("x")
    res = CliRunner().invoke(build_app(), ["export", str(notes), "--to", "trc"])
    assert res.exit_code == 2 and res.stderr.startswith("silpose export: error: ") and res.stderr.count("\n") == 1
    mine = tmp_path / "mine.trc"
    mine.write_text("my own file\n")
    res = CliRunner().invoke(build_app(), ["export", str(path), "--to", "trc", "--person", "1", "-o", str(mine)])
    assert res.exit_code == 2 and mine.read_text() == "my own file\n"  # never replaces a file silpose did not write
