"""A multi-camera frames folder: per-camera background and frame images (or videos), validated (not read).

Layout (the "frames dataset" contract; only the two folders below are read here)::

    DIR/background/<camera>/00000.png ...   N >= 2 empty-scene frames per camera
    DIR/background/<camera>.mp4|.avi        ... or one video per camera
    DIR/frames/<camera>/00000.png ...       one frame per time step per camera
    DIR/frames/<camera>.mp4|.avi            ... or one video per camera

``<camera>`` is a camera name of the rig the caller passes. Frames are matched across cameras by
file name (image folders: every camera folder must hold the same file names) or by index
(videos: ``00000``, ``00001``, ...; every video must have the same number of frames). A camera
whose frames entry is absent is reported in :attr:`FramesFolder.missing` (the caller decides what
that means); every other problem found without decoding a frame raises
:class:`~silpose.app.errors.FramesInputError` naming the file or folder: an unknown camera name, missing or too
few background frames, videos OpenCV cannot open, frame names or counts that differ across cameras.
:func:`open_frames` checks a folder for a model's rig. The frames are read as a recording
(:mod:`silpose.app.recordings.frames_source`), where an unreadable frame or one of another size is an error
naming the file.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import cv2

from ..errors import FramesInputError
from .images import IMAGE_SUFFIXES, VIDEO_SUFFIXES, frame_order


@dataclass(frozen=True)
class CameraEntry:
    """Where one camera's frames or background live: an image folder or a video file.

    name: camera name; path: the folder or video; images: the image files in name order (``images.frame_order``: img2 before img10) (None for a video).
    """

    name: str
    path: Path
    images: tuple[Path, ...] | None

    @property
    def is_video(self) -> bool:
        return self.images is None


def _entries(folder: Path, cameras: Sequence[str], what: str) -> dict[str, CameraEntry]:
    """Camera entries (sub-folders and videos) of ``folder``; unknown names and duplicates are errors."""
    found: dict[str, CameraEntry] = {}
    for p in sorted(folder.iterdir()):
        if p.name.startswith("."):
            continue
        if p.is_dir():
            name, images = p.name, tuple(
                sorted((q for q in p.iterdir() if q.is_file() and q.suffix.lower() in IMAGE_SUFFIXES), key=frame_order)
            )
        elif p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES:
            name, images = p.stem, None
        else:
            continue
        if name not in cameras:
            raise FramesInputError(
                f"{p}: camera {name!r} is not in the rig (cameras {list(cameras)}); rename or remove this {what} entry"
            )
        if name in found:
            raise FramesInputError(f"{p}: camera {name!r} has both {found[name].path.name} and {p.name} in {folder}")
        if images is not None and not images:
            raise FramesInputError(f"{p}: no {'/'.join(s[1:] for s in IMAGE_SUFFIXES)} images in this {what} folder")
        found[name] = CameraEntry(name, p, images)
    return found


def _video_length(path: Path) -> int:
    """Frame count OpenCV reports for a video (checked again while decoding)."""
    cap = cv2.VideoCapture(str(path))
    try:
        if not cap.isOpened():
            raise FramesInputError(f"{path}: OpenCV cannot open this video")
        return int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
    finally:
        cap.release()


class FramesFolder:
    """Validated view of a frames folder for a rig's cameras.

    Parameters
    ----------
    root : str or Path
        The folder holding ``background/`` and ``frames/``.
    cameras : sequence of str
        The rig's camera names, in view order.

    Attributes
    ----------
    present : tuple of str
        Cameras (rig order) with frames.
    missing : tuple of str
        Cameras (rig order) without a frames entry.
    frame_names : list of str
        Frame names (image file stems, or ``00000``-style indices for videos), in order.
    """

    def __init__(self, root, cameras: Sequence[str]):
        self.root = Path(root)
        self.cameras = tuple(str(c) for c in cameras)
        if not self.root.is_dir():
            raise FramesInputError(f"{self.root}: frames folder not found")
        frames_dir, bg_dir = self.root / "frames", self.root / "background"
        if not frames_dir.is_dir():
            raise FramesInputError(
                f"{frames_dir}: no such folder; a frames folder holds frames/<camera>/ (or frames/<camera>.mp4) "
                f"and background/<camera>/, cameras {list(self.cameras)}"
            )
        self._frames = _entries(frames_dir, self.cameras, "frames")
        if not self._frames:
            raise FramesInputError(f"{frames_dir}: no camera folders or videos named as the rig's cameras {list(self.cameras)}")
        if not bg_dir.is_dir():
            raise FramesInputError(f"{bg_dir}: no such folder: background frames are needed to learn each camera's background")
        self._background = _entries(bg_dir, self.cameras, "background")
        self.present = tuple(c for c in self.cameras if c in self._frames)
        self.missing = tuple(c for c in self.cameras if c not in self._frames)
        for cam in self.present:
            if cam not in self._background:
                raise FramesInputError(
                    f"{bg_dir}: missing background frames for camera {cam!r} "
                    f"(expected {bg_dir / cam}/00000.png ... or {bg_dir / cam}.mp4)"
                )
            bg = self._background[cam]
            if bg.images is not None and len(bg.images) < 2:
                raise FramesInputError(f"{bg.path}: a background needs at least 2 frames, found {len(bg.images)}")
        self.frame_names = self._match_frames()

    # ------------------------------------------------------------------ validation
    def _match_frames(self) -> list[str]:
        lengths: dict[str, int] = {}
        names: list[str] | None = None
        ref = None
        for cam in self.present:
            e = self._frames[cam]
            if e.is_video:
                lengths[cam] = _video_length(e.path)
                continue
            stems = [p.stem for p in e.images]
            lengths[cam] = len(stems)
            if names is None:
                names, ref = stems, e
            elif stems != names:
                only = sorted(set(stems) ^ set(names))
                what = f"file {only[0]!r} is in one but not the other" if only else "the file names differ"
                raise FramesInputError(
                    f"{e.path}: frame files differ from {ref.path} ({len(stems)} vs {len(names)} frames; {what}); "
                    f"every camera folder must hold the same file names"
                )
        counts = set(lengths.values())
        if len(counts) > 1:
            desc = ", ".join(f"{self._frames[c].path.name}: {n}" for c, n in lengths.items())
            raise FramesInputError(f"{self.root / 'frames'}: frame counts differ across cameras ({desc})")
        n = counts.pop()
        if n == 0:
            raise FramesInputError(f"{self._frames[self.present[0]].path}: no frames")
        return names if names is not None else [f"{i:05d}" for i in range(n)]

    @property
    def n_frames(self) -> int:
        return len(self.frame_names)


def open_frames(model, root) -> FramesFolder:
    """A frames folder validated against a fitted model's rig (camera names).

    model: a ShapeStructureModel with a rig (``rig_``); root: the folder. FramesInputError otherwise.
    """
    if model.rig_ is None:
        raise FramesInputError("the model file stores no rig, so camera folders cannot be matched to views")
    rig = model.rig_
    return FramesFolder(root, rig.names)
