"""One camera of a recording, step by step (:mod:`.pipeline`): its reader, each frame's mask and blobs, static
clutter made background (colour videos), and a warning when its masks look wrong over the run."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .blobs import Blobs, find_blobs
from .silhouettes import MASK_THRESHOLD
from .sources import CameraReader, ThreadedReader
from .views import VIEW_EMPTY, VIEW_ENDED, body_box

#: metres: radius of the cylinder around each detected person that is never made background: the body and
#: the arms' swing (half the view test's 0.9 m, so a box on the floor beside someone's path is absorbed)
PROTECT_RADIUS_M = 0.45
#: a camera whose masks are empty, or mostly foreground, in at least this share of its frames gets a warning
#: naming the likely cause (0/1 or inverted mask videos, a wrong background clip)
MASK_DIAGNOSIS_SHARE = 0.9


@dataclass
class Seen:
    """One camera at one step: background (mask or frame) for the overlay, blobs, camera status (or None)."""

    background: np.ndarray | None
    blobs: Blobs | None
    status: str | None
    mask: np.ndarray | None = None
    peak: int = 0  # the frame's highest grey level when its mask came out empty (the diagnosis's hint)


def shown(source) -> str:
    """How a warning names a camera's video: its file name, with its folder when that is the camera's
    (``cam1/video.avi``)."""
    p = source.path
    return f"{p.parent.name}/{p.name}" if p.parent.name == source.camera else p.name


class CameraStep:
    """One camera's reader + mask maker; ``step()`` -> :class:`Seen` (runs in a worker thread); ``settle()``
    (main thread, between steps) makes static clutter background (module docstring)."""

    def __init__(self, reader: CameraReader | ThreadedReader, silhouettes, min_area: int, keep_frame: bool,
                 cam=None, absorb_frames: int = 0):
        self.reader, self.silhouettes, self.min_area, self.keep_frame = reader, silhouettes, min_area, keep_frame
        self.cam, self.absorb_frames = cam, int(absorb_frames)
        self.age: np.ndarray | None = None  # frames each pixel has been foreground outside every person's box
        self.absorbed = 0  # pixels made background
        self.ended = False
        self.frames = self.empty = self.crowded = 0  # frames read, with no foreground, mostly foreground
        self.brightest_empty = 0  # the highest grey level of a frame whose mask came out empty
        self.quiesce: Callable[[], None] | None = None  # waits for this camera's step started ahead (.lookahead)

    def step(self) -> Seen:
        """The next frame's mask and blobs (a worker thread; :meth:`tally` counts it, in the run's thread)."""
        if self.ended:
            return Seen(None, None, VIEW_ENDED)
        img, ahead = self.reader.read_with() if isinstance(self.reader, ThreadedReader) else (self.reader.read(), None)
        if img is None:
            self.ended = True
            return Seen(None, None, VIEW_ENDED)
        return self._segment(img, ahead)

    def ahead(self, img: np.ndarray):
        """What the camera's reader thread computes of a colour frame it decoded (module docstring, "Threads"): its
        segmentation candidates (:meth:`~.silhouettes.ColourSegmenter.candidates`); None for mask videos."""
        candidates = getattr(self.silhouettes, "candidates", None)
        return None if candidates is None else candidates(self.reader.source.camera, img)

    def _segment(self, img: np.ndarray, ahead=None) -> Seen:
        """``ahead``: the frame's segmentation candidates from the reader thread (:meth:`ahead`), or None."""
        cam = self.reader.source.camera
        mask = self.silhouettes(cam, img) if ahead is None else self.silhouettes(cam, img, ahead)
        blobs = find_blobs(mask, self.min_area)
        return Seen(img if self.keep_frame else mask, blobs, VIEW_EMPTY if blobs.empty else None, mask,
                     int(img.max()) if blobs.empty else 0)

    def resegment(self, seen: Seen) -> Seen:
        """``seen`` segmented again from its frame (colour videos: a step started ahead, before :meth:`settle` made
        some of the background new)."""
        return seen if seen.status == VIEW_ENDED or not self.keep_frame else self._segment(seen.background)

    def tally(self, seen: Seen) -> None:
        """Count a step's mask for :meth:`diagnosis`."""
        if seen.blobs is None:
            return
        self.frames += 1
        if seen.blobs.empty:
            self.empty += 1
            self.brightest_empty = max(self.brightest_empty, seen.peak)
        elif 2 * int(seen.blobs.area[1:].sum()) > seen.mask.size:
            self.crowded += 1

    def settle(self, seen: Seen, people_xy: np.ndarray) -> bool:
        """Foreground outside every detected person's body box (:func:`~.views.body_box`, at floor points
        ``people_xy`` (P, 2)) for ``absorb_frames`` frames in a row becomes background (colour videos only).
        Returns True if some did (a next step segmented already is then out of date)."""
        models = getattr(self.silhouettes, "models", None)
        if self.absorb_frames <= 0 or models is None or seen.mask is None or seen.background is None:
            return False
        fg = seen.mask.astype(bool)
        loose = fg.copy()
        if len(people_xy):
            h, w = loose.shape
            for x0, y0, x1, y1 in body_box(self.cam, people_xy, PROTECT_RADIUS_M):
                if not np.isfinite([x0, y0, x1, y1]).all():  # beyond this camera's lens model: not in its image
                    continue
                a, b = max(0, int(np.floor(x0))), min(w, int(np.ceil(x1)) + 1)
                c, d = max(0, int(np.floor(y0))), min(h, int(np.ceil(y1)) + 1)
                if a < b and c < d:
                    loose[c:d, a:b] = False
        if self.age is None:
            self.age = np.zeros(loose.shape, np.uint16)
        # foreground outside every box ages; inside a box it keeps its age; background starts again from 0
        # (in place: a few passes over the frame instead of four temporaries)
        np.multiply(self.age, fg, out=self.age, casting="unsafe")
        np.minimum(self.age, 65534, out=self.age, where=loose)
        np.add(self.age, 1, out=self.age, where=loose, casting="unsafe")
        ready = loose & (self.age >= self.absorb_frames)  # never where a person may be now (their colours)
        if int(ready.sum()) >= self.min_area:
            if self.quiesce is not None:  # never change the model under a step that is segmenting ahead
                self.quiesce()
            models[self.reader.source.camera].absorb(seen.background, ready)
            self.absorbed += int(ready.sum())
            self.age[ready] = 0
            return True
        return False

    def diagnosis(self, masks: bool) -> str | None:
        """One warning line when this camera's masks look wrong over the run (module docstring), else None."""
        name, n = shown(self.reader.source), self.frames
        if n == 0:
            return None
        if self.empty >= MASK_DIAGNOSIS_SHARE * n:
            hint = ("its grey levels never exceeded "
                    f"{self.brightest_empty}: if foreground is stored as 1 (not 255), rescale the video"
                    if masks and 0 < self.brightest_empty <= MASK_THRESHOLD else
                    "check that this is the right video" + (" and the background clip" if not masks else ""))
            return f"{name}: no foreground in {self.empty} of {n} frames ({hint})"
        if self.crowded >= MASK_DIAGNOSIS_SHARE * n:
            what = ("are the masks inverted (people black on white)?" if masks else
                    "did the lighting change, or the camera move, since the background was learnt?")
            return f"{name}: foreground covers more than half of the image in {self.crowded} of {n} frames: {what}"
        return None
