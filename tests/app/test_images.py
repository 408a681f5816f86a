"""silpose.app.inputs.images: load_frames / load_video round trips and their errors (each naming the file or folder)."""

import cv2
import numpy as np
import pytest

from silpose.app.errors import FramesInputError
from silpose.app.inputs.images import load_frames, load_video
from silpose.segment import BackgroundModel


def _images(n, h=24, w=32, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (n, h, w, 3), dtype=np.uint8)


def test_load_frames_round_trip_sorted_by_name(tmp_path):
    imgs = _images(4)
    names = ["frame_0003.png", "frame_0000.png", "frame_0002.PNG", "frame_0001.png"]
    for name, img in zip(names, imgs):
        assert cv2.imwrite(str(tmp_path / name), img)
    (tmp_path / "notes.txt").write_text("not an image")
    (tmp_path / "sub.png").mkdir()  # a folder with an image suffix is skipped
    frames, got = load_frames(tmp_path)
    assert got == sorted(names)
    order = [names.index(n) for n in got]
    np.testing.assert_array_equal(frames, imgs[order])  # PNG is lossless
    gray, _ = load_frames(tmp_path, gray=True)
    np.testing.assert_array_equal(gray, np.stack([cv2.cvtColor(f, cv2.COLOR_BGR2GRAY) for f in imgs[order]]))
    # The loaded stack feeds the model directly.
    assert BackgroundModel().fit(frames).mean_.shape == (24, 32)


def test_load_frames_errors_name_the_folder_or_file(tmp_path):
    with pytest.raises(FramesInputError, match=r"^folder: .*missing does not exist"):
        load_frames(tmp_path / "missing")
    (tmp_path / "a_file.png").write_bytes(b"")
    with pytest.raises(FramesInputError, match=r"^folder: .*a_file.png is not a directory"):
        load_frames(tmp_path / "a_file.png")
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FramesInputError, match=r"^folder: no png/jpg/jpeg/bmp/tif/tiff images in .*empty"):
        load_frames(empty)

    bad = tmp_path / "bad"
    bad.mkdir()
    cv2.imwrite(str(bad / "0.png"), _images(1)[0])
    (bad / "1.jpg").write_bytes(b"\xff\xd8 this is not a jpeg")
    with pytest.raises(FramesInputError, match=r"1\.jpg: cannot read this image"):
        load_frames(bad)

    sizes = tmp_path / "sizes"
    sizes.mkdir()
    cv2.imwrite(str(sizes / "0.png"), _images(1)[0])
    cv2.imwrite(str(sizes / "1.png"), _images(1, h=20)[0])
    with pytest.raises(FramesInputError, match=r"1\.png: frame size 32x20 \(WxH\) differs from 0\.png \(32x24"):
        load_frames(sizes)


def test_load_video_round_trip(tmp_path):
    path = tmp_path / "clip.avi"
    # Smooth frames so MJPG compression error stays small.
    base = cv2.GaussianBlur(_images(1, 48, 64)[0], (0, 0), 3)
    imgs = np.stack([np.roll(base, 2 * i, axis=1) for i in range(6)])
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    assert writer.isOpened()
    for img in imgs:
        writer.write(img)
    writer.release()
    frames = load_video(path)
    assert frames.shape == imgs.shape and frames.dtype == np.uint8
    assert np.abs(frames.astype(int) - imgs).mean() < 4
    assert load_video(path, max_frames=2).shape[0] == 2
    assert load_video(path, gray=True).shape == (6, 48, 64)


def test_load_video_errors_name_the_file(tmp_path):
    with pytest.raises(FramesInputError, match=r"^path: video file .*nope\.avi does not exist"):
        load_video(tmp_path / "nope.avi")
    junk = tmp_path / "junk.avi"
    junk.write_bytes(b"definitely not a video" * 10)
    with pytest.raises(FramesInputError, match=r"junk\.avi: (OpenCV cannot open this video|the video has no decodable frames)"):
        load_video(junk)
    (tmp_path / "ok.avi").write_bytes(b"")
    with pytest.raises(FramesInputError, match=r"^max_frames: must be >= 1"):
        load_video(tmp_path / "ok.avi", max_frames=0)
