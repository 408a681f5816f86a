"""The overlay worker's messages (silpose.app.recordings.overlay_messages): what is packed is read back, field for
field and bit for bit; a malformed or cut message, or a PNG name that leaves its folder, is refused."""

from __future__ import annotations

import io
import json
import struct

import numpy as np
import pytest

from silpose.app.recordings.overlay_messages import END, pack, pack_image, read_message


def _stream(*messages) -> io.BytesIO:
    return io.BytesIO(b"".join(bytes(part) if not isinstance(part, bytes) else part for m in messages for part in m))


def test_a_frame_and_an_image_come_back_as_sent():
    rng = np.random.default_rng(3)
    mask = (rng.random((7, 9)) < 0.5).astype(np.uint8)
    people = [{"person": np.int32(4), "status": np.str_("ok"), "outline": rng.normal(size=(5, 2)), "recon": None,
               "joints_px": rng.normal(size=(19, 2)), "anchor_px": np.array([1.5, -2.0])},
              {"person": 0, "status": "merged", "outline": None, "recon": rng.normal(size=(5, 2)).astype(np.float32),
               "joints_px": None, "anchor_px": None}]
    image = rng.integers(0, 255, (7, 9, 3), dtype=np.uint8)
    s = _stream(pack("cam1", mask, (9, 7), 12, people, "img_0012"), pack_image("cam0", image),
                pack("cam0", None, (9, 7), 13, []), [END])
    camera, (background, size, camera2, frame, items), name = read_message(s, {"cam0", "cam1"})
    assert (camera, camera2, size, frame, name) == ("cam1", "cam1", (9, 7), 12, "img_0012")
    np.testing.assert_array_equal(background, mask)
    assert background.dtype == np.uint8
    for sent, got in zip(people, items):
        assert got["person"] == int(sent["person"]) and got["status"] == str(sent["status"])
        for key in ("outline", "recon", "joints_px", "anchor_px"):
            if sent[key] is None:
                assert got[key] is None
            else:
                np.testing.assert_array_equal(got[key], np.asarray(sent[key], np.float64))
    camera, got_image, name = read_message(s, {"cam0", "cam1"})
    assert camera == "cam0" and name is None
    np.testing.assert_array_equal(got_image, image)
    assert read_message(s, {"cam0"})[1][0] is None
    assert read_message(s, {"cam0"}) is None


def _raw(header: dict, payload: bytes = b"") -> io.BytesIO:
    body = json.dumps(header).encode()
    return io.BytesIO(struct.pack("<I", len(body)) + body + payload)


@pytest.mark.parametrize("header, error", [
    ({"camera": "x", "image": {"shape": [1, 1, 3], "dtype": "uint8"}}, "unknown camera 'x'"),
    ({"camera": "a", "image": {"shape": [1, 1, 3], "dtype": "object"}}, "not uint8, float64 or bits"),
    ({"camera": "a", "image": {"shape": [1, -1, 3], "dtype": "uint8"}}, "bad array shape"),
    ({"camera": "a", "frame": "1", "size": [1, 1], "people": []}, "needs 'frame'"),
    ({"camera": "a", "frame": 1, "size": [1, 1], "people": [{"person": "1", "status": "ok"}]}, "needs 'person'"),
    ({"camera": "a", "frame": 1, "size": [1, 1], "people": [], "name": "../x"}, "bad file name"),
    ({"camera": "a", "frame": 1, "size": [1, 1], "people": [], "name": ".hidden"}, "bad file name"),
    ({"camera": "a", "image": {"shape": [1, 1, 3], "dtype": "uint8"}, "name": 7}, "bad file name"),
])
def test_a_malformed_message_is_refused(header, error):
    with pytest.raises(ValueError, match=error):
        read_message(_raw(header, b"\0" * 64), {"a"})


def test_a_message_cut_short_is_refused():
    s = _raw({"camera": "a", "image": {"shape": [4, 4, 3], "dtype": "uint8"}}, b"\0" * 10)
    with pytest.raises(EOFError, match="38 bytes into a message"):
        read_message(s, {"a"})


def test_a_mask_travels_packed_and_a_grey_frame_as_it_is():
    """A {0, 1} background is sent 8 pixels to a byte (an eighth of its bytes, odd sizes included) and read back
    bit for bit; a background with other levels is sent whole, unchanged."""
    rng = np.random.default_rng(5)
    mask = (rng.random((486, 643)) < 0.2).astype(np.uint8)  # 312,498 pixels: not a multiple of 8
    grey = rng.integers(0, 255, (486, 643), dtype=np.uint8)
    for background, payload in ((mask, (mask.size + 7) // 8), (grey, grey.size)):
        message = pack("a", background, (643, 486), 0, [])
        assert sum(len(bytes(part)) for part in message[1:]) == payload
        got = read_message(_stream(message), {"a"})[1][0]
        assert got.dtype == np.uint8 and got.shape == background.shape
        np.testing.assert_array_equal(got, background)
