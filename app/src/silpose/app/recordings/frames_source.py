"""The frames-folder layout as one more source layout of a recording (``silpose infer --frames DIR``).

Layout (:mod:`silpose.app.inputs.frames_folder`, which validates it)::

    DIR/background/<camera>/00000.png ...   (or <camera>.mp4|.avi) empty-scene frames, >= 2 per camera
    DIR/frames/<camera>/00000.png ...       (or <camera>.mp4|.avi) frames, the same file names per camera

It is a recording folder (``DIR/frames``: one frame folder or video per camera, read by
:func:`~.sources.open_recording` and :class:`~.sources.CameraReader` like any other) with its empty-room clips
beside it (``DIR/background``: ``--background``). What the layout adds is its contract, checked before any
frame is processed: every camera folder holds the same file names (they name the frames), a camera of the
frames has a background, no entry names a camera outside the rig
(:class:`~silpose.app.inputs.frames_folder.FramesFolder`, one-line errors). And while reading, a frame that cannot be read or has another size is an input error naming
the file (:func:`bad_frame`), where a recording would end that camera's video.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import cv2

from ..errors import RecordingError
from ..inputs.frames_folder import FramesFolder
from ..inputs.images import frame_size_text
from .sources import CameraSource, Recording, open_recording

#: the sub-folders of a frames folder
FRAMES, BACKGROUND = "frames", "background"


def is_frames_folder(path) -> bool:
    """True if ``path`` has the frames-folder layout (a ``frames/`` sub-folder)."""
    return (Path(path) / FRAMES).is_dir()


@dataclass
class FramesFolderSource:
    """A validated frames folder: ``recording`` (``DIR/frames``'s cameras), ``background`` (``DIR/background``,
    the empty-room clips), ``frame_names`` (N,) (the image file stems, or ``00000``-style indices of videos)."""

    root: Path
    recording: Recording
    background: Path
    frame_names: list[str]


def open_frames_folder(root, rig) -> FramesFolderSource:
    """Validate ``root`` for ``rig`` (module docstring) and open its frames as a recording."""
    root = Path(root)
    folder = FramesFolder(root, rig.names)  # the layout's one-line errors (names, counts, backgrounds)
    recording = open_recording(root / FRAMES, rig)
    return FramesFolderSource(root, recording, root / BACKGROUND, list(folder.frame_names))


def bad_frame(source: CameraSource, index: int) -> RecordingError:
    """The one-line error for frame ``index`` of a frames-folder camera whose reader stopped there."""
    if source.images is None:
        return RecordingError(f"{source.path}: the video ends after {index} frames; other cameras have "
                              f"{source.n_frames}")
    path = source.images[index]
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        return RecordingError(f"{path}: cannot read this image (corrupt or not an image)")
    return RecordingError(f"{path}: frame size {frame_size_text(img.shape)} differs from camera "
                          f"{source.camera!r} ({source.width}x{source.height} (WxH))")


def frames_folder_run(path, opt, rig, require: bool = False) -> tuple[Path, object, list[str] | None]:
    """A run's (recording folder, options, frame names): for a frames folder, its ``frames/`` with its
    ``background/`` as the empty-room clips (unless the options give masks or another background) and its
    validated frame names; any other folder as it is, with None (``require``: the layout's errors instead)."""
    if not require and not is_frames_folder(path):
        return Path(path), opt, None
    root = Path(path)
    names = list(FramesFolder(root, rig.names).frame_names)
    if not opt.masks and opt.background is None and opt.background_frames is None:
        opt = dataclasses.replace(opt, background=root / BACKGROUND)
    return root / FRAMES, opt, names
