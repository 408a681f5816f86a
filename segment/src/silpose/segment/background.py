"""The paper's background subtraction (section 6, after its reference [12]) as a fitted model.

1. Background statistics: per-pixel mean and standard deviation of the graylevel over N >= 2
   empty-scene frames, accumulated exactly in int64 sums (sum x, sum x^2) so long backgrounds
   (the paper uses 400 frames) can stream in chunks through :meth:`BackgroundModel.partial_fit`:
       mean = S1 / N,   var = (N S2 - S1^2) / N^2   (population variance, numpy's ddof=0).
2. Candidates: pixels whose graylevel is more than ``k_sigma`` standard deviations from the
   background mean, ``|f - mean| > k_sigma * max(std, min_std)``. Colour frames (with
   ``colour=True``, the default) use the per-channel statistics instead: a pixel is a candidate
   when the RMS over the channels of ``(f_c - mean_c) / max(std_c, min_std)`` exceeds
   ``k_sigma`` (on a graylevel frame this is the rule above).
3. Shadow rejection: a candidate is a shadow when the frame correlates with the background mean
   over the candidate pixels of the ``ncc_window`` around it (local NCC > ``ncc_threshold``, see
   :mod:`.ncc`) *and* the window got darker, ``shadow_ratio[0] <= E_W[f] / E_W[b] <=
   shadow_ratio[1]``. Two additions to the paper, and why:
   - the darkening rule: NCC is blind to gain and offset, so it alone would also call a
     brightened or nearly black correlated patch a "shadow"; a cast shadow only attenuates the
     light, by a bounded factor, so the default ``(0.25, 1.0)`` admits darkening to no less
     than a quarter of the background brightness;
   - the noise correction (``noise_correction``): camera noise caps the NCC of a deep shadow
     below the threshold; the NCC is divided by that noise ceiling, estimated from the
     per-pixel background variance.
   On colour frames a third step extends the accepted shadows (an addition, see
   :mod:`.chroma`): candidates whose colour is the background's, darkened (brightness
   distortion in ``shadow_ratio``, chromaticity distortion <= ``chroma_max``), are shadows when
   they are 8-connected to an NCC-accepted shadow pixel through such pixels. The NCC alone
   leaves the rim and the poorly textured parts of rendered floor shadows.
4. Mixed edge pixels (an addition, ``edge_coverage``): a pixel on the mask's edge that the person
   covers only in part differs from the background by that part of the person's own difference (light
   mixes linearly over a pixel: ``f - b = a (p - b)`` for a pixel a fraction ``a`` of which shows the
   person). An edge pixel (a kept pixel with a dropped 8-neighbour) whose difference ``|f - b|``
   (graylevels; Euclidean over the channels of colour frames) is below ``edge_coverage`` times the
   largest difference of its interior kept 8-neighbours is dropped: the mask's edge then passes where
   the person covers half of a pixel, as a true mask's does, instead of wherever any of the person
   shows -- about a pixel too far out all round, which matters at the recordings' working sizes, where a
   pixel holds several camera pixels (:mod:`silpose.app.recordings.resolution`).
5. Median filter (``median_size``), morphological open (``open_size``) then close
   (``close_size``), see :mod:`.cleanup`, guarded by the evidence (``cleanup_guard``, an addition): the filters
   are there for the pixels near the threshold (noise specks, ragged edges), so they neither drop a pixel whose
   difference from the background is unambiguous (above ``cleanup_guard[0] * k_sigma``: a hand's tip, an
   elbow's corner) nor add one that matches the background (below ``cleanup_guard[1] * k_sigma``: the gap
   between an arm and the torso, which a closing fills) -- hysteresis, as in Canny's edge thresholds. Then the
   largest 8-connected blob (``largest_blob``).

Two additions for real rooms (not in the paper):

- :meth:`BackgroundModel.fit_robust`: a background from frames in which people move about (a recording
  where nobody left the room): the per-pixel median is the mean and 1.4826 x the median absolute deviation
  the standard deviation, both robust to a person covering a pixel in less than half of the frames
  (someone who stands still longer becomes background, which is what a static blob should become).
- ``gain`` (per-frame lighting): before the comparison each frame is divided by its gain with respect
  to the background, the median over a grid of pixels (every 4th row and column, where the background
  is brighter than 16) of ``frame / background`` -- per channel for colour frames (a white-balance shift).
  The median ignores the people as long as they cover less than half of the grid. A plate shot in the
  morning and a recording in the afternoon, or a camera's auto-exposure, then no longer make the whole
  frame foreground.

Colour frames are BGR (``cv2.imread`` order) and are converted with ``cv2.cvtColor`` for the
graylevel statistics and the NCC.

Speed (issue 24: at most 1.5x OpenCV's MOG2 at the same resolution). Steps 1-2 run on the whole frame;
steps 3-5 on the frame's region of interest only: the candidates' bounding box grown by a margin that
keeps every later value what whole-frame processing gives (``BackgroundModel._roi_margin``). Inside it
the NCC is computed at the candidates only, from exact integer window sums in a compiled kernel
(:mod:`.ncc`, :mod:`.ncc_kernel`); the colour test runs
on the candidates that are not NCC seeds and fall within per-channel uint8 bounds every shadow-like
pixel meets (one ``cv2.inRange``); the edge rule reuses the candidates' squared colour differences;
the gain's division and the colour candidates are one compiled pass over the frame
(:mod:`.colour_kernels`, OpenCV's arithmetic bit for bit), which :meth:`BackgroundModel.candidates` also gives on its
own: it changes nothing in the model, so another thread may run it on the next frames (:class:`Candidates`, handed
to :meth:`BackgroundModel.segment`, which computes them again if the statistics changed since). The masks equal those of the former
whole-frame pipeline (``tests/segment/test_region_of_interest.py``). Measured with
``benchmarks/segmentation.py``'s ``--quick`` sizes, the former and this pipeline alternating in one
process (2 rounds, a shared 2-core machine at load 3-4; CPU time per frame, fastest of 3 passes, over
MOG2's at the same resolution): 320x240 2.60 / 2.64x before, 1.17 / 1.22x after (2.3 -> 1.0-1.1 ms per
frame); 1920x1080 at full size 3.98 / 4.14x before, 1.40 / 1.33x after (91-97 -> 30-32 ms); the working
size 360x202, resize and scaling back included, 1.61 / 1.66x before, 1.23 / 1.19x after; the
subtractions alone on frames shrunk beforehand 3.35 / 3.52x before, 1.76 / 1.67x after (the gain's
division and median, which MOG2 does not do, are about a tenth of ours there).

Defaults were measured on ``data/smoke/frames`` (Blender Cycles renders with floor shadows, 32
views; ``python -m silpose.app.segment_quality``): mean IoU against the true masks 0.662 with
the paper's graylevel rules and the former cleanup (median 5, open 3, close 7), see
``BackgroundModel``'s parameters for the measured effect of each change.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import cv2
import numpy as np

from . import cleanup
from .validate import SegmentError, as_frame_stack, as_single_frame, frame_size_text, to_gray
from .chroma import seeded_components, shadow_like
from .ncc import MAX_NCC_WINDOW, background_window_stats, shadow_mask

STAGES = ("candidates", "shadow_rejected", "edges", "median", "morphology", "final")
"""Names of the masks returned with ``return_stages=True``, in pipeline order."""

_SUM3 = np.ones((1, 3), np.float32)  # cv2.transform matrix: sum of the 3 channels
_CROSS3 = np.ones((3, 3), np.uint8)  # 8-neighbourhood of the edge rule
_BATCH_CHUNK = 64  # frames per vectorised chunk in segment_batch (bounds the temporaries)
#: frames per uint32 partial sum of squares in partial_fit (65,000 x 255^2 < 2^32)
SUM_FRAMES = 65_000
_GAIN_STEP = 4  # every 4th row and column are the pixels the gain is measured on
_GAIN_MIN_LEVEL = 16.0  # graylevels: darker background pixels say little about the gain


@dataclass(frozen=True)
class Candidates:
    """A colour frame's whole-frame steps (the gain's division and step 2), as :meth:`BackgroundModel.candidates`
    gives them -- possibly in another thread, while the model segments earlier frames: the frame divided by its gain
    ``divided`` (H, W, 3) uint8, the candidates ``mask`` (H, W) bool, the squared colour differences ``sq`` (H, W)
    float32 (None when the edge rule is off) and the normalised ``score`` (H, W) float32, computed against the
    model's statistics of ``version`` (:attr:`BackgroundModel.version`; the model ignores them once its statistics
    changed since)."""

    divided: np.ndarray
    mask: np.ndarray
    sq: np.ndarray | None
    score: np.ndarray
    version: int


def add_sums(frames: np.ndarray, s1: np.ndarray, s2: np.ndarray) -> None:
    """Add the per-pixel sums of ``frames`` (N, H, W[, C]) uint8 and of their squares to the int64 running sums
    ``s1``, ``s2`` (H, W[, C]), exactly: uint32 partial sums over at most :data:`SUM_FRAMES` frames (a square is
    at most 255^2 = 65025, so 65,000 of them fit in 32 bits), each square taken in uint16. About 30x faster than
    int64 copies of the frames and an int64 ``einsum`` (0.02 s instead of 0.64 s for 20 692x522 colour frames)."""
    for start in range(0, frames.shape[0], SUM_FRAMES):
        chunk = frames[start : start + SUM_FRAMES]
        s1 += chunk.sum(axis=0, dtype=np.uint32)
        acc = np.zeros(frames.shape[1:], np.uint32)
        sq = np.empty(frames.shape[1:], np.uint16)
        for f in chunk:
            np.multiply(f, f, out=sq, dtype=np.uint16)
            acc += sq
        s2 += acc


def _outer_index(j: np.ndarray, width: int, outer_width: int, row0: int, col0: int) -> np.ndarray:
    """Flat indices ``j`` (n,) into a rectangle ``width`` pixels wide whose top-left pixel is (``row0``,
    ``col0``) of an image ``outer_width`` wide -> the same pixels' flat indices into that image (n,)."""
    return j + (j // width) * (outer_width - width) + (row0 * outer_width + col0)


def _median_rows(x: np.ndarray) -> np.ndarray:
    """``np.median(x, axis=-1)`` of float32 rows (..., n), n >= 1, without NaN: the same values (the mean of the
    two middle ones for even n, summed in float32), without np.median's generic machinery (half its time on the
    few thousand gain ratios of a frame)."""
    n = x.shape[-1]
    k = n // 2
    if n % 2:
        return np.partition(x, k, axis=-1)[..., k]
    part = np.partition(x, (k - 1, k), axis=-1)
    return (part[..., k - 1] + part[..., k]) / np.float32(2)


class BackgroundModel:
    """Per-pixel Gaussian background model with NCC shadow rejection (paper section 6).

    Parameters
    ----------
    k_sigma : float, default 4.0
        A pixel is a candidate when ``|f - mean| > k_sigma * max(std, min_std)`` (graylevels), or
        for colour frames when the RMS over channels of ``(f_c - mean_c) / max(std_c, min_std)``
        exceeds it. The paper uses 3; rendered and real edges are blurred over 1-2 pixels, and at
        3 sigma the faintly mixed pixels outside the person pass, fattening the silhouette by
        about a pixel (on ``data/smoke/frames``, with colour: mean IoU 0.903 at 3 with median 3 /
        open 1 / close 3, 0.913 at 4 with the default cleanup).
    colour : bool, default True
        With colour background frames, also learn per-channel means and standard deviations and
        use them on colour frames (candidates above, and the colour shadow rule ``chroma_max``).
        Graylevel frames, or ``colour=False``, give the paper's graylevel pipeline. Background
        chunks must then all be colour or all graylevel.
    min_std : float, default 2.0
        Floor on the per-pixel standard deviation, in graylevels (0-255). Pixels that never
        changed in the background frames (saturated, or too few frames) would otherwise flag
        any one-level change; 2 graylevels is below typical camera noise.
    ncc_window : int, default 7
        Odd side, in pixels, of the square window of the local normalised correlation.
    ncc_threshold : float or None, default 0.9
        Candidates whose window correlates with the background above this (and darkened, see
        ``shadow_ratio``) are shadows and removed. ``None`` disables shadow rejection (plain
        ``k_sigma`` differencing).
    shadow_ratio : (float, float), default (0.25, 1.0)
        Bounds on the local brightness ratio ``E_W[frame] / E_W[background]`` for a shadow.
    min_texture : float, default 2.0
        Graylevels; windows whose background standard deviation is below this have nothing to
        correlate (NCC is set to 0), so candidates there are never called shadows.
    ncc_support : {"candidates", "window"}, default "candidates"
        Pixels of the window the correlation runs over: the candidate pixels only (the paper's
        "normalized correlation with other candidate pixels in a small neighborhood"), or all of
        them. Over candidates a shadow is rejected up to its edge; over full windows a rim of
        about ``ncc_window // 2`` pixels survives along the shadow's border.
    min_support : float, default 0.25
        With ``ncc_support="candidates"``: minimum fraction of the window that must be candidates
        for the correlation to count (fewer samples give meaningless correlations).
    chroma_max : float or None, default 6.0
        Graylevels. Colour frames only: a candidate whose colour is the background mean colour
        scaled by ``alpha`` in ``shadow_ratio`` (chromaticity distortion ``|f - alpha m| <=
        chroma_max``) is a shadow when it is 8-connected, through such pixels, to an
        NCC-accepted shadow pixel (:mod:`.chroma`). About twice the chromaticity distortion camera
        noise of 2 graylevels per channel gives. None disables the rule. Measured on
        ``data/smoke/frames``: false-positive pixels outside the truth (grown 2 px) go from
        26,292 (NCC only, colour candidates) to 377, mean IoU from 0.710 to 0.913.
    noise_correction : bool, default True
        Divide the NCC by the ceiling that camera noise puts on it (noise variance = the
        per-pixel background variance ``std_**2``; gain capped at sqrt(2)), see :mod:`.ncc`.
        Without it, deep shadows on a noisy camera correlate below ``ncc_threshold`` and survive.
    median_size : int, default 3
        Odd side of the median filter in pixels; <= 1 disables it.
    open_size, close_size : int, default 3 and 5
        Sides of the elliptical structuring elements of the opening and closing; <= 1 disables.
        Arms are 4-6 px wide at 320x240: a 5x5 median or 7x7 closing rounds hands and fills the
        gaps between limbs (mean IoU 0.913 with 3 / 3 / 5 vs 0.898 with the former 5 / 3 / 7 on
        ``data/smoke/frames``).
    cleanup_guard : (float, float) or None, default (2.0, 0.5)
        (strong, weak), in multiples of ``k_sigma`` (the candidates' normalised difference: graylevel
        ``|f - mean| / max(std, min_std)``, or its RMS over the channels of colour frames): the clean-up
        keeps every pixel the earlier steps kept whose difference exceeds ``strong * k_sigma``, and adds
        none whose difference is below ``weak * k_sigma`` (module docstring, step 5). None: the clean-up
        alone. Measured with the default clean-up sizes at 320x240 (mean IoU against the true masks, the
        synthetic scene of :mod:`.synthetic`, 200 frames / ``data/smoke/frames``, 32 Cycles views):
        None 0.9867 / 0.9344, (2, 0.5) 0.9977 / 0.9403 (MOG2 on the same frames: 0.9970 / 0.8891); over 8
        other seeds of the synthetic scene (40 frames each) 0.9844 -> 0.9974, MOG2 0.9978 (ahead on 2).
    largest_blob : bool, default True
        Keep only the largest 8-connected blob.
    gain : bool, default False
        Divide each frame by its gain with respect to the background before comparing (module
        docstring): a lighting change between the background and the frames. Off: the paper's rule.
    edge_coverage : float or None, default 0.5
        Mixed edge pixels (module docstring, step 4): an edge pixel is dropped when its difference
        from the background is below this fraction of its interior neighbours' largest; 0.5 puts the
        edge where the person covers half a pixel (a true mask's edge). None: off. Measured on the
        synthetic scenes of :mod:`.synthetic` (1920x1080, 6 frames, mean IoU against the true masks
        shrunk to the same size): 0.929 -> 0.971 at 360x202 (a person 160 px tall), 0.953 -> 0.983 at
        540x304 (``benchmarks/segmentation.py``).

    Parameters are read by :meth:`fit` / :meth:`partial_fit` (sklearn convention): changing one
    afterwards takes effect at the next fit.

    Attributes
    ----------
    n_frames_seen_ : int
        Background frames accumulated so far.
    frame_shape_ : (int, int)
        (H, W) of the background frames.
    mean_ : array (H, W) float64
        Per-pixel mean graylevel (available once ``n_frames_seen_ >= 2``).
    std_ : array (H, W) float64
        Per-pixel standard deviation of the graylevel (ddof = 0, before the ``min_std`` floor).
    colour_mean_, colour_std_ : array (H, W, 3) float64 or None
        Per-pixel, per-channel (BGR) mean and standard deviation when ``colour`` and the
        background frames are colour; else None.
    """

    def __init__(
        self,
        k_sigma: float = 4.0,
        colour: bool = True,
        min_std: float = 2.0,
        ncc_window: int = 7,
        ncc_threshold: float | None = 0.9,
        shadow_ratio: tuple[float, float] = (0.25, 1.0),
        min_texture: float = 2.0,
        ncc_support: str = "candidates",
        min_support: float = 0.25,
        chroma_max: float | None = 6.0,
        noise_correction: bool = True,
        median_size: int = 3,
        open_size: int = 3,
        close_size: int = 5,
        largest_blob: bool = True,
        gain: bool = False,
        edge_coverage: float | None = 0.5,
        cleanup_guard: tuple[float, float] | None = (2.0, 0.5),
    ):
        self.k_sigma = k_sigma
        self.colour = colour
        self.chroma_max = chroma_max
        self.min_std = min_std
        self.ncc_window = ncc_window
        self.ncc_threshold = ncc_threshold
        self.shadow_ratio = shadow_ratio
        self.min_texture = min_texture
        self.ncc_support = ncc_support
        self.min_support = min_support
        self.noise_correction = noise_correction
        self.median_size = median_size
        self.open_size = open_size
        self.close_size = close_size
        self.largest_blob = largest_blob
        self.gain = gain
        self.edge_coverage = edge_coverage
        self.cleanup_guard = cleanup_guard
        self._stats_lock = threading.Lock()  # the statistics' derived arrays change under it (_prepare)
        self._version = 0

    # ------------------------------------------------------------------ fitting
    def fit(self, frames) -> BackgroundModel:
        """Learn the background from frames (N, H, W) or (N, H, W, 3) uint8, N >= 2. Returns self."""
        self._check_params()
        stack = as_frame_stack(frames, "frames")
        if stack.shape[0] < 2:
            raise SegmentError(f"frames: a background needs at least 2 frames, got {stack.shape[0]}")
        for attr in ("n_frames_seen_", "frame_shape_", "mean_", "std_", "_s1", "_s2", "_c1", "_c2",
                     "colour_mean_", "colour_std_"):
            self.__dict__.pop(attr, None)
        return self.partial_fit(stack)

    def partial_fit(self, frames, finalise: bool = True) -> BackgroundModel:
        """Add background frames (N, H, W) or (N, H, W, 3) uint8 to the running sums. Returns self.

        The statistics (``mean_``, ``std_``) and the segmentation's thresholds are updated after each call once 2
        frames or more have been seen; frames must all have the size of the first chunk. ``finalise=False``: more
        chunks follow at once, so only the sums grow (the statistics of a 922x519 colour background cost as much
        as adding 40 frames); the model cannot segment until a call with ``finalise=True``. The sums are exact, so
        the model is the same however the frames were split.
        """
        self._check_params()
        stack = as_frame_stack(frames, "frames")
        gray = to_gray(stack)
        is_colour = stack.ndim == 4
        if hasattr(self, "n_frames_seen_") and self._s1 is None:
            raise SegmentError("partial_fit: this background came from fit_robust (medians); call fit or fit_robust again")
        if not hasattr(self, "n_frames_seen_"):
            self.frame_shape_ = gray.shape[1:]
            self.n_frames_seen_ = 0
            self._s1 = np.zeros(self.frame_shape_, np.int64)
            self._s2 = np.zeros(self.frame_shape_, np.int64)
            track = bool(self.colour) and is_colour
            self._c1 = np.zeros((*self.frame_shape_, 3), np.int64) if track else None
            self._c2 = np.zeros((*self.frame_shape_, 3), np.int64) if track else None
        elif gray.shape[1:] != self.frame_shape_:
            raise SegmentError(
                f"frames: frame size {frame_size_text(gray.shape[1:])} differs from the background's "
                f"{frame_size_text(self.frame_shape_)}"
            )
        elif self.colour and (self._c1 is not None) != is_colour:
            first = "colour" if self._c1 is not None else "graylevel"
            raise SegmentError(
                f"frames: {'colour' if is_colour else 'graylevel'} frames after {first} ones; with colour=True "
                f"the background must be all colour or all graylevel"
            )
        if self._c1 is not None:
            add_sums(stack, self._c1, self._c2)
        add_sums(gray, self._s1, self._s2)
        self.n_frames_seen_ += gray.shape[0]
        self._stale = not finalise
        if finalise and self.n_frames_seen_ >= 2:
            self._finalise()
        return self

    def fit_robust(self, frames) -> BackgroundModel:
        """Learn the background from frames (N, H, W) or (N, H, W, 3) uint8, N >= 3, in which people may appear:
        per-pixel median and 1.4826 x median absolute deviation (module docstring). Returns self; the model
        cannot be extended with :meth:`partial_fit` afterwards."""
        self._check_params()
        stack = as_frame_stack(frames, "frames")
        if stack.shape[0] < 3:
            raise SegmentError(f"frames: a robust background needs at least 3 frames, got {stack.shape[0]}")
        gray = to_gray(stack)
        self.frame_shape_ = gray.shape[1:]
        self.n_frames_seen_ = int(stack.shape[0])
        self._s1 = self._s2 = None  # no running sums: partial_fit refuses
        self._stale = False
        self._c1 = self._c2 = None

        def med_mad(x):
            med = np.median(x, axis=0)
            return med, 1.4826 * np.median(np.abs(x - med[None].astype(np.float32)), axis=0)

        self.mean_, self.std_ = (a.astype(np.float64) for a in med_mad(gray.astype(np.float32)))
        colour = None
        if self.colour and stack.ndim == 4:
            colour = tuple(a.astype(np.float64) for a in med_mad(stack.astype(np.float32)))
        self._prepare(colour)
        return self

    def absorb(self, frame, where) -> BackgroundModel:
        """Make the pixels ``where`` ((H, W) bool) background, with the values they have in ``frame`` ((H, W) or
        (H, W, 3) uint8, the background's kind): an object that was not in the background frames and stays
        (a moved chair, someone standing still at the back). The standard deviations are kept. A later
        :meth:`partial_fit` recomputes the statistics from its sums and forgets what was absorbed. Returns self."""
        self._check_fitted()
        arr = as_single_frame(frame, "frame")
        self._check_shape(arr.shape[:2], "frame")
        where = np.asarray(where, bool)
        self._check_shape(where.shape, "where")
        if not where.any():
            return self
        gray = to_gray(arr[None])[0]
        self.mean_ = self.mean_.copy()
        self.mean_[where] = gray[where]
        colour = None
        if self.colour_mean_ is not None:
            cm = self.colour_mean_.copy()
            if arr.ndim == 3:
                cm[where] = arr[where]
            else:
                cm[where] = gray[where][:, None]
            colour = (cm, self.colour_std_)
        self._prepare(colour)
        return self

    def _finalise(self) -> None:
        n = self.n_frames_seen_
        # Exact integer numerator: var = (N S2 - S1^2) / N^2 (no cancellation, no float drift).
        self.mean_ = self._s1 / n
        self.std_ = np.sqrt((n * self._s2 - self._s1 * self._s1) / float(n * n))
        colour = None
        if self._c1 is not None:
            colour = (self._c1 / n, np.sqrt((n * self._c2 - self._c1 * self._c1) / float(n * n)))
        self._prepare(colour)

    def _prepare(self, colour: tuple[np.ndarray, np.ndarray] | None) -> None:
        """Thresholds and window statistics from ``mean_``, ``std_`` and the colour (mean, std) or None (:meth:`_derive`),
        then a new :attr:`version`, under the statistics' lock: :meth:`candidates` computed in another thread
        meanwhile never read half of them, and those computed before are out of date."""
        with self._stats_lock:
            self._derive(colour)
            self._version += 1

    def _derive(self, colour: tuple[np.ndarray, np.ndarray] | None) -> None:
        thr = self.k_sigma * np.maximum(self.std_, self.min_std)
        # Integer bounds, clipped to int16: |f - mean| > thr  <=>  f > floor(mean + thr) or f < ceil(mean - thr).
        self._upper = np.clip(np.floor(self.mean_ + thr), -1, 256).astype(np.int16)
        self._lower = np.clip(np.ceil(self.mean_ - thr), -1, 256).astype(np.int16)
        self._guard = None
        if self.cleanup_guard is not None:
            # the clean-up's guard (step 5) in the same integer form: strong |f - mean| > S thr, weak |f - mean| < W thr
            strong, weak = (float(v) for v in self.cleanup_guard)
            self._guard = tuple(np.clip(b, -1, 256).astype(np.int16) for b in (
                np.floor(self.mean_ + strong * thr), np.ceil(self.mean_ - strong * thr),
                np.ceil(self.mean_ + weak * thr) - 1, np.floor(self.mean_ - weak * thr) + 1))
        self.colour_mean_ = self.colour_std_ = None
        self._inv_var = None
        if colour is not None:
            self.colour_mean_, self.colour_std_ = colour
            # Colour candidates: sum_c (f_c - mean_c)^2 / max(std_c, min_std)^2 > 3 k^2.
            self._cmean32 = self.colour_mean_.astype(np.float32)
            self._cmean_planes = np.ascontiguousarray(self.colour_mean_.reshape(-1, 3).T)  # (3, H W) channel planes
            if self.chroma_max is not None:
                # A shadow-like pixel has f_c = alpha m_c + r_c with alpha in shadow_ratio and |r_c| <= cd <= chroma_max,
                # so lo m_c - chroma_max <= f_c <= hi m_c + chroma_max in every channel: uint8 bounds (one graylevel
                # looser than that, against rounding) that rule most other pixels out in one cv2.inRange.
                lo, hi = self.shadow_ratio
                cm = self.colour_mean_
                self._like_lo = np.clip(np.ceil(lo * cm - self.chroma_max) - 1, 0, 255).astype(np.uint8)
                self._like_hi = np.clip(np.floor(hi * cm + self.chroma_max) + 1, 0, 255).astype(np.uint8)
            self._inv_var = (1.0 / np.maximum(np.maximum(self.colour_std_, self.min_std), 1e-6) ** 2).astype(np.float32)
            h, w = self.colour_mean_.shape[:2]
            self._cmean_rows, self._inv_var_rows = self._cmean32.reshape(h, 3 * w), self._inv_var.reshape(h, 3 * w)
            self._cthr = np.float32(3.0 * self.k_sigma**2)
            if self.cleanup_guard is not None:  # the guard's squared thresholds on the same score
                self._cguard = tuple(np.float32(3.0 * (float(v) * self.k_sigma) ** 2) for v in self.cleanup_guard)
        self._mean32 = self.mean_.astype(np.float32)
        self._bg = None
        if self.ncc_threshold is not None:
            noise = self.std_**2 if self.noise_correction else None
            self._bg = background_window_stats(self.mean_, self.ncc_window, self.min_texture, noise)
        ref = self.colour_mean_ if self.colour_mean_ is not None else self.mean_
        grid = ref[::_GAIN_STEP, ::_GAIN_STEP]
        self._gain_ref = grid.astype(np.float32)
        self._gain_ok = (grid > _GAIN_MIN_LEVEL) if grid.ndim == 2 else (grid > _GAIN_MIN_LEVEL).all(axis=-1)
        self._gain_ref_ok = self._gain_ref[self._gain_ok]  # (N,) or (N, 3): frame_gain's denominators
        self._gain_ref_rows = np.ascontiguousarray(self._gain_ref_ok.T)  # (N,) or (3, N)
        h, w = self.mean_.shape
        grid_px = np.arange(0, h, _GAIN_STEP)[:, None] * w + np.arange(0, w, _GAIN_STEP)[None, :]
        self._gain_px = grid_px[self._gain_ok]  # (N,) flat pixel indices of those grid points

    def _check_params(self) -> None:
        def fail(name, value, rule):
            raise SegmentError(f"{name}: {rule}, got {value!r}")

        if not (np.isscalar(self.k_sigma) and self.k_sigma > 0):
            fail("k_sigma", self.k_sigma, "must be a positive number")
        if not (np.isscalar(self.min_std) and self.min_std >= 0):
            fail("min_std", self.min_std, "must be a number >= 0 (graylevels)")
        w = self.ncc_window
        if not (isinstance(w, (int, np.integer)) and 3 <= w <= MAX_NCC_WINDOW and w % 2 == 1):
            fail("ncc_window", w, f"must be an odd integer in [3, {MAX_NCC_WINDOW}]")
        t = self.ncc_threshold
        if t is not None and not (np.isscalar(t) and -1.0 <= t < 1.0):
            fail("ncc_threshold", t, "must be None or a number in [-1, 1)")
        r = self.shadow_ratio
        if not (len(r) == 2 and 0 <= r[0] < r[1]):
            fail("shadow_ratio", r, "must be (low, high) with 0 <= low < high")
        if not (np.isscalar(self.min_texture) and self.min_texture >= 0):
            fail("min_texture", self.min_texture, "must be a number >= 0 (graylevels)")
        if self.ncc_support not in ("candidates", "window"):
            fail("ncc_support", self.ncc_support, 'must be "candidates" or "window"')
        if not (np.isscalar(self.min_support) and 0 <= self.min_support <= 1):
            fail("min_support", self.min_support, "must be a number in [0, 1]")
        if not isinstance(self.colour, (bool, np.bool_)):
            fail("colour", self.colour, "must be True or False")
        c = self.chroma_max
        if c is not None and not (np.isscalar(c) and c >= 0):
            fail("chroma_max", c, "must be None or a number >= 0 (graylevels)")
        if not isinstance(self.noise_correction, (bool, np.bool_)):
            fail("noise_correction", self.noise_correction, "must be True or False")
        if not isinstance(self.largest_blob, (bool, np.bool_)):
            fail("largest_blob", self.largest_blob, "must be True or False")
        if not isinstance(self.gain, (bool, np.bool_)):
            fail("gain", self.gain, "must be True or False")
        e = self.edge_coverage
        if e is not None and not (np.isscalar(e) and 0 < e < 1):
            fail("edge_coverage", e, "must be None or a number in (0, 1)")
        g = self.cleanup_guard
        if g is not None and not (len(g) == 2 and all(np.isscalar(v) for v in g) and 0 <= g[1] <= 1 <= g[0]):
            fail("cleanup_guard", g, "must be None or (strong, weak) with 0 <= weak <= 1 <= strong")
        m = self.median_size
        if not (isinstance(m, (int, np.integer)) and (m <= 1 or m % 2 == 1)):
            fail("median_size", m, "must be an odd integer (or <= 1 to disable)")
        for name in ("open_size", "close_size"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)):
                fail(name, v, "must be an integer (<= 1 disables)")

    # ------------------------------------------------------------------ segmentation
    def _check_fitted(self) -> None:
        if not hasattr(self, "n_frames_seen_"):
            raise SegmentError("BackgroundModel: not fitted; call fit(background_frames) before segmenting")
        if getattr(self, "_stale", False):
            raise SegmentError("BackgroundModel: frames were added with partial_fit(finalise=False); finish with "
                               "partial_fit(frames) before segmenting")
        if self.n_frames_seen_ < 2:
            raise SegmentError(
                f"BackgroundModel: the background has {self.n_frames_seen_} frame; at least 2 are needed"
            )

    def _check_shape(self, shape, name: str) -> None:
        if tuple(shape) != tuple(self.frame_shape_):
            raise SegmentError(
                f"{name}: frame size {frame_size_text(shape)} differs from the background's "
                f"{frame_size_text(self.frame_shape_)}"
            )

    @property
    def version(self) -> int:
        """Counts the changes of the model's statistics (a fit, an absorb): :class:`Candidates` carry the one they
        were computed against."""
        self._check_fitted()
        return self._version

    def candidates(self, frame) -> Candidates | None:
        """The whole-frame steps of segmenting one colour frame (H, W, 3) uint8 (:class:`Candidates`), for
        :meth:`segment` to finish: they read the model and change nothing, so another thread may compute them for
        the next frames while this one segments (the recordings pipeline's reader threads). None for a graylevel
        model or frame (they have no such step)."""
        self._check_fitted()
        arr = as_single_frame(frame, "frame")
        self._check_shape(arr.shape[:2], "frame")
        with self._stats_lock:  # the statistics of one version throughout
            if arr.ndim != 3 or self._inv_var is None:
                return None
            divided = np.empty_like(arr)
            return Candidates(divided, *self._colour_candidates(arr, divided), self._version)

    def segment(self, frame, return_stages: bool = False, candidates: Candidates | None = None):
        """Foreground mask of one frame (streaming API).

        Parameters
        ----------
        frame : array (H, W) or (H, W, 3) uint8, same size as the background
        return_stages : bool
            Also return the intermediate masks.
        candidates : Candidates or None
            :meth:`candidates` of this frame, computed beforehand (elsewhere); recomputed here when the model's
            statistics changed since (:attr:`version`). The mask is the same either way.

        Returns
        -------
        array (H, W) bool, or with ``return_stages`` a dict {stage name: (H, W) bool} over
        :data:`STAGES` (``"final"`` is the mask).
        """
        self._check_fitted()
        arr = as_single_frame(frame, "frame")
        self._check_shape(arr.shape[:2], "frame")
        if candidates is not None and (candidates.version != self._version or arr.ndim != 3
                                       or candidates.mask.shape != arr.shape[:2]):
            candidates = None  # out of date (or not this model's kind): computed again below
        stages = self._segment(arr[None], return_stages, None if candidates is None else [candidates])
        if return_stages:
            return {k: v[0] for k, v in stages.items()}
        return stages["final"][0]

    def segment_batch(self, frames, return_stages: bool = False):
        """Foreground masks of a stack of frames (batch API; equal to :meth:`segment` frame by frame).

        Parameters
        ----------
        frames : array (N, H, W) or (N, H, W, 3) uint8
        return_stages : bool

        Returns
        -------
        array (N, H, W) bool, or a dict {stage name: (N, H, W) bool}.
        """
        self._check_fitted()
        stack = as_frame_stack(frames, "frames")
        self._check_shape(stack.shape[1:3], "frames")
        out = {k: np.empty(stack.shape[:3], bool) for k in (STAGES if return_stages else ("final",))}
        for start in range(0, stack.shape[0], _BATCH_CHUNK):
            chunk = self._segment(stack[start : start + _BATCH_CHUNK], return_stages)
            for k in out:
                out[k][start : start + _BATCH_CHUNK] = chunk[k]
        return out if return_stages else out["final"]

    def frame_gain(self, frame) -> np.ndarray:
        """The gain of one frame (H, W) or (H, W, 3) uint8 with respect to the background: a scalar for
        graylevel frames, (3,) per channel for colour ones when the background is colour (module docstring)."""
        self._check_fitted()
        f = np.asarray(frame)[::_GAIN_STEP, ::_GAIN_STEP]
        ref = self._gain_ref
        if f.ndim == 3 and ref.ndim == 2:
            f = f.astype(np.float32) @ np.array([0.114, 0.587, 0.299], np.float32)  # BGR -> grey, as cv2.cvtColor
        elif f.ndim == 2 and ref.ndim == 3:
            ref = ref @ np.array([0.114, 0.587, 0.299], np.float32)
        else:  # the frame of the background's kind: the grid's reference values and pixels taken once (_prepare)
            frame = np.asarray(frame)
            px = np.take(frame.reshape(-1, *frame.shape[2:]), self._gain_px, axis=0)  # (N,) or (N, 3)
            # per channel, over contiguous rows: the same medians as over the (N, C) columns, in a third of the time
            ratio = np.ascontiguousarray(px.T, dtype=np.float32) / self._gain_ref_rows
            if not ratio.shape[-1]:
                return np.ones(ratio.shape[:-1], np.float32)
            return _median_rows(ratio)
        ratio = f[self._gain_ok].astype(np.float32) / ref[self._gain_ok]
        if not len(ratio):
            return np.ones(ratio.shape[1:], np.float32)
        return np.median(ratio, axis=0).astype(np.float32)

    def _normalise_gain(self, stack: np.ndarray) -> np.ndarray:
        """Each frame divided by its gain (rounded, saturating): ``cv2.convertScaleAbs`` by the inverse gain, channel
        by channel for colour frames (split, scaled, merged: 6x faster than ``cv2.transform`` by the diagonal
        matrix of the float32 inverse gains, 2.5x a 3-channel ``cv2.LUT``, and the same values, tested)."""
        out = np.empty_like(stack)
        for i, f in enumerate(stack):
            g = self.frame_gain(f)
            if f.ndim == 3 and np.ndim(g) == 1:
                inv = (1.0 / np.maximum(g, 1e-3)).astype(np.float32)
                cv2.merge([cv2.convertScaleAbs(c, alpha=float(a)) for c, a in zip(cv2.split(f), inv)], dst=out[i])
            else:
                cv2.convertScaleAbs(f, dst=out[i], alpha=float(1.0 / max(float(g), 1e-3)))
        return out

    def _segment(self, stack: np.ndarray, stages: bool = False,
                 given: list[Candidates] | None = None) -> dict[str, np.ndarray]:
        """Pipeline on validated frames (N, H, W) or (N, H, W, 3) uint8 -> {stage: (N, H, W) bool}: every stage
        of :data:`STAGES` with ``stages``, else only ``"final"``; ``given``: the frames' :class:`Candidates`,
        up to date (colour), instead of computing them.

        After the candidates, each frame is processed on its region of interest only: the candidates'
        bounding box grown by :meth:`_roi_margin` pixels (clipped to the frame). Every later step gives there
        the values it gives on the whole frame, and nothing outside it (see :meth:`_roi_margin`)."""
        use_colour = stack.ndim == 4 and self._inv_var is not None
        if use_colour and given is not None:
            scored = [(c.mask, c.sq, c.score) for c in given]
            stack = given[0].divided[None] if len(given) == 1 else np.stack([c.divided for c in given])
        elif use_colour:  # each frame's gain division and candidates in one compiled pass (_colour_candidates)
            divided = np.empty_like(stack)
            scored = [self._colour_candidates(f, divided[i]) for i, f in enumerate(stack)]
            stack = divided
        elif self.gain:
            stack = self._normalise_gain(stack)
        if not use_colour:
            # Graylevel, vectorised over the stack: |f - mean| > k sigma, for integer f exactly
            # f > floor(mean + k sigma) or f < ceil(mean - k sigma) (bounds precomputed in _finalise).
            gray = to_gray(stack)
            cand_all = (gray > self._upper) | (gray < self._lower)
        names = STAGES if stages else ("final",)
        out = {k: np.zeros(stack.shape[:3], bool) for k in names}
        h, w = stack.shape[1:3]
        margin = self._roi_margin()
        for i in range(stack.shape[0]):
            cand, sq, score = scored[i] if use_colour else (cand_all[i], None, None)
            if stages:
                out["candidates"][i] = cand
            x, y, bw, bh = cv2.boundingRect(cand.view(np.uint8))
            if bw == 0:
                continue  # no candidate: every later stage is empty
            roi = (slice(max(y - margin, 0), min(y + bh + margin, h)), slice(max(x - margin, 0), min(x + bw + margin, w)))
            if use_colour:  # the same graylevels as to_gray's, pixel by pixel
                whole, region_gray = stack[i], cv2.cvtColor(stack[i][roi], cv2.COLOR_BGR2GRAY)
            else:
                whole, region_gray = gray[i], gray[i][roi]
            guard = None
            if self.cleanup_guard is not None:
                guard = self._guard_masks(region_gray if score is None else score[roi], roi)
            masks = self._segment_roi(whole, region_gray, np.ascontiguousarray(cand[roi]), roi, stages, sq, guard)
            for k, m in masks.items():
                out[k][i][roi] = m
        return out

    def _colour_candidates(self, frame: np.ndarray, out: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """One colour frame (H, W, 3) uint8 divided by its gain (``gain``; else copied) into ``out`` (H, W, 3) uint8,
        and its candidates (H, W) bool, the squared colour difference from the background mean
        ``sum_c (f_c - mean_c)^2`` (H, W) float32 that the edge rule uses (None when it is off), and the candidates'
        score ``sum_c (f_c - mean_c)^2 / std_c^2`` (H, W) float32 (above ``3 k_sigma^2``: a candidate) that the
        clean-up's guard reads, all of the divided frame: one compiled pass (:mod:`.colour_kernels`, the arithmetic
        of ``cv2.convertScaleAbs`` and of float32 ``cv2.subtract`` / ``multiply`` / ``transform``, bit for bit)."""
        from .colour_kernels import normalise_and_score  # numba: imported when the first colour frame is segmented

        h, w = frame.shape[:2]
        inv = np.ones(3, np.float32)
        if self.gain:
            inv = (1.0 / np.maximum(self.frame_gain(frame), 1e-3)).astype(np.float32)
        sq, score, cand = np.empty((h, w), np.float32), np.empty((h, w), np.float32), np.empty((h, w), bool)
        normalise_and_score(np.ascontiguousarray(frame).reshape(h, 3 * w), np.tile(inv, w), self._cmean_rows,
                            self._inv_var_rows, self._cthr, out.reshape(h, 3 * w), sq, score, cand)
        return cand, (sq if self.edge_coverage is not None else None), score

    def _guard_masks(self, region: np.ndarray, roi) -> tuple[np.ndarray, np.ndarray]:
        """The clean-up's guard on a region of interest ``roi`` (module docstring, step 5): (strong, weak) (h, w)
        uint8 masks 255/0 of the pixels whose difference from the background is above ``cleanup_guard[0]`` / below
        ``cleanup_guard[1]`` times the candidates' threshold. region: the region's colour score (h, w) float32
        (:meth:`_colour_candidates`) with a colour background, else its graylevels (h, w) uint8."""
        if region.dtype == np.float32:
            strong_thr, weak_thr = self._cguard
            return (cv2.compare(region, float(strong_thr), cv2.CMP_GT),
                    cv2.compare(region, float(weak_thr), cv2.CMP_LT))
        su, sl, wu, wl = (b[roi] for b in self._guard)
        g = region.astype(np.int16)
        strong = cv2.bitwise_or(cv2.compare(g, su, cv2.CMP_GT), cv2.compare(g, sl, cv2.CMP_LT))
        weak = cv2.bitwise_and(cv2.compare(g, wu, cv2.CMP_LE), cv2.compare(g, wl, cv2.CMP_GE))
        return strong, weak

    def _roi_margin(self) -> int:
        """Pixels the region of interest extends beyond the candidates' bounding box. Every pixel of a later stage
        that can be set lies inside it, and so does each window that decides one: the NCC's windows (radius
        ``r_n = ncc_window // 2``) around candidates, and the clean-up's. The median (radius ``r_m``) sets pixels
        up to ``r_m`` out and reads ``r_m`` further; the opening adds nothing beyond the median's, its erosion
        reads ``2 r_o`` further; the closing dilates by ``r_c`` and its erosion reads ``2 r_c`` beyond that. So
        a margin above ``max(r_n, 2 r_m, r_m + 2 r_o, r_m + 3 r_c)`` leaves a ring of unset pixels inside the
        region's edges wide enough that OpenCV's border rules there (replicated, or neutral for the morphology)
        see what the whole frame would show: zeros. One more pixel for the edge rule's 3x3 neighbourhoods."""
        r_n = self.ncc_window // 2
        r_m, r_o, r_c = (max(int(v), 1) // 2 for v in (self.median_size, self.open_size, self.close_size))
        return max(r_n, 2 * r_m, r_m + 2 * r_o, r_m + 3 * r_c) + 2

    def _segment_roi(self, whole, gray, cand, roi, stages: bool, sq=None, guard=None) -> dict[str, np.ndarray]:
        """Steps 3-5 on a frame's region of interest ``roi`` (slice, slice) -> {stage: (h, w) bool} (every stage
        after "candidates" with ``stages``, else "final"). whole: the whole frame (H, W, 3) colour with a colour
        background, else (H, W) graylevel, contiguous; gray (h, w) uint8 and cand (h, w) bool (contiguous): the
        region's graylevels and candidates; sq: the whole frame's squared colour differences or None (see
        :meth:`_colour_candidates`); guard: the region's (strong, weak) masks of the clean-up's guard
        (:meth:`_guard_masks`) or None."""
        out = {}
        kept = cand
        frame = whole[roi]
        if self._bg is not None:
            support = kept if self.ncc_support == "candidates" else None
            shadow = shadow_mask(gray, self._bg.crop(*roi), support, self.min_support, self.ncc_threshold,
                                 self.shadow_ratio, at=kept)
            if frame.ndim == 3 and self.chroma_max is not None and shadow.any():
                # grow_shadows, with the colour test at the candidates that are not seeds only, their colours taken
                # from the whole frame's contiguous pixel lists (a fancy index into the region is 4x slower)
                like = np.zeros(kept.shape, bool)
                maybe = cv2.inRange(frame, self._like_lo[roi], self._like_hi[roi]) > 0  # (see _prepare)
                j = np.flatnonzero(kept & ~shadow & maybe)
                px = _outer_index(j, kept.shape[1], whole.shape[1], roi[0].start, roi[1].start)
                flat, px3 = whole.reshape(-1), 3 * px
                colours = [np.take(flat, px3 + k) for k in range(3)]  # 1-D takes, channel by channel: fast
                means = [np.take(plane, px) for plane in self._cmean_planes]
                like.reshape(-1)[j] = shadow_like(colours, means, self.shadow_ratio, self.chroma_max, channel_axis=0)
                shadow = seeded_components(like, shadow)
            kept = kept & ~shadow
        if stages:
            out["shadow_rejected"] = kept
        if self.edge_coverage is not None:
            kept = self._trim_edges(frame, kept, roi, sq)
        before = kept.view(np.uint8) * np.uint8(255)
        m = cleanup.median(before, self.median_size)
        if stages:
            out["edges"], out["median"] = kept, m > 0
        m = cleanup.open_close(m, self.open_size, self.close_size)
        if guard is not None:  # what the filters changed against the evidence is undone (module docstring, step 5)
            m = cleanup.guard(before, m, *guard)
        if stages:
            out["morphology"] = m > 0
        if self.largest_blob:
            m = cleanup.largest_blob(m)
        out["final"] = m > 0
        return out

    def _trim_edges(self, frame: np.ndarray, kept: np.ndarray, roi=(slice(None), slice(None)), sq=None) -> np.ndarray:
        """Step 4 of the module docstring on one frame's region of interest ``roi`` ((h, w, 3) colour with a colour
        background, else (h, w) graylevel; gain-normalised) and its kept pixels (h, w) bool -> the kept pixels
        without the mixed edge pixels. Only the kept pixels' bounding box (grown by one) is computed. sq: the
        whole frame's squared colour differences when the candidates computed them (the same values), else None."""
        k8 = kept.view(np.uint8)
        x, y, w, h = cv2.boundingRect(k8)
        if w == 0:
            return kept
        H, W = kept.shape
        x0, y0, x1, y1 = max(x - 1, 0), max(y - 1, 0), min(x + w + 1, W), min(y + h + 1, H)
        sub = k8[y0:y1, x0:x1]
        interior = cv2.erode(sub, _CROSS3, borderType=cv2.BORDER_REPLICATE)  # all 8 neighbours kept
        if sq is not None:
            d = cv2.sqrt(sq[roi][y0:y1, x0:x1])
        elif frame.ndim == 3:
            mean = self._cmean32[roi][y0:y1, x0:x1]
            d = cv2.subtract(frame[y0:y1, x0:x1], mean, dtype=cv2.CV_32F)
            d = cv2.sqrt(cv2.transform(cv2.multiply(d, d), _SUM3))
        else:
            d = cv2.absdiff(frame[y0:y1, x0:x1].astype(np.float32), self._mean32[roi][y0:y1, x0:x1])
        ref = cv2.dilate(d * interior, _CROSS3)  # the largest interior neighbour's difference (0: none)
        drop = (sub > interior) & (d < np.float32(self.edge_coverage) * ref)
        if not drop.any():
            return kept
        out = kept.copy()
        out[y0:y1, x0:x1] &= ~drop
        return out
