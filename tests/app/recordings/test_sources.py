"""The videos folder: matching, probing, synchronising and streaming (silpose.app.recordings.sources)."""

import dataclasses

import threading

import numpy as np
import pytest

from silpose.app.errors import RecordingError
from silpose.app.camera_names import camera_in_stem
from silpose.app.recordings.sources import (CameraReader, holds_background_clips, open_recording,
                                            parse_offsets)


def _numbered(n, h=486, w=644, value=0):
    """n grey frames whose top-left 16x16 block encodes the frame index (x 8 grey levels)."""
    f = np.full((n, h, w), value, np.uint8)
    for i in range(n):
        f[i, :16, :16] = 8 * i
    return f


def _frame_index(img):
    return int(round(float(img[4:12, 4:12].mean()) / 8))


def test_parse_offsets():
    assert parse_offsets("cam1=3, cam2=-1", ["cam0", "cam1", "cam2"]) == {"cam1": 3, "cam2": -1}
    assert parse_offsets(None, ["cam0"]) == {}
    with pytest.raises(RecordingError, match="camera 'cam9' is not in the rig"):
        parse_offsets("cam9=1", ["cam0"])
    with pytest.raises(RecordingError, match="not <camera>=<integer frames>"):
        parse_offsets("cam0=x", ["cam0"])


def test_matches_videos_to_cameras_and_warns_for_a_missing_one(rig, tools, tmp_path):
    for cam in ("cam0", "cam1", "cam3"):
        tools.write_video(tmp_path / f"{cam}.mp4", _numbered(5))
    (tmp_path / "notes").mkdir()  # other folders are ignored
    rec = open_recording(tmp_path, rig)
    assert list(rec.sources) == ["cam0", "cam1", "cam3"] and rec.missing == ("cam2",)
    assert rec.n_steps == 5 and rec.fps == pytest.approx(25.0)
    assert any("cam2" in w and "missing view" in w for w in rec.warnings)


def test_offsets_shift_frames_and_unequal_lengths_run_to_the_longest(rig, tools, tmp_path):
    tools.write_video(tmp_path / "cam0.mp4", _numbered(12))
    tools.write_video(tmp_path / "cam1.mp4", _numbered(10))
    rec = open_recording(tmp_path, rig, {"cam1": -2})  # cam1's frame i - 2 is cam0's frame i
    assert rec.sources["cam0"].skip == 2 and rec.sources["cam1"].skip == 0
    assert rec.n_steps == 10  # cam0: 12 - 2, cam1: 10
    r0, r1 = CameraReader(rec.sources["cam0"], grey=True), CameraReader(rec.sources["cam1"], grey=True)
    first = [(_frame_index(r0.read()), _frame_index(r1.read())) for _ in range(3)]
    assert first == [(2, 0), (3, 1), (4, 2)]
    r0.close(), r1.close()
    tools.write_video(tmp_path / "cam2.mp4", _numbered(7))
    rec = open_recording(tmp_path, rig)
    assert rec.n_steps == 12 and any("unequal length" in w and "cam2.mp4 7" in w and "video ended" in w
                                     for w in rec.warnings)


def test_mapping_file_names_the_videos(rig, tools, tmp_path):
    tools.write_video(tmp_path / "left.mp4", _numbered(4))
    (tmp_path / "cameras.toml").write_text('[cameras]\ncam2 = "left.mp4"\n')
    rec = open_recording(tmp_path, rig)
    assert list(rec.sources) == ["cam2"] and rec.sources["cam2"].path.name == "left.mp4"
    (tmp_path / "cameras.toml").write_text('[cameras]\ncamX = "left.mp4"\n')
    with pytest.raises(RecordingError, match=r"cameras.toml: field 'cameras.camX': not a rig camera"):
        open_recording(tmp_path, rig)


def test_camera_in_stem_reads_dataset_video_names():
    assert camera_in_stem("hd_00_00", ["00_00", "00_01"]) == ["00_00"]  # CMU Panoptic
    assert camera_in_stem("gBR_sBM_c01_d04_mBR0_ch01", ["c01", "c02"]) == ["c01"]  # AIST++
    assert camera_in_stem("Cam1-take2", ["cam1", "cam2"]) == ["cam1"]  # words, any case
    assert camera_in_stem("cam10", ["cam1", "cam10"]) == ["cam10"]
    assert camera_in_stem("cam10_take", ["cam1"]) == []  # cam10 is not cam1
    assert camera_in_stem("hd_00_00", ["00_00", "00"]) == ["00_00"]  # 00 only inside the longer match
    assert camera_in_stem("cam1_vs_cam2", ["cam1", "cam2"]) == ["cam1", "cam2"]
    # one camera spelt two ways (Pose2Sim's calibration cam_01, its videos cam01): numbers compared as numbers
    cams = ["cam_01", "cam_02", "cam_10"]
    for stem, want in (("cam01", ["cam_01"]), ("Cam1", ["cam_01"]), ("cam-1_take3", ["cam_01"]),
                       ("cam10", ["cam_10"]), ("camera01", []), ("cam03", [])):
        assert camera_in_stem(stem, cams) == want, stem
    assert camera_in_stem("cam_02", ["cam01", "cam02"]) == ["cam02"]
    assert camera_in_stem("take_02", ["1", "2"]) == []  # number-only names keep the exact rule (02 is not 2)
    assert camera_in_stem("take_02", ["00_01", "00_02"]) == []


def test_videos_named_with_the_camera_inside_are_matched_with_a_warning(rig, tools, tmp_path):
    tools.write_video(tmp_path / "hd_cam0.mp4", _numbered(3))
    tools.write_video(tmp_path / "cam2.mp4", _numbered(3))
    rec = open_recording(tmp_path, rig)
    assert rec.sources["cam0"].path.name == "hd_cam0.mp4" and rec.sources["cam2"].path.name == "cam2.mp4"
    assert any("hd_cam0.mp4: read as camera 'cam0'" in w for w in rec.warnings)
    # a lab's folder: cam0.mp4 beside another video whose name holds cam0's: the exact name is the camera's video
    tools.write_video(tmp_path / "cam0.mp4", _numbered(3))
    rec = open_recording(tmp_path, rig)
    assert rec.sources["cam0"].path.name == "cam0.mp4"
    assert any("hd_cam0.mp4: not read (camera 'cam0' is cam0.mp4)" in w for w in rec.warnings)
    (tmp_path / "cam0.mp4").unlink()
    tools.write_video(tmp_path / "cam0_take2.mp4", _numbered(3))  # two videos holding cam0's name, none exactly
    with pytest.raises(RecordingError, match=r"camera 'cam0' has both cam0_take2.mp4 and hd_cam0.mp4; name the one to read cam0.mp4"):
        open_recording(tmp_path, rig)
    (tmp_path / "cam0_take2.mp4").unlink()
    tools.write_video(tmp_path / "cam1_and_cam3.mp4", _numbered(3))
    with pytest.raises(RecordingError, match=r"'cam1_and_cam3' names several rig cameras \(cam1, cam3\)"):
        open_recording(tmp_path, rig)


def test_image_folders_are_cameras_too(rig, tmp_path):
    import cv2

    (tmp_path / "cam1").mkdir()
    for i, f in enumerate(_numbered(3)):
        cv2.imwrite(str(tmp_path / "cam1" / f"{i:04d}.png"), f)
    rec = open_recording(tmp_path, rig)
    r = CameraReader(rec.sources["cam1"], grey=False)  # a grey reader reads masks (test_mask_images), not grey codes
    assert [_frame_index(r.read()) for _ in range(3)] == [0, 1, 2] and r.read() is None


@pytest.mark.parametrize("case, pattern", [
    ("unknown", r"stranger.mp4: 'stranger' is not a rig camera"),
    ("garbage", r"cam0.mp4: OpenCV \(FFmpeg\) cannot open this video|cam0.mp4: the video has no decodable frame"),
    ("empty", r"cam0.mp4: OpenCV \(FFmpeg\) cannot open this video|cam0.mp4: the video has no decodable frame"),
    ("size", r"cam0.mp4: frames are 320x240 \(WxH\), camera 'cam0' of the rig is 644x486 \(another aspect ratio\)"),
    ("fps", r"frame rates differ by more than 5 % \(cam0.mp4 25 fps, cam1.mp4 30 fps\)"),
    ("none", r"no video named as a rig camera"),
])
def test_bad_folders_are_one_line_errors(rig, tools, tmp_path, case, pattern):
    if case == "unknown":
        tools.write_video(tmp_path / "stranger.mp4", _numbered(2))
    elif case == "garbage":
        (tmp_path / "cam0.mp4").write_bytes(b"this is not a video" * 100)
    elif case == "empty":
        (tmp_path / "cam0.mp4").write_bytes(b"")
    elif case == "size":
        tools.write_video(tmp_path / "cam0.mp4", _numbered(2, 240, 320))
    elif case == "fps":
        tools.write_video(tmp_path / "cam0.mp4", _numbered(2), fps=25)
        tools.write_video(tmp_path / "cam1.mp4", _numbered(2), fps=30)
    with pytest.raises(RecordingError, match=pattern) as err:
        open_recording(tmp_path, rig)
    assert "\n" not in str(err.value)


def test_a_video_at_half_the_calibrations_size_is_scaled_up(rig, tools, tmp_path):
    """Labs calibrate at full resolution and keep smaller videos: 322x242 is the 644x486 picture at half size
    (video codecs need even sides: 243 rounds to 242). Frames come out at the rig's size, the mask where it
    was; a warning says so. 320x240 (another aspect ratio) stays an error (test_bad_folders_...)."""
    import cv2

    full = np.zeros((3, 486, 644), np.uint8)
    full[:, 100:300, 200:260] = 255
    half = np.stack([cv2.resize(f, (322, 242), interpolation=cv2.INTER_AREA) for f in full])
    tools.write_video(tmp_path / "cam2.mp4", half)
    rec = open_recording(tmp_path, rig)
    assert rec.sources["cam2"].resize_to == (644, 486)
    assert any("cam2.mp4: frames are 322x242" in w and "scaled by 2" in w for w in rec.warnings)
    frame = CameraReader(rec.sources["cam2"], grey=True).read()
    assert frame.shape == (486, 644)
    iou = ((frame > 127) & (full[0] > 0)).sum() / ((frame > 127) | (full[0] > 0)).sum()
    assert iou > 0.97


def test_camera_folders_holding_videos(rig, tools, tmp_path):
    """The course/lab layout cam1/{background,video,checkerboard}.avi: --videos reads each camera's video,
    --background its background clip; an ambiguous folder is a one-line error naming its videos."""
    for cam in rig.names:
        (tmp_path / cam).mkdir()
        tools.write_video(tmp_path / cam / "video.avi", _numbered(5))
        tools.write_video(tmp_path / cam / "background.avi", _numbered(3))
        tools.write_video(tmp_path / cam / "checkerboard.avi", _numbered(2))
        (tmp_path / cam / "config.xml").write_text("<opencv_storage/>")
    rec = open_recording(tmp_path, rig)
    assert {c: s.path.name for c, s in rec.sources.items()} == dict.fromkeys(rig.names, "video.avi")
    assert rec.n_steps == 5
    assert holds_background_clips(tmp_path, rig.names) and not holds_background_clips(tmp_path / "cam0", rig.names)
    bg = open_recording(tmp_path, rig, role="background")
    assert {s.path.name for s in bg.sources.values()} == {"background.avi"} and bg.n_steps == 3
    for cam in rig.names[1:]:  # only the recordings left: never used as empty-room clips
        (tmp_path / cam / "background.avi").unlink()
    with pytest.raises(RecordingError, match=r"cam1: holds 2 videos \(checkerboard.avi, video.avi\) and none is named "
                                             r"'background'"):
        open_recording(tmp_path, rig, role="background")
    (tmp_path / "cam1" / "checkerboard.avi").unlink()
    with pytest.raises(RecordingError, match=r"cam1: holds 1 video \(video.avi\) and none is named 'background'"):
        open_recording(tmp_path, rig, role="background")
    (tmp_path / "cam0" / "video.avi").rename(tmp_path / "cam0" / "take2.avi")
    with pytest.raises(RecordingError, match=r"cam0: holds 3 videos \(background.avi, checkerboard.avi, take2.avi\) "
                                             r"and none is named 'video'"):
        open_recording(tmp_path, rig)


def test_threaded_reader_gives_the_frames_in_order_then_none(rig, tools, tmp_path):
    from silpose.app.recordings.sources import ThreadedReader

    tools.write_video(tmp_path / "cam0.mp4", _numbered(9))
    rec = open_recording(tmp_path, rig)
    r = ThreadedReader(CameraReader(rec.sources["cam0"], grey=True), depth=2)
    got = [_frame_index(r.read()) for _ in range(9)]
    assert got == list(range(9)) and r.read() is None and r.read() is None and r.summary() is None
    r.close()


def test_threaded_reader_hands_each_frame_with_what_its_thread_computed_of_it(rig, tools, tmp_path):
    """``after`` runs in the reader's thread on each decoded frame; ``read_with`` hands its result over with that
    frame (None for frames decoded before it was set, and at the end)."""
    from silpose.app.recordings.sources import ThreadedReader

    tools.write_video(tmp_path / "cam0.mp4", _numbered(9))
    rec = open_recording(tmp_path, rig)
    threads = set()

    def after(img):
        threads.add(threading.current_thread().name)
        return _frame_index(img) * 10

    r = ThreadedReader(CameraReader(rec.sources["cam0"], grey=True), depth=2, after=after)
    got = [r.read_with() for _ in range(9)]
    assert [(_frame_index(f), x) for f, x in got] == [(i, 10 * i) for i in range(9)]
    assert r.read_with() == (None, None) and threads == {"read-cam0"}
    r.close()
    late = ThreadedReader(CameraReader(rec.sources["cam0"], grey=True), depth=2)
    late.after = after  # set while the thread runs: the frames it decoded before have None
    got = [late.read_with() for _ in range(9)]
    late.close()
    assert [_frame_index(f) for f, _ in got] == list(range(9))
    assert all(x is None or x == 10 * _frame_index(f) for f, x in got) and got[-1][1] == 80


def test_a_video_a_codec_block_narrower_is_the_calibrations_picture(rig, tools, tmp_path):
    """Pose2Sim's demo: one 1088 px calibration, videos 1080 and 1088 px wide (encoders round sides to 16 px).
    A video 8 columns narrower and 4 rows taller than the camera is read pixel for pixel: the right edge padded
    with its last column, the bottom cut; the blob stays where it was. 20 px off stays an error."""
    full = np.zeros((3, 486, 644), np.uint8)
    full[:, 100:300, 200:260] = 255
    narrow = np.zeros((3, 490, 636), np.uint8)
    narrow[:, :486, :] = full[:, :, :636]
    narrow[:, :, -1] = 90  # the last column, repeated into the padding
    tools.write_video(tmp_path / "cam1.mp4", narrow)
    rec = open_recording(tmp_path, rig)
    src = rec.sources["cam1"]
    assert (src.width, src.height, src.pad, src.resize_to) == (644, 486, (8, -4), None)
    assert any("cam1.mp4: frames are 636x490" in w and "8 column(s), -4 row(s)" in w for w in rec.warnings)
    frame = CameraReader(src, grey=True).read()
    assert frame.shape == (486, 644)
    np.testing.assert_allclose(frame[:, 636:].mean(axis=1), frame[:, 635], atol=1)  # padding repeats the edge
    iou = ((frame > 127) & (full[0] > 0)).sum() / ((frame > 127) | (full[0] > 0)).sum()
    assert iou > 0.97
    tools.write_video(tmp_path / "cam1.mp4", np.zeros((2, 486, 624), np.uint8))
    with pytest.raises(RecordingError, match=r"cam1.mp4: frames are 624x486 \(WxH\).*another aspect ratio"):
        open_recording(tmp_path, rig)


def test_spread_frames_decodes_forward_or_seeks_to_the_same_frames(rig, tools, tmp_path, monkeypatch):
    """Frames near each other are reached by decoding forward (CameraReader.skip), far ones by seeking; either
    way the picks are the evenly spread frames."""
    from silpose.app.recordings import silhouettes

    tools.write_video(tmp_path / "cam0.mp4", _numbered(30))
    src = open_recording(tmp_path, rig).sources["cam0"]
    picks = [0, 4, 7, 11, 14, 18, 22, 25, 29]  # np.linspace(0, 29, 9) rounded
    near = [_frame_index(f) for f in silhouettes.spread_frames(src, 9)]
    monkeypatch.setattr(silhouettes, "SEEK_GAP", -1)  # every pick sought
    far = [_frame_index(f) for f in silhouettes.spread_frames(src, 9)]
    assert near == far == picks
    r = CameraReader(src, grey=True)
    r.skip(5)
    assert _frame_index(r.read()) == 5 and r.index == 6
    r.close()


def test_frames_read_ahead_are_given_again_without_decoding_them_twice(rig, tools, tmp_path, monkeypatch):
    """CameraReader.read_ahead keeps what it read: the reads after it give the same frames, in order, then the
    video goes on; the decoder is asked for each frame once."""
    tools.write_video(tmp_path / "cam0.mp4", _numbered(12))
    src = open_recording(tmp_path, rig).sources["cam0"]
    r = CameraReader(src, grey=False)
    decoded = []
    plain = r._next
    monkeypatch.setattr(r, "_next", lambda: decoded.append(1) or plain())
    ahead = r.read_ahead(5)
    assert [_frame_index(f) for f in ahead] == [0, 1, 2, 3, 4] and len(decoded) == 5
    assert [_frame_index(f) for f in r.read_ahead(3)] == [0, 1, 2] and len(decoded) == 5  # nothing new decoded
    r.skip(1)
    got = [r.read() for _ in range(8)]
    assert [_frame_index(f) for f in got] == [1, 2, 3, 4, 5, 6, 7, 8] and len(decoded) == 9
    r.close()
    short = CameraReader(src, grey=False)
    assert len(short.read_ahead(50)) == 12  # a shorter video gives what it has
    assert sum(short.read() is not None for _ in range(13)) == 12
    short.close()


def test_room_view_is_the_median_of_the_first_frames_from_a_source_or_from_the_runs_reader(rig, tools, tmp_path):
    """The room view (silhouettes.room_view) is the per-pixel median of frames spread over the recording's first
    room_span frames -- the same whether read by a reader of its own or through the run's reader, which then gives
    those frames again from the first."""
    from silpose.app.recordings import silhouettes

    tools.write_video(tmp_path / "cam0.mp4", _numbered(30))
    src = open_recording(tmp_path, rig).sources["cam0"]
    span = silhouettes.room_span
    assert span(dataclasses.replace(src, fps=60.0, resize_to=(160, 120))) == 120  # 2 s
    assert span(dataclasses.replace(src, fps=1.0)) == 9  # at least ROOM_FRAMES
    assert span(dataclasses.replace(src, fps=60.0, resize_to=(1920, 1080))) == 64 * 2**20 // (3 * 1920 * 1080)
    frames = CameraReader(src, grey=False).read_ahead(span(src))
    assert len(frames) == min(30, span(src))
    picks = np.linspace(0, len(frames) - 1, silhouettes.ROOM_FRAMES).round().astype(int)
    expected = np.median(np.stack([frames[i] for i in picks]), axis=0).astype(np.uint8)
    own = silhouettes.room_view(src)
    reader = CameraReader(src, grey=False)
    through = silhouettes.room_view(reader)
    np.testing.assert_array_equal(own, expected)
    np.testing.assert_array_equal(through, expected)
    assert [_frame_index(reader.read()) for _ in range(3)] == [0, 1, 2]
    reader.close()


@pytest.mark.parametrize("n", [3, 4, 9, 10, 17])
def test_median_frames_is_numpys_median(n):
    from silpose.app.recordings.silhouettes import median_frames

    frames = list(np.random.default_rng(n).integers(0, 256, (n, 7, 5, 3), dtype=np.uint8))
    assert np.array_equal(median_frames(frames), np.median(np.stack(frames), axis=0).astype(np.uint8))


def test_a_grey_reader_takes_the_luma_plane_of_yuv_videos(rig, tools, tmp_path):
    """Mask videos (planar YUV) are read from the decoder's luma plane, mapped to the grey levels of OpenCV's
    BGR -> grey conversion of the same frames (within 1); a video of another pixel format (FFV1, BGRA) is read
    as BGR and converted."""
    import cv2

    from silpose.app.recordings.sources import DECODER_PARAMS

    y, x = np.mgrid[:486, :644]
    frames = np.stack([((x + 3 * i) % 256).astype(np.uint8) for i in range(3)])
    frames[:, 100:300, 200:400] = 255  # a mask-like block
    tools.write_video(tmp_path / "cam0.mp4", frames)
    w = cv2.VideoWriter(str(tmp_path / "cam1.avi"), cv2.VideoWriter_fourcc(*"FFV1"), 25, (644, 486))
    for f in frames:
        w.write(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR))
    w.release()
    rec = open_recording(tmp_path, rig)
    for cam, luma in (("cam0", True), ("cam1", False)):
        r = CameraReader(rec.sources[cam], grey=True)
        cap = cv2.VideoCapture(str(rec.sources[cam].path), cv2.CAP_FFMPEG, DECODER_PARAMS)
        assert r.luma is luma
        for _ in range(3):
            got, (ok, bgr) = r.read(), cap.read()
            want = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
            assert ok and got.shape == want.shape and np.abs(got.astype(int) - want).max() <= 1
        assert r.read() is None
        r.close()
        cap.release()


def test_luma_to_grey_is_the_table_at_every_level():
    """The saturating arithmetic that maps a mask video's luma plane to grey levels gives :data:`LUMA_TO_GREY`'s
    value at each of the 256 levels, in frames of any size (OpenCV's vectorised loops and their tails)."""
    from silpose.app.recordings.sources import LUMA_TO_GREY, luma_to_grey

    want = np.clip(np.round((np.arange(256) - 16) * 255 / 219), 0, 255)  # BT.601 limited range -> 0..255
    np.testing.assert_array_equal(LUMA_TO_GREY, want)
    rng = np.random.default_rng(0)
    for shape in [(16, 16), (486, 644), (3, 5), (1, 257)]:
        img = np.arange(np.prod(shape)).reshape(shape).astype(np.uint8) if shape == (16, 16) else \
            rng.integers(0, 256, shape, dtype=np.uint8)
        got = luma_to_grey(img)
        assert got.dtype == np.uint8 and got.shape == shape
        np.testing.assert_array_equal(got, LUMA_TO_GREY[img])


def test_frames_named_without_zero_padding_are_read_in_numeric_order(rig, tmp_path):
    """Exporters that do not zero-pad name frames img1, img2, ..., img10: read in that order, not as strings sort
    (img1, img10, img11, img2, ...); the frame order of ``silpose infer INPUT``'s camera folders is the same."""
    import cv2

    from silpose.app.inputs.images import frame_order

    (tmp_path / "cam1").mkdir()
    frames = _numbered(12)
    for i, f in enumerate(frames):
        cv2.imwrite(str(tmp_path / "cam1" / f"img{i + 1}.png"), f)
    rec = open_recording(tmp_path, rig)
    r = CameraReader(rec.sources["cam1"], grey=False)
    assert [_frame_index(r.read()) for _ in range(12)] == list(range(12))
    names = ["f10.png", "f9.png", "f0010b.png", "F2.png", "f1.png", "f00011.png"]
    assert sorted(names, key=frame_order) == ["f1.png", "F2.png", "f9.png", "f10.png", "f0010b.png", "f00011.png"]
    padded = [f"{i:05d}.png" for i in range(30)]
    assert sorted(padded[::-1], key=frame_order) == padded  # zero-padded names keep their order


def test_a_video_whose_codec_cannot_be_decoded_says_so(rig, tools, tmp_path, monkeypatch):
    """A file that opens, whose header names a codec and frames, but none of whose frames decodes (AV1 videos in
    the opencv-python wheels: OpenCV's FFmpeg has no AV1 decoder) is named with its codec and a re-encoding
    command, not called empty; alone, that camera is a missing view; an empty header stays "empty or corrupt"."""
    import cv2

    from silpose.app.recordings import sources

    real = cv2.VideoCapture

    class Undecodable:  # OpenCV's capture of an AV1 file: opened, its header read, every frame refused
        def __init__(self, path, *args):
            self.real = real(path, *args)

        def __getattr__(self, name):
            return getattr(self.real, name)

        def read(self):
            return False, None

        def get(self, prop):
            return float(int.from_bytes(b"AV01", "little")) if prop == cv2.CAP_PROP_FOURCC else self.real.get(prop)

    for cam in ("cam0", "cam1"):
        tools.write_video(tmp_path / f"{cam}.mp4", _numbered(4))
    monkeypatch.setattr(sources.cv2, "VideoCapture", Undecodable)
    with pytest.raises(RecordingError, match=r"cam0.mp4: none of its 4 frames decodes: OpenCV's FFmpeg has no decoder "
                                             r"for its 'AV01' video, or the file is corrupt; re-encode it, e\.g\. "
                                             r"ffmpeg -i cam0.mp4 -c:v libx264"):
        open_recording(tmp_path, rig)
    monkeypatch.setattr(sources.cv2, "VideoCapture", lambda path, *a: Undecodable(path, *a) if "cam1" in str(path)
                        else real(path, *a))
    rec = open_recording(tmp_path, rig)
    assert "cam1" in rec.missing and "cam0" in rec.sources
    assert any("cam1.mp4: none of its 4 frames decodes" in w and "a missing view in every frame" in w
               for w in rec.warnings)


def _on_a_grid(times: np.ndarray, fps: float, n_steps: int) -> list[int]:
    """Brute force of the time grid (silpose.app.recordings.sources, "Time stamps"): step k's frame is the first frame
    whose time rounds to step k, else the frame of step k - 1."""
    steps = np.round((times - times[0]) * fps).astype(int)
    out = []
    for k in range(n_steps):
        own = np.flatnonzero(steps == k)
        out.append(int(own[0]) if len(own) else out[-1])
    return out


@pytest.mark.parametrize("times_ms", [
    [0, 40, 80, 200, 240, 260, 280, 320, 360, 400, 520, 560],  # gaps of 3 and 2 steps, a frame between two steps
    [0, 41, 79, 121, 162, 198, 240, 279, 320, 361],            # a constant rate with jittered time stamps
])
def test_a_variable_frame_rate_video_is_read_on_the_time_grid(rig, tools, tmp_path, monkeypatch, times_ms):
    """A phone's video whose frames are unevenly spaced in time: each step of the recording's 25 fps grid gets
    the frame its time stamp puts there (the brute force above): the previous frame again across a gap, the
    second of two frames for one step dropped; the summary counts both. The frames' indices are drawn into them
    (a constant-rate file; OpenCV's time stamps replaced by the uneven ones, which are what it reads from a
    variable-rate file)."""
    import cv2

    from silpose.app.recordings import sources

    times = np.asarray(times_ms, float)
    tools.write_video(tmp_path / "cam0.mp4", _numbered(len(times)), fps=25)
    real = cv2.VideoCapture

    class Stamped:
        def __init__(self, path, *args):
            self.real, self.grabbed = real(path, *args), -1

        def __getattr__(self, name):
            return getattr(self.real, name)

        def grab(self):
            ok = self.real.grab()
            self.grabbed += ok
            return ok

        def read(self):
            return self.retrieve() if self.grab() else (False, None)

        def get(self, prop):
            return float(times[self.grabbed]) if prop == cv2.CAP_PROP_POS_MSEC else self.real.get(prop)

    monkeypatch.setattr(sources.cv2, "VideoCapture", Stamped)
    rec = open_recording(tmp_path, rig)
    src = rec.sources["cam0"]
    assert src.grid_fps == 25
    want = _on_a_grid(times / 1000, 25, int(round(times[-1] / 40)) + 1)
    reader = CameraReader(src, grey=True)
    got = []
    while (img := reader.read()) is not None:
        got.append(_frame_index(img))
    assert got == want
    repeats = sum(a == b for a, b in zip(want[1:], want[:-1]))
    dropped = len(times) - len(set(want))
    assert (reader.repeated, reader.dropped) == (repeats, dropped)
    line = reader.summary()
    assert (line is None) == (repeats == dropped == 0)
    if line:
        assert f"{repeats} step(s) gave the previous frame again and {dropped} frame(s) were dropped" in line
    start = CameraReader(dataclasses.replace(src, skip=5), grey=True)  # an offset skips grid steps, not frames
    assert _frame_index(start.read()) == want[5]


def test_videos_whose_rates_differ_a_little_are_kept_in_time(rig, tools, tmp_path):
    """Rates 3 % apart (a phone's 29.1 fps average beside a 30 fps camera) are read on one grid at their median:
    each video gives the frames its time stamps place there, and its steps are counted on that grid."""
    tools.write_video(tmp_path / "cam0.mp4", _numbered(30), fps=30)
    tools.write_video(tmp_path / "cam1.mp4", _numbered(30), fps=29.1)
    tools.write_video(tmp_path / "cam2.mp4", _numbered(30), fps=30)
    rec = open_recording(tmp_path, rig)
    assert rec.fps == 30 and {s.grid_fps for s in rec.sources.values()} == {30}
    assert rec.n_steps == 31  # cam1's 30 frames last 30 / 29.1 s: 30.9 steps of the 30 fps grid
    reader = CameraReader(rec.sources["cam1"], grey=True)
    got = []
    while (img := reader.read()) is not None:
        got.append(_frame_index(img))
    assert got == _on_a_grid(np.arange(30) / 29.1, 30, len(got)) and reader.repeated == 1 and reader.dropped == 0
    plain = CameraReader(rec.sources["cam0"], grey=True)
    assert [_frame_index(plain.read()) for _ in range(30)] == list(range(30)) and plain.read() is None
    assert plain.summary() is None


def test_offsets_in_seconds_are_steps_of_the_time_grid(rig, tools, tmp_path):
    """``cam1=0.12s`` is cam1 0.12 s ahead: at 25 fps, 3 steps, as ``cam1=3``; a negative one, the frames of the
    others that many steps later; in seconds without any frame rate (image folders), a one-line error."""
    for cam in ("cam0", "cam1"):
        tools.write_video(tmp_path / f"{cam}.mp4", _numbered(8), fps=25)
    assert parse_offsets("cam1=0.12s, cam0=2", ["cam0", "cam1"]) == {"cam1": 0.12, "cam0": 2}
    for text, want in (("cam1=0.12s", {"cam1": 3}), ("cam1=3", {"cam1": 3}), ("cam1=-0.08s", {"cam1": -2})):
        rec = open_recording(tmp_path, rig, parse_offsets(text, ["cam0", "cam1"]))
        assert rec.offsets == want
        readers = {c: CameraReader(s, grey=True) for c, s in rec.sources.items()}
        first = {c: _frame_index(r.read()) for c, r in readers.items()}
        lead = want["cam1"]
        assert first == ({"cam0": 0, "cam1": lead} if lead > 0 else {"cam0": -lead, "cam1": 0})
    with pytest.raises(RecordingError, match="is not <camera>=<integer frames> or <camera>=<seconds>s"):
        parse_offsets("cam1=0.1ms", ["cam1"])
    folders = tmp_path / "folders"
    (folders / "cam0").mkdir(parents=True)
    import cv2

    cv2.imwrite(str(folders / "cam0" / "0000.png"), _numbered(1)[0])
    with pytest.raises(RecordingError, match="offsets in seconds need a frame rate"):
        open_recording(folders, rig, parse_offsets("cam0=0.5s", ["cam0"]))
