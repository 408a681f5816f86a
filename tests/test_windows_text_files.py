"""Files users edit by hand, saved by a Windows editor (a UTF-8 byte-order mark, CRLF line ends), read as the same
files: a generation config, a joint map, a silpose rig file, a recording's cameras.toml. Calibration files and BVH
clips: tests/app/rig/test_formats.py and tests/datagen/test_bvh_blender.py."""

from pathlib import Path

import numpy as np

from silpose.datagen.config import load_config
from silpose.datagen.motion.joint_maps import load_map_file, map_from_spec
from silpose.shared.camera import default_rig, load_rig

ROOT = Path(__file__).resolve().parents[1]


def _windows(text: str, path: Path) -> Path:
    path.write_bytes(b"\xef\xbb\xbf" + text.replace("\r\n", "\n").replace("\n", "\r\n").encode("utf-8"))
    return path


def test_a_generation_config_reads_the_same(tmp_path):
    text = (ROOT / "configs" / "smoke.toml").read_text(encoding="utf-8")
    plain = tmp_path / "plain.toml"
    plain.write_text(text, encoding="utf-8")
    assert load_config(_windows(text, tmp_path / "windows.toml")).to_dict() == load_config(plain).to_dict()


def test_a_joint_map_reads_the_same(tmp_path):
    text = "".join(f'{role} = "{name}"\n' for role, name in map_from_spec("cmu").items())  # a whole map
    plain = tmp_path / "plain.toml"
    plain.write_text(text, encoding="utf-8")
    assert load_map_file(_windows(text, tmp_path / "windows.toml")) == load_map_file(plain)


def test_a_rig_file_reads_the_same(tmp_path):
    rig = default_rig()
    got = load_rig(_windows(rig.to_json(), tmp_path / "rig.json"))
    assert got.names == rig.names
    for a, b in zip(got, rig):
        np.testing.assert_array_equal(a.K, b.K)
        np.testing.assert_array_equal(a.R, b.R)


def test_a_recordings_camera_mapping_reads_the_same(tmp_path):
    import cv2

    from silpose.app.recordings.sources import open_recording

    rig = default_rig()
    cam = rig[1]
    writer = cv2.VideoWriter(str(tmp_path / "left.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 10, (cam.width, cam.height))
    for _ in range(3):
        writer.write(np.zeros((cam.height, cam.width, 3), np.uint8))
    writer.release()
    _windows(f'[cameras]\n{cam.name} = "left.mp4"\n', tmp_path / "cameras.toml")
    rec = open_recording(tmp_path, rig)
    assert list(rec.sources) == [cam.name] and rec.sources[cam.name].path.name == "left.mp4"
