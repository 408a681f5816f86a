"""Phone videos: a portrait video stored as landscape frames plus a display rotation in its metadata is read upright,
as players show it, unless only its stored frames fit the rig camera (silpose.app.recordings.sources, "Orientation").

The rotation is written into the MP4's track header (the 3 x 3 display matrix of ISO/IEC 14496-12 ``tkhd``), as a
phone writes it. The upright frames expected are the stored ones turned by ``np.rot90(stored, -rotation / 90)``:
FFmpeg's own command-line tool extracts exactly those from such files (checked by hand for 90, 180 and 270 degrees;
the tool is not installed in CI).
"""

import dataclasses
import struct

import numpy as np
import pytest

from silpose.app.inputs.images import display_rotation
from silpose.app.recordings.sources import CameraReader, open_recording
from silpose.app.rig.image_size import media_size
from silpose.shared.camera import Rig


def rotate_mp4(path, degrees: int) -> None:
    """Write a display rotation of ``degrees`` into the track header of the MP4 file ``path`` (in place)."""
    data = bytearray(path.read_bytes())
    at = data.find(b"tkhd")
    assert at > 0, "no track header"
    version = data[at + 4]
    matrix = at + 4 + 4 + (20 if version == 0 else 32) + 16  # after version/flags, times, ids, duration, layer...
    c, s = int(round(np.cos(np.deg2rad(degrees)))), int(round(np.sin(np.deg2rad(degrees))))
    data[matrix:matrix + 36] = struct.pack(">9i", c << 16, s << 16, 0, -s << 16, c << 16, 0, 0, 0, 1 << 30)
    path.write_bytes(bytes(data))


def _stored_frames(n=3, h=486, w=644):
    """Grey frames with an asymmetric mark (a bar near the top-left), so that every quarter turn differs."""
    f = np.zeros((n, h, w), np.uint8)
    f[:, 40:120, 60:400] = 255
    f[:, 40:300, 60:140] = 255
    return f


def _with_camera(rig, name, width, height) -> Rig:
    cams = tuple(dataclasses.replace(c, width=width, height=height) if c.name == name else c for c in rig)
    return Rig(cams, rig.transform, rig.workspace, rig.source)


def _iou(a, b):
    a, b = a > 127, b > 127
    return (a & b).sum() / (a | b).sum()


@pytest.mark.parametrize("degrees", [90, 270])
def test_a_portrait_phone_video_is_read_upright_for_a_portrait_camera(rig, tools, tmp_path, degrees):
    stored = _stored_frames()
    path = tmp_path / "cam2.mp4"
    tools.write_video(path, stored)
    rotate_mp4(path, degrees)
    portrait = _with_camera(rig, "cam2", 486, 644)
    rec = open_recording(tmp_path, portrait)
    src = rec.sources["cam2"]
    assert (src.rotation, src.upright, src.width, src.height) == (degrees, True, 486, 644)
    assert any("cam2.mp4" in w and f"by {degrees} degrees" in w and "read upright (486x644)" in w for w in rec.warnings)
    frame = CameraReader(src, grey=True).read()
    assert frame.shape == (644, 486)
    want = np.rot90(stored[0], -degrees // 90)
    assert _iou(frame, want) > 0.97
    assert _iou(frame, np.rot90(stored[0], degrees // 90)) < 0.5  # not the other quarter turn
    assert media_size(path) == (486, 644)  # rig import's image-size probe agrees


def test_a_rotated_video_whose_stored_frames_fit_the_camera_is_read_as_stored(rig, tools, tmp_path):
    stored = _stored_frames()
    path = tmp_path / "cam2.mp4"
    tools.write_video(path, stored)
    rotate_mp4(path, 90)
    rec = open_recording(tmp_path, rig)  # the lab rig's cam2 is 644x486: calibrated on the stored frames
    src = rec.sources["cam2"]
    assert (src.upright, src.width, src.height) == (False, 644, 486)
    assert any("cam2.mp4" in w and "read as stored" in w for w in rec.warnings)
    frame = CameraReader(src, grey=True).read()
    assert frame.shape == (486, 644) and _iou(frame, stored[0]) > 0.97


def test_a_half_turn_is_read_upright_with_a_way_back(rig, tools, tmp_path):
    stored = _stored_frames()
    path = tmp_path / "cam2.mp4"
    tools.write_video(path, stored)
    rotate_mp4(path, 180)
    rec = open_recording(tmp_path, rig)  # both orientations fit: as players show it, and the warning says how to undo
    src = rec.sources["cam2"]
    assert (src.rotation, src.upright) == (180, True)
    assert any("read upright" in w and "rotate=0" in w for w in rec.warnings)
    frame = CameraReader(src, grey=True).read()
    assert _iou(frame, stored[0, ::-1, ::-1]) > 0.97


def test_videos_without_a_rotation_are_read_as_before(rig, tools, tmp_path):
    import cv2

    path = tmp_path / "cam2.mp4"
    tools.write_video(path, _stored_frames())
    cap = cv2.VideoCapture(str(path))
    assert display_rotation(cap) == 0
    cap.release()
    rec = open_recording(tmp_path, rig)
    assert (rec.sources["cam2"].rotation, rec.sources["cam2"].upright) == (0, False)
    assert not any("degrees" in w for w in rec.warnings)
