"""A recording's input: one video (or image folder) per camera, matched to the rig, synchronised, streamed.

Layout of ``silpose infer MODEL --videos DIR``::

    DIR/<camera>.mp4 | .avi | .mkv | .mov | ...    one video per camera, named as in the rig (or holding the name), or
    DIR/<camera>/00000.png ...                     a folder of frames (PNG/JPG, name order: frame_order), or
    DIR/<camera>/video.avi                         a camera folder holding videos: its only video, or the one
                                                   named ``video`` (``background`` for ``--background DIR``)
    DIR/cameras.toml                               optional: [cameras] <camera> = "<file or folder>"

The camera-folder layout is what many labs and courses keep (``cam1/background.avi``, ``cam1/video.avi``,
``cam1/checkerboard.avi``, ``cam1/config.xml``): ``--videos data --background data`` then reads each camera's
``video`` and ``background`` clip.

With ``cameras.toml`` only the mapped entries are read (paths relative to DIR); without it every video's
file stem must name a rig camera (sub-folders not named after a camera are ignored): be the name, or hold it
as whole words (:func:`silpose.app.camera_names.camera_in_stem`: CMU Panoptic's ``hd_00_00.mp4`` is camera ``00_00``, AIST++'s
``gBR_sBM_c01_d04_mBR0_ch01.mp4`` camera ``c01``; a warning says which video was read as which camera, and a
stem naming two cameras is an error; a video named exactly as a camera is that camera's, and another whose name
holds the camera's -- ``cam1_checkerboard.mp4`` beside ``cam1.mp4`` -- is not read, with a warning). A rig camera with
no video is a missing view in every frame (a warning); no video at all is an error.

Orientation: a phone stores a portrait video as landscape frames plus a rotation in its metadata (the display
matrix), and players and FFmpeg show it upright. OpenCV reads the stored frames unless asked
(``CAP_PROP_ORIENTATION_AUTO``), so a video with a rotation of 90, 180 or 270 degrees is read upright, as every
player shows it -- unless only its stored frames fit the rig camera's size (a calibration made on frames read
without the rotation), then as stored; either way a warning names the choice (:func:`orient`).

Checks before any frame is processed, each a one-line :class:`~silpose.app.errors.RecordingError` naming
the file: the video opens and decodes a first frame; its frame size is the rig camera's -- or the same
picture at another scale (a lab calibrates at full resolution and records or stores smaller videos: both
sides scaled by one factor, to the pixel: the rig's aspect ratio gives the video's height from its width within
one pixel), then every frame is resized to the camera's size
(bilinear; a mask is thresholded after) with a warning -- or the same picture with fewer than
:data:`CODEC_BLOCK` (16) columns or rows more or less at its right and bottom edges (encoders round frame
sides to blocks of 16 px and players crop them back, so one lab's videos come out 1080 or 1088 px wide for
one 1088 px calibration, as in Pose2Sim's demo): every frame is cut, or padded by repeating its last column
or row, to the camera's size, pixel for pixel, with a warning; all videos have
one frame rate (:data:`FPS_TOLERANCE`, 5 %; farther apart, giving twice or dropping one frame in twenty is
no repair, and the videos are refused). Per-camera offsets (``--offsets cam1=3``: cam1's frame ``i + 3`` was
shot with the other cameras' frame ``i``; ``cam1=0.12s``: in seconds, as an audio clap gives them, rounded to the
time grid's steps) shift each video; the recording then runs from the first step every
camera has a frame to the end of the longest video (videos of unequal length: a warning). A camera whose
video ends early -- shorter than the others, or a truncated or corrupt file that stops decoding before its
header's count -- is a missing view with status "video ended" from there on while the other cameras go on;
the run stops when no camera is left. A camera whose video cannot be opened at all is a missing view in
every frame (a warning), unless no camera can be read (then the first camera's error).

Time stamps: a video's frames are placed on the recording's time grid by their presentation time stamps
(``CAP_PROP_POS_MSEC``), not by their index: step ``k`` is ``k / fps`` seconds after the video's first frame,
``fps`` the highest of the cameras' rates (OpenCV gives a variable-rate video's average rate, below its nominal one;
and a camera slower than the grid gives a frame twice rather than a faster one dropping frames). Phones record at a
variable frame rate (fewer frames in dim light, a frame dropped now and then): read by index, such a video drifts
from the others by a frame at every gap and stays there. On the grid, a frame whose time rounds to a step already
given is dropped, and a step with no frame of its own gives the previous frame again; :meth:`CameraReader.summary`
counts both. A constant-rate video's time stamps round to its indices, so it is read as before, frame for frame. A
video whose time stamps do not increase (none stored) is read by index.

FFmpeg's own decoder lines (``[mjpeg @ 0x...] overread 8``) never reach the terminal: :func:`quiet_decoders`
sets ``OPENCV_FFMPEG_LOGLEVEL`` to quiet unless the user set it, and OpenCV's own log to errors, when this
module is imported (OpenCV reads the variable once, when the process first touches a video); each camera
whose decoding stopped early gets one warning line instead (:meth:`CameraReader.summary`).

Decoding: OpenCV's FFmpeg backend (``cv2.VideoCapture``), one frame at a time, so memory does not grow
with the recording's length. Why not PyAV: OpenCV already ships FFmpeg in the wheel the workspace uses
(no new dependency), decodes a 644x486 frame in ~1.3 ms here (MPEG-4 part 2; about PyAV's speed, both
call libavcodec). A grey reader (mask videos) asks OpenCV for the decoder's own picture (``CAP_PROP_CONVERT_RGB``
off) when its pixel format is planar YUV (:data:`LUMA_FORMATS`) and keeps the luma plane, mapped to the grey levels
of a BGR -> grey conversion (:data:`LUMA_TO_GREY`): FFmpeg's YUV -> BGR conversion and the grey conversion after it
were half of a mask frame's decoding (0.48 -> 0.24 CPU ms per 644x486 frame).
Frames larger than the working size are shrunk by :func:`~.resolution.shrink` (a whole-factor block average
then bilinear: a sixth of the time of OpenCV's ``INTER_AREA`` at a fractional factor).
"""

from __future__ import annotations

import collections
import dataclasses
import os
import queue
import threading
import tomllib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ..camera_names import camera_in_stem
from ..errors import RecordingError
from ..inputs.images import IMAGE_SUFFIXES, VIDEO_SUFFIXES, display_rotation, frame_order
from ..inputs.mask_images import mask_grey
from .resolution import shrink

#: optional camera -> file mapping inside the videos folder
MAPPING_FILE = "cameras.toml"
#: relative frame-rate difference tolerated between cameras: frames are placed by their time stamps (module
#: docstring, "Time stamps"), so a phone's variable rate (29.2 fps on average for a nominal 30) is kept in time
FPS_TOLERANCE = 0.05
#: a video whose sides differ from its camera's calibrated picture by fewer pixels is that picture with its right
#: and bottom edges cut or padded (encoders round sides to blocks of 16 px; module docstring)
CODEC_BLOCK = 16
#: ``cv2.VideoCapture`` open parameters of a camera's reader: FFmpeg decodes in the calling thread. Every camera
#: already decodes in a thread of its own (:class:`ThreadedReader`, or the pipeline's per-camera pool), and FFmpeg's
#: own decoding threads only add their hand-over to the CPU time: measured on a 1932x1458 MPEG-4 video (30 frames,
#: loaded 2-core machine), 6.1 CPU ms per frame with one thread, 8.9 with FFmpeg's default (one per core); the
#: frames are the same
DECODER_PARAMS = [cv2.CAP_PROP_N_THREADS, 1]
#: pixel formats (FourCC of ``CAP_PROP_CODEC_PIXEL_FORMAT``) whose first plane is the luma plane: a grey reader
#: (mask videos) takes that plane from the decoder (``CAP_PROP_CONVERT_RGB`` off) instead of a BGR picture it then
#: converts to grey -- FFmpeg's YUV -> BGR conversion is most of a small frame's decoding: measured on the lab's
#: 644x486 MPEG-4 mask videos, 0.48 -> 0.24 CPU ms per frame; every other format is read as BGR
LUMA_FORMATS = frozenset({"I420", "IYUV", "YV12", "NV12", "NV21", "Y42B", "444P"})
#: video (limited-range) luma 16..235 -> the grey level 0..255 of OpenCV's BGR -> grey conversion of the same
#: frame (BT.601: grey = 1.164 (Y - 16), chroma cancels): within 1 grey level of it on the lab's mask videos, and the
#: same masks (60 frames)
LUMA_TO_GREY = np.clip(np.round((np.arange(256) - 16) * 255 / 219), 0, 255).astype(np.uint8)


def luma_to_grey(luma: np.ndarray) -> np.ndarray:
    """``LUMA_TO_GREY[luma]`` for (H, W) uint8 luma, computed as OpenCV's saturating ``255 / 219 (Y - 16)``: the same
    256 values (the exact ones are never within 0.002 of a rounding tie), in a quarter of ``cv2.LUT``'s time on the
    lab's 644x486 frames (0.08 against 0.35 ms)."""
    return cv2.addWeighted(luma, 255.0 / 219.0, luma, 0.0, -16.0 * 255.0 / 219.0)
#: FFmpeg log level OpenCV is given unless the user set ``OPENCV_FFMPEG_LOGLEVEL`` (-8: AV_LOG_QUIET)
FFMPEG_LOGLEVEL = "-8"


def quiet_decoders() -> None:
    """Keep FFmpeg's and OpenCV's decoder messages off the terminal (module docstring); set
    ``OPENCV_FFMPEG_LOGLEVEL=24`` (warnings) to see FFmpeg's lines."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", FFMPEG_LOGLEVEL)
    if os.environ.get("OPENCV_LOG_LEVEL") is None and hasattr(cv2, "setLogLevel"):
        cv2.setLogLevel(2)  # errors only: OpenCV's own "can't be used to capture by name" warnings


quiet_decoders()


@dataclass(frozen=True)
class CameraSource:
    """One camera's video or frame folder, probed.

    camera: rig camera name; path: the file or folder; fps: frames per second (0 when unknown: image
    folders, or a header without it); n_frames: frames the header (or folder) reports, -1 when unknown;
    width, height: size of the frames read, px (after ``pad``); skip: frames skipped at the start (offsets);
    resize_to: (width, height) of the rig camera when the frames are its picture at another scale (each frame is
    resized), else None; pad: (columns, rows) added at the right and bottom edges of every decoded frame
    (negative: removed) to give the rig camera's picture (:data:`CODEC_BLOCK`), applied before ``resize_to``;
    rotation: degrees of the video's display rotation (metadata; 0, 90, 180 or 270); upright: frames are read
    rotated as players show them (``width``, ``height`` are then those of the rotated frames); grid_fps: the
    recording's frame rate, on whose time grid the frames are placed by their time stamps (module docstring, "Time
    stamps"; 0: by index).
    """

    camera: str
    path: Path
    fps: float
    n_frames: int
    width: int
    height: int
    skip: int = 0
    images: tuple[Path, ...] | None = None
    resize_to: tuple[int, int] | None = None
    pad: tuple[int, int] = (0, 0)
    rotation: int = 0
    upright: bool = False
    grid_fps: float = 0.0

    @property
    def is_video(self) -> bool:
        return self.images is None

    @property
    def n_steps(self) -> int:
        """Steps of the recording's time grid the frames span (``n_frames`` at the grid's rate: the duration the
        header gives, ``n_frames / fps``, times ``grid_fps``; module docstring, "Time stamps"), -1 when unknown."""
        if self.n_frames < 0 or not (self.grid_fps > 0 and self.fps > 0):
            return self.n_frames
        return int(round(self.n_frames * self.grid_fps / self.fps))


@dataclass
class Recording:
    """The synchronised cameras of a recording.

    sources: {camera: CameraSource} in rig order, cameras with a readable video; missing: rig cameras
    without (no video, or one that cannot be opened); n_steps: time steps (frames of the longest video after
    offsets; -1 when a header does not say); fps: frames per second of the time grid, the fastest camera's (0
    when unknown); warnings: one line each; offsets: {camera: steps} as given (seconds turned into steps).
    """

    root: Path
    sources: dict[str, CameraSource]
    missing: tuple[str, ...]
    n_steps: int
    fps: float
    warnings: list[str] = field(default_factory=list)
    offsets: dict[str, int] = field(default_factory=dict)


class Seconds(float):
    """An offset given in seconds (``--offsets cam1=0.43s``): steps of the recording's time grid once its rate is
    known (:func:`open_recording`)."""


def parse_offsets(text: str | None, cameras) -> dict[str, int | Seconds]:
    """``"cam1=3,cam2=-1,cam3=0.43s"`` -> {camera: frames, or :class:`Seconds`}; unknown cameras and malformed items
    are one-line errors."""
    out: dict[str, int | Seconds] = {}
    if not text:
        return out
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        name, sep, value = item.partition("=")
        name, value = name.strip(), value.strip()
        try:
            n = Seconds(value[:-1]) if value.endswith("s") else int(value)
        except ValueError:
            n = None
        if not sep or n is None or not np.isfinite(n):
            raise RecordingError(f"--offsets: {item!r} is not <camera>=<integer frames> or <camera>=<seconds>s")
        if name not in cameras:
            raise RecordingError(f"--offsets: camera {name!r} is not in the rig (cameras {list(cameras)})")
        out[name] = n
    return out


def _camera_folder_video(folder: Path, role: str) -> Path | None:
    """The video a camera folder holds for ``role`` (``"video"`` or ``"background"``): None when the folder
    holds frames (or nothing); the one whose stem is ``role``, or its only video unless that is named for the
    other role (``background.avi`` is never the recording, ``video.avi`` never the empty room); else a
    one-line error."""
    files = [q for q in sorted(folder.iterdir()) if q.is_file() and not q.name.startswith(".")]
    if any(q.suffix.lower() in IMAGE_SUFFIXES for q in files):
        return None
    videos = [q for q in files if q.suffix.lower() in VIDEO_SUFFIXES]
    if not videos:
        return None
    named = [q for q in videos if q.stem.lower() == role]
    if len(named) == 1:
        return named[0]
    other = "background" if role == "video" else "video"
    if len(videos) == 1 and videos[0].stem.lower() != other:  # never a recording as the empty room, or back
        return videos[0]
    raise RecordingError(
        f"{folder}: holds {len(videos)} video{'s' if len(videos) > 1 else ''} ({', '.join(q.name for q in videos)}) "
        f"and none is named '{role}'; "
        f"name the one to use {role}{videos[0].suffix} or map it in {folder.parent / MAPPING_FILE}")


def holds_background_clips(folder: Path, cameras) -> bool:
    """True if ``folder`` has camera folders and each holds a video named ``background`` (the layout where
    ``--background`` can be the videos folder itself)."""
    dirs = [folder / c for c in cameras if (folder / c).is_dir()] if folder.is_dir() else []
    return bool(dirs) and all(any(q.is_file() and q.stem.lower() == "background" and q.suffix.lower() in VIDEO_SUFFIXES
                                  for q in d.iterdir()) for d in dirs)


def _entries(folder: Path, cameras: tuple[str, ...], role: str = "video",
             renamed: list[str] | None = None) -> dict[str, Path]:
    mapping = folder / MAPPING_FILE
    if mapping.is_file():
        try:
            doc = tomllib.loads(mapping.read_text(encoding="utf-8-sig"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise RecordingError(f"{mapping}: not valid TOML ({exc})") from None
        table = doc.get("cameras")
        if not isinstance(table, dict) or not table:
            raise RecordingError(f"{mapping}: field 'cameras' must be a table <camera> = \"<video file>\"")
        out = {}
        for cam, rel in table.items():
            if cam not in cameras:
                raise RecordingError(f"{mapping}: field 'cameras.{cam}': not a rig camera (cameras {list(cameras)})")
            if not isinstance(rel, str):
                raise RecordingError(f"{mapping}: field 'cameras.{cam}' must be a file name (string)")
            p = folder / rel
            if not p.exists():
                raise RecordingError(f"{mapping}: field 'cameras.{cam}': {p} does not exist")
            out[cam] = p
        return out
    out: dict[str, Path] = {}
    held: list[tuple[str, Path]] = []  # videos whose names hold a camera's: after the ones named exactly
    for p in sorted(folder.iterdir()):
        if p.name.startswith("."):
            continue
        if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES:
            named = camera_in_stem(p.stem, cameras)
            if len(named) != 1:
                what = (f"names several rig cameras ({', '.join(named)})" if named
                        else f"is not a rig camera (cameras {list(cameras)})")
                raise RecordingError(f"{p}: {p.stem!r} {what}; rename the video or map it in {folder / MAPPING_FILE}")
            if named[0] != p.stem:
                held.append((named[0], p))
                continue
        elif not (p.is_dir() and p.name in cameras):
            continue
        else:
            p = _camera_folder_video(p, role) or p
            if p.is_file():
                out[p.parent.name] = p
                continue
        if p.stem in out:
            raise RecordingError(f"{p}: camera {p.stem!r} has both {out[p.stem].name} and {p.name}")
        out[p.stem] = p
    exact = set(out)
    for cam, p in held:  # a lab's cam1.mp4 beside cam1_checkerboard.mp4: the exact name is the camera's video
        if cam in exact:
            if renamed is not None:
                renamed.append(f"{p.name}: not read (camera {cam!r} is {out[cam].name})")
        elif cam in out:
            raise RecordingError(f"{p}: camera {cam!r} has both {out[cam].name} and {p.name}; name the one to read "
                                 f"{cam}{p.suffix} or map it in {folder / MAPPING_FILE}")
        else:
            out[cam] = p
            if renamed is not None:
                renamed.append(f"{p.name}: read as camera {cam!r} (its name holds the camera's)")
    return out


def _probe(camera: str, path: Path) -> CameraSource:
    """Open, check the first frame decodes, read size / rate / count."""
    if path.is_dir():
        images = tuple(sorted((q for q in path.iterdir() if q.is_file() and q.suffix.lower() in IMAGE_SUFFIXES),
                              key=frame_order))
        if not images:
            raise RecordingError(f"{path}: no {'/'.join(s[1:] for s in IMAGE_SUFFIXES)} frames in this camera folder")
        img = cv2.imread(str(images[0]), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise RecordingError(f"{images[0]}: cannot read this image (corrupt or not an image)")
        return CameraSource(camera, path, 0.0, len(images), img.shape[1], img.shape[0], images=images)
    cap = cv2.VideoCapture(str(path), cv2.CAP_FFMPEG, DECODER_PARAMS)
    try:
        if not cap.isOpened():
            raise RecordingError(f"{path}: OpenCV (FFmpeg) cannot open this video (corrupt, or not a video)")
        cap.set(cv2.CAP_PROP_ORIENTATION_AUTO, 0.0)  # the stored frames (OpenCV's default differs between builds)
        ok, img = cap.read()
        if not ok or img is None:
            raise RecordingError(_undecodable(path, cap))
        fps = float(cap.get(cv2.CAP_PROP_FPS) or 0.0)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
        rotation = display_rotation(cap)
    finally:
        cap.release()
    return CameraSource(camera, path, fps if np.isfinite(fps) and fps > 0 else 0.0, count if count > 0 else -1,
                        img.shape[1], img.shape[0], rotation=rotation)


def _undecodable(path: Path, cap) -> str:
    """Why video ``path``, which OpenCV opened, gave no first frame: a file whose header names a codec and frames
    is one this OpenCV's FFmpeg cannot decode (AV1, in the opencv-python wheels of this writing) or a corrupt one,
    and re-encoding it says which; else it is empty or corrupt."""
    try:
        codec = _fourcc(cap.get(cv2.CAP_PROP_FOURCC)).strip("\0 ")
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    except (ValueError, OverflowError):  # NaN or out-of-range properties
        codec, count = "", 0
    if codec.isprintable() and codec and count > 0:
        return (f"{path}: none of its {count} frames decodes: OpenCV's FFmpeg has no decoder for its {codec!r} "
                f"video, or the file is corrupt; re-encode it, e.g. ffmpeg -i {path.name} -c:v libx264 -crf 18 "
                f"{path.stem}-h264.mp4")
    return f"{path}: the video has no decodable frame (empty or corrupt)"


def _fits(width: int, height: int, want) -> bool:
    """Frames of ``width`` x ``height`` are the rig camera ``want``'s picture: the same size, the same picture with
    fewer than :data:`CODEC_BLOCK` columns or rows more or less, or the same picture at another scale (module doc)."""
    if (width, height) == (want.width, want.height):
        return True
    if max(abs(want.width - width), abs(want.height - height)) < CODEC_BLOCK:
        return True
    return abs(want.height * width / want.width - height) <= 1.0


def orient(src: CameraSource, want) -> tuple[CameraSource, str | None]:
    """``src`` read upright or as stored for the rig camera ``want`` (module doc, "Orientation"), and the warning
    that says which (None without a rotation)."""
    if not src.rotation or not src.is_video:
        return src, None
    turned = src.rotation % 180 == 90
    up = dataclasses.replace(src, upright=True, width=src.height if turned else src.width,
                             height=src.width if turned else src.height)
    what = f"{src.path.name}: its metadata rotates its {src.width}x{src.height} frames by {src.rotation} degrees"
    if _fits(up.width, up.height, want) or not _fits(src.width, src.height, want):
        return up, (f"{what}: read upright ({up.width}x{up.height}) as players show it"
                    + ("" if turned else "; if camera {!r} was calibrated on the stored frames, remove the rotation "
                       "(ffmpeg -i IN -c copy -metadata:s:v rotate=0 OUT)".format(src.camera)))
    return src, (f"{what}: read as stored, because camera {src.camera!r} of the rig is {want.width}x{want.height} "
                 f"(calibrated on the stored frames)")


def _probe_or_error(camera: str, path: Path) -> CameraSource | RecordingError:
    try:
        return _probe(camera, path)
    except RecordingError as exc:
        return exc


def probe_all(entries: dict[str, Path], cameras) -> list[CameraSource | RecordingError]:
    """:func:`_probe` of every camera of ``cameras`` that ``entries`` maps to a file or folder, in that order: its
    source, or its one-line error. The videos are opened side by side, a thread each (at most the CPU count):
    opening a video and decoding its first frame is FFmpeg's work, which releases the GIL, and a run's set-up
    otherwise waits for one video after the other."""
    todo = [c for c in cameras if c in entries]
    workers = max(1, min(len(todo), os.cpu_count() or 1))
    if workers == 1:
        return [_probe_or_error(c, entries[c]) for c in todo]
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(lambda c: _probe_or_error(c, entries[c]), todo))


def open_recording(folder, rig, offsets: dict[str, int | Seconds] | None = None, role: str = "video") -> Recording:
    """Match, probe and synchronise the videos of ``folder`` for ``rig`` (module docstring); ``role`` picks the
    video of camera folders that hold several (``"video"``, or ``"background"`` for empty-room clips)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RecordingError(f"{folder}: videos folder not found")
    cameras = tuple(rig.names)
    renamed: list[str] = []
    entries = _entries(folder, cameras, role, renamed)
    if not entries:
        raise RecordingError(
            f"{folder}: no video named as a rig camera ({', '.join(c + '.mp4' for c in cameras)}, or a "
            f"{MAPPING_FILE} mapping)")
    warnings = list(renamed)
    quiet_decoders()
    sources = {}
    unreadable: list[RecordingError] = []
    for cam, src in zip([c for c in cameras if c in entries], probe_all(entries, cameras)):
        if isinstance(src, RecordingError):  # one unreadable camera is a missing view, not the end of the recording
            unreadable.append(src)
            continue
        want = rig[cameras.index(cam)]
        src, turned = orient(src, want)
        if turned:
            warnings.append(turned)
        if (src.width, src.height) != (want.width, want.height):
            sx = want.width / src.width
            pad = (want.width - src.width, want.height - src.height)
            if abs(want.height / sx - src.height) > 1.0 and max(map(abs, pad)) < CODEC_BLOCK:
                warnings.append(f"{src.path.name}: frames are {src.width}x{src.height}, camera {cam!r} of the rig is "
                                f"{want.width}x{want.height}: read as its picture with the right and bottom edges "
                                f"{'padded' if min(pad) >= 0 else 'cut'} by {pad[0]} column(s), {pad[1]} row(s) "
                                "(encoders round sides to 16 px)")
                sources[cam] = dataclasses.replace(src, width=want.width, height=want.height, pad=pad)
                continue
            if abs(want.height / sx - src.height) > 1.0:  # not the same picture up to rounding
                raise RecordingError(
                    f"{src.path}: frames are {src.width}x{src.height} (WxH), camera {cam!r} of the rig is "
                    f"{want.width}x{want.height} (another aspect ratio): crop or resize the video to the "
                    f"calibration's picture, or calibrate at this resolution")
            src = dataclasses.replace(src, resize_to=(want.width, want.height))
            warnings.append(f"{src.path.name}: frames are {src.width}x{src.height}, camera {cam!r} of the rig is "
                            f"{want.width}x{want.height}: every frame is scaled by {sx:.3g}")
        sources[cam] = src
    if not sources and unreadable:
        raise unreadable[0]
    warnings += [f"{exc}: a missing view in every frame" for exc in unreadable]
    missing = tuple(c for c in cameras if c not in sources)
    absent = [c for c in missing if c not in entries]
    if absent:
        warnings.append(f"no video for camera(s) {', '.join(absent)}: a missing view in every frame")
    rates = {c: s.fps for c, s in sources.items() if s.fps > 0}
    fps = 0.0
    if rates:
        lo, hi = min(rates.values()), max(rates.values())
        if hi > lo * (1 + FPS_TOLERANCE):
            desc = ", ".join(f"{sources[c].path.name} {r:g} fps" for c, r in rates.items())
            raise RecordingError(
                f"{folder}: the videos' frame rates differ by more than {100 * FPS_TOLERANCE:g} % ({desc}); "
                f"re-encode them to one rate (e.g. ffmpeg -i IN -r 30 OUT)")
        fps = hi  # the grid of the fastest camera: the others give a frame twice rather than lose one
        unknown = [c for c, s in sources.items() if s.fps == 0 and s.is_video]
        if unknown:
            warnings.append(f"no frame rate in {', '.join(sources[c].path.name for c in unknown)}: assuming {fps:g} fps")
    offsets = dict(offsets or {})
    if any(isinstance(v, Seconds) for v in offsets.values()):
        if fps <= 0:
            raise RecordingError(f"{folder}: --offsets in seconds need a frame rate, and no video states one: give "
                                 "them in frames")
        offsets = {c: int(round(v * fps)) if isinstance(v, Seconds) else v for c, v in offsets.items()}
    base = min([0] + [offsets.get(c, 0) for c in sources])
    for c, s in sources.items():
        sources[c] = dataclasses.replace(s, skip=offsets.get(c, 0) - base, grid_fps=fps if s.is_video else 0.0)
    lengths = {c: s.n_steps - s.skip for c, s in sources.items() if s.n_frames >= 0}
    for c, n in lengths.items():
        if n <= 0:
            raise RecordingError(f"{sources[c].path}: has {sources[c].n_frames} frames, fewer than its offset {sources[c].skip}")
    n_steps = max(lengths.values()) if len(lengths) == len(sources) else -1
    if len(set(lengths.values())) > 1:
        warnings.append(
            "videos of unequal length (" + ", ".join(f"{sources[c].path.name} {n}" for c, n in lengths.items())
            + " frames after offsets): a shorter video's camera is a missing view ('video ended') after its last frame")
    return Recording(folder, sources, missing, n_steps, fps, warnings, offsets)


def _fourcc(code: float) -> str:
    """The four characters of a FourCC number (OpenCV's ``CAP_PROP_*`` codes)."""
    return int(code).to_bytes(4, "little").decode("latin-1")


def fit_picture(img: np.ndarray, pad: tuple[int, int]) -> np.ndarray:
    """``img`` (H, W[, C]) with ``pad = (columns, rows)`` added at its right and bottom edges (copies of its
    last column / row) or, when negative, removed there: (H + rows, W + columns[, C])."""
    dw, dh = int(pad[0]), int(pad[1])
    if dw < 0:
        img = img[:, :dw]
    if dh < 0:
        img = img[:dh]
    if dw > 0 or dh > 0:
        img = cv2.copyMakeBorder(img, 0, max(dh, 0), 0, max(dw, 0), cv2.BORDER_REPLICATE)
    return img


class CameraReader:
    """Streams one camera's frames: :meth:`read` gives the next one, or None at the end.

    grey: (H, W) uint8 frames (masks), else (H, W, 3) uint8 BGR. A video opens at construction and
    skips ``source.skip`` frames (offsets) plus ``start`` frames.
    """

    def __init__(self, source: CameraSource, grey: bool, start: int = 0):
        self.source = source
        self.grey = grey
        self.index = source.skip + int(start)
        self.ended_at: int | None = None  # frame index where reading stopped, once it has
        self.cap = None
        self.luma = False  # frames are the decoder's luma plane (LUMA_FORMATS)
        self._ahead: collections.deque = collections.deque()  # frames read by read_ahead, given again by read
        # the time grid (module docstring, "Time stamps"): the first frame's time, a grabbed frame not yet given
        # (its step is later), the last frame given (a step without a frame of its own gives it again)
        self._grid = source.is_video and source.grid_fps > 0
        self._t0: float | None = None
        self._t_last = -np.inf
        self._held: float | None = None  # time stamp of the grabbed frame held back
        self._last: np.ndarray | None = None
        self.repeated = self.dropped = 0
        if source.is_video:
            self.cap = self._open(grey)
            if grey and _fourcc(self.cap.get(cv2.CAP_PROP_CODEC_PIXEL_FORMAT)) in LUMA_FORMATS:
                self.luma = True
            elif grey:
                self.cap.release()
                self.cap = self._open(False)
            for k in range(self.index):
                if self._grab_step(k, skipping=True) is False:
                    break

    def _grab_step(self, step: int, skipping: bool = False) -> bool | None:
        """Grab the frame of grid step ``step`` (module docstring, "Time stamps"): True when the capture now holds
        it (:meth:`cv2.VideoCapture.retrieve` decodes it), None when the step has no frame of its own (the
        previous frame is its frame), False at the end of the video. Without the grid: the next frame. A step
        with no frame of its own when no frame was decoded before (``self._last`` None: the first step read after
        skipping, ``skipping`` False) takes the next frame."""
        if not self._grid:
            return self.cap.grab()
        while True:
            if self._held is None:
                if not self.cap.grab():
                    return False
                t = float(self.cap.get(cv2.CAP_PROP_POS_MSEC)) / 1000.0
                if not (np.isfinite(t) and t > self._t_last):  # no usable time stamps: by index from here on
                    self._grid = False
                    return True
                self._t_last = t
                if self._t0 is None:
                    self._t0 = t
                self._held = t
            held = int(round((self._held - self._t0) * self.source.grid_fps))
            if held < step:  # a second frame for a step already given: dropped
                self._held = None
                self.dropped += 1
                continue
            if held > step and (skipping or self._last is not None):  # no frame of its own: the previous one
                self.repeated += 1
                return None
            self._held = None
            return True

    def _open(self, luma: bool):
        params = DECODER_PARAMS + ([cv2.CAP_PROP_CONVERT_RGB, 0] if luma else [])
        cap = cv2.VideoCapture(str(self.source.path), cv2.CAP_FFMPEG, params)
        if not cap.isOpened():
            raise RecordingError(f"{self.source.path}: OpenCV (FFmpeg) cannot open this video")
        # upright or as stored (module doc, "Orientation"); set either way: OpenCV's default differs between builds
        cap.set(cv2.CAP_PROP_ORIENTATION_AUTO, 1.0 if self.source.upright else 0.0)
        return cap

    def read_ahead(self, n: int) -> list[np.ndarray]:
        """The next ``n`` frames (fewer at the end), as :meth:`read` gives them, kept: the next ``n`` calls of
        :meth:`read` give them again without decoding them twice (a set-up that looks at a recording's first
        frames before the run, :func:`~.silhouettes.room_view_ahead`). Memory: ``n`` frames."""
        frames = list(self._ahead)
        while len(frames) < n:
            img = self._read()
            if img is None:
                break
            frames.append(img)
        self._ahead = collections.deque(frames)
        return frames[:n]

    def read(self) -> np.ndarray | None:
        if self._ahead:
            return self._ahead.popleft()
        return self._read()

    def _read(self) -> np.ndarray | None:
        img = self._next()
        if img is None:
            if self.ended_at is None:
                self.ended_at = self.index
            return None
        self.index += 1
        if self.grey and img.ndim == 3:
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        elif self.luma:
            img = luma_to_grey(img)
        if self.source.pad != (0, 0):
            img = fit_picture(img, self.source.pad)
        if self.source.resize_to is not None:
            if self.source.resize_to[0] < img.shape[1]:  # averaging the merged pixels: no aliasing
                img = shrink(img, self.source.resize_to)
            else:
                img = cv2.resize(img, self.source.resize_to, interpolation=cv2.INTER_LINEAR)
        return img

    def seek(self, frame: int) -> None:
        """Move to frame ``frame`` of the recording (after the source's offset): the next :meth:`read` gives it
        (a video seeks from its previous key frame; an approximate position is fine for sampling)."""
        self.index = self.source.skip + int(frame)
        self.ended_at = None
        self._ahead.clear()
        if self.cap is not None:
            self.cap.set(cv2.CAP_PROP_POS_FRAMES, float(self.index))
            self._held, self._last, self._t_last = None, None, -np.inf
            if self._t0 is None:
                self._t0 = 0.0  # OpenCV's time stamps count from the stream's start

    def skip(self, n: int) -> None:
        """Move ``n`` frames forward without returning them: a video's frames are decoded (its P-frames need
        them) but neither converted to BGR nor resized -- for a few frames, cheaper than :meth:`seek` (OpenCV's
        FFmpeg seek decodes again from 16 or more frames before the target)."""
        n = max(0, int(n))
        while n and self._ahead:
            self._ahead.popleft()
            n -= 1
        for _ in range(n):
            if self.cap is not None:
                if self._grab_step(self.index, skipping=True) is False:
                    break
                self._last = None  # not decoded: a step without a frame of its own after this one takes the next
            self.index += 1

    def _next(self) -> np.ndarray | None:
        if self.ended_at is not None:
            return None
        if self.cap is not None:
            got = self._grab_step(self.index)
            if got is None:
                return self._last
            ok, img = self.cap.retrieve() if got else (False, None)
            self._last = img if ok else None
            return img if ok else None
        if self.index >= len(self.source.images):
            return None
        if self.grey:  # masks as users' tools write them: 0/1, palettes, label maps, RGBA cut-outs (mask_grey)
            img = cv2.imread(str(self.source.images[self.index]), cv2.IMREAD_UNCHANGED)
            img = None if img is None else mask_grey(img)
        else:
            img = cv2.imread(str(self.source.images[self.index]), cv2.IMREAD_COLOR)
        if img is None or (img.shape[1], img.shape[0]) != (self.source.width, self.source.height):
            return None  # a corrupt frame ends the camera, like a video that stops decoding
        return img

    def summary(self) -> str | None:
        """One line when reading stopped before the header's (or folder's) frame count, or when frames were
        repeated or dropped to keep the video on the recording's time grid (module docstring, "Time stamps");
        else None."""
        p = self.source.path
        name = f"{p.parent.name}/{p.name}" if p.parent.name == self.source.camera else p.name
        timing = (f"{name}: its frames' time stamps are off the {self.source.grid_fps:g} fps grid of the recording "
                  f"(a variable frame rate): {self.repeated} step(s) gave the previous frame again and "
                  f"{self.dropped} frame(s) were dropped, to keep camera {self.source.camera!r} in time"
                  if self.repeated or self.dropped else None)
        n = self.source.n_steps
        # on the grid, the steps are the duration's estimate (CameraSource.n_steps), within a step
        late = 1 if self._grid and (n != self.source.n_frames or self.repeated or self.dropped) else 0
        if self.ended_at is None or n < 0 or self.ended_at >= n - late:
            return timing
        stopped = self._stopped(name, n)
        return stopped if timing is None else f"{stopped}; {timing}"

    def _stopped(self, name: str, n: int) -> str:
        return (f"{name}: decoding stopped at frame {self.ended_at} of the {n} its header announced "
                f"(truncated or corrupt file; set OPENCV_FFMPEG_LOGLEVEL=24 to see FFmpeg's messages): "
                f"camera {self.source.camera!r} is a missing view ('video ended') from there on"
                if self.source.images is None else
                f"{name}: frame {self.ended_at} of {n} cannot be read (corrupt or of another size): camera "
                f"{self.source.camera!r} is a missing view ('video ended') from there on")

    def close(self) -> None:
        if self.cap is not None:
            self.cap.release()
            self.cap = None


class ThreadedReader:
    """A :class:`CameraReader` decoding in its own thread, ``depth`` frames ahead: the camera's decoding
    (FFmpeg releases the GIL) overlaps the other cameras' and the segmentation. Same ``read`` / ``summary``
    / ``close`` as the reader it wraps; an exception in the thread is raised by the next ``read``.

    ``after`` (settable while the thread runs; None: nothing): a function of a decoded frame whose result
    :meth:`read_with` hands over with it, computed in this thread too (the pipeline: the frame's segmentation
    candidates, :meth:`~.silhouettes.ColourSegmenter.candidates`, which release the GIL; None for frames decoded
    before it was set)."""

    def __init__(self, reader: CameraReader, depth: int = 4, after: Callable[[np.ndarray], object] | None = None):
        self.reader = reader
        self.source = reader.source
        self.after = after
        self._queue: queue.Queue = queue.Queue(maxsize=max(1, int(depth)))
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"read-{reader.source.camera}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                img = self.reader.read()
                after = self.after
                self._put((img, None if img is None or after is None else after(img)))
                if img is None:
                    return
        except BaseException as exc:  # handed to the consumer
            self._put(exc)

    def _put(self, item) -> None:
        while not self._stop.is_set():
            try:
                self._queue.put(item, timeout=0.1)
                return
            except queue.Full:
                continue

    def read(self) -> np.ndarray | None:
        return self.read_with()[0]

    def read_with(self) -> tuple[np.ndarray | None, object]:
        """(the next frame or None at the end, ``after`` of it or None)."""
        if not self._thread.is_alive() and self._queue.empty():
            return None, None
        item = self._queue.get()
        if isinstance(item, BaseException):
            raise item
        return item

    def summary(self) -> str | None:
        return self.reader.summary()

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
        self.reader.close()
