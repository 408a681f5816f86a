"""The paper's background subtraction (section 6, after its reference [12]) as a fitted model.

1. Background statistics: per-pixel mean and standard deviation of the graylevel over N >= 2
   empty-scene frames, accumulated exactly in int64 sums (sum x, sum x^2) so long backgrounds
   (the paper uses 400 frames) can stream in chunks through :meth:`BackgroundModel.partial_fit`:
       mean = S1 / N,   var = (N S2 - S1^2) / N^2   (population variance, numpy's ddof=0).
2. Candidates: pixels whose graylevel is more than ``k_sigma`` standard deviations from the
   background mean, ``|f - mean| > k_sigma * max(std, min_std)``.
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
4. Median filter (``median_size``), morphological open (``open_size``) then close
   (``close_size``), and the largest 8-connected blob (``largest_blob``), see :mod:`.cleanup`.

Colour frames are BGR (``cv2.imread`` order) and are converted with ``cv2.cvtColor``.
"""

from __future__ import annotations

import numpy as np

from . import cleanup
from ._validate import SegmentError, as_frame_stack, as_single_frame, frame_size_text, to_gray
from .ncc import background_window_stats, shadow_mask

STAGES = ("candidates", "shadow_rejected", "median", "morphology", "final")
"""Names of the masks returned with ``return_stages=True``, in pipeline order."""

_BATCH_CHUNK = 64  # frames per vectorised chunk in partial_fit / segment_batch (bounds the temporaries)


class BackgroundModel:
    """Per-pixel Gaussian background model with NCC shadow rejection (paper section 6).

    Parameters
    ----------
    k_sigma : float, default 3.0
        A pixel is a candidate when ``|f - mean| > k_sigma * max(std, min_std)``.
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
    noise_correction : bool, default True
        Divide the NCC by the ceiling that camera noise puts on it (noise variance = the
        per-pixel background variance ``std_**2``; gain capped at sqrt(2)), see :mod:`.ncc`.
        Without it, deep shadows on a noisy camera correlate below ``ncc_threshold`` and survive.
    median_size : int, default 5
        Odd side of the median filter in pixels; <= 1 disables it.
    open_size, close_size : int, default 3 and 7
        Sides of the elliptical structuring elements of the opening and closing; <= 1 disables.
    largest_blob : bool, default True
        Keep only the largest 8-connected blob.

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
    """

    def __init__(
        self,
        k_sigma: float = 3.0,
        min_std: float = 2.0,
        ncc_window: int = 7,
        ncc_threshold: float | None = 0.9,
        shadow_ratio: tuple[float, float] = (0.25, 1.0),
        min_texture: float = 2.0,
        ncc_support: str = "candidates",
        min_support: float = 0.25,
        noise_correction: bool = True,
        median_size: int = 5,
        open_size: int = 3,
        close_size: int = 7,
        largest_blob: bool = True,
    ):
        self.k_sigma = k_sigma
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

    # ------------------------------------------------------------------ fitting
    def fit(self, frames) -> BackgroundModel:
        """Learn the background from frames (N, H, W) or (N, H, W, 3) uint8, N >= 2. Returns self."""
        self._check_params()
        stack = as_frame_stack(frames, "frames")
        if stack.shape[0] < 2:
            raise SegmentError(f"frames: a background needs at least 2 frames, got {stack.shape[0]}")
        for attr in ("n_frames_seen_", "frame_shape_", "mean_", "std_", "_s1", "_s2"):
            self.__dict__.pop(attr, None)
        return self.partial_fit(stack)

    def partial_fit(self, frames) -> BackgroundModel:
        """Add background frames (N, H, W) or (N, H, W, 3) uint8 to the running sums. Returns self.

        The statistics (``mean_``, ``std_``) are updated after each call once 2 frames or more
        have been seen; frames must all have the size of the first chunk.
        """
        self._check_params()
        stack = as_frame_stack(frames, "frames")
        gray = to_gray(stack)
        if not hasattr(self, "n_frames_seen_"):
            self.frame_shape_ = gray.shape[1:]
            self.n_frames_seen_ = 0
            self._s1 = np.zeros(self.frame_shape_, np.int64)
            self._s2 = np.zeros(self.frame_shape_, np.int64)
        elif gray.shape[1:] != self.frame_shape_:
            raise SegmentError(
                f"frames: frame size {frame_size_text(gray.shape[1:])} differs from the background's "
                f"{frame_size_text(self.frame_shape_)}"
            )
        for start in range(0, gray.shape[0], _BATCH_CHUNK):  # bounded int64 temporaries
            g = gray[start : start + _BATCH_CHUNK].astype(np.int64)
            self._s1 += g.sum(axis=0)
            self._s2 += np.einsum("nhw,nhw->hw", g, g)
        self.n_frames_seen_ += gray.shape[0]
        if self.n_frames_seen_ >= 2:
            self._finalise()
        return self

    def _finalise(self) -> None:
        n = self.n_frames_seen_
        # Exact integer numerator: var = (N S2 - S1^2) / N^2 (no cancellation, no float drift).
        self.mean_ = self._s1 / n
        self.std_ = np.sqrt((n * self._s2 - self._s1 * self._s1) / float(n * n))
        thr = self.k_sigma * np.maximum(self.std_, self.min_std)
        # Integer bounds, clipped to int16: |f - mean| > thr  <=>  f > floor(mean + thr) or f < ceil(mean - thr).
        self._upper = np.clip(np.floor(self.mean_ + thr), -1, 256).astype(np.int16)
        self._lower = np.clip(np.ceil(self.mean_ - thr), -1, 256).astype(np.int16)
        self._bg = None
        if self.ncc_threshold is not None:
            noise = self.std_**2 if self.noise_correction else None
            self._bg = background_window_stats(self.mean_, self.ncc_window, self.min_texture, noise)

    def _check_params(self) -> None:
        def fail(name, value, rule):
            raise SegmentError(f"{name}: {rule}, got {value!r}")

        if not (np.isscalar(self.k_sigma) and self.k_sigma > 0):
            fail("k_sigma", self.k_sigma, "must be a positive number")
        if not (np.isscalar(self.min_std) and self.min_std >= 0):
            fail("min_std", self.min_std, "must be a number >= 0 (graylevels)")
        w = self.ncc_window
        if not (isinstance(w, (int, np.integer)) and w >= 3 and w % 2 == 1):
            fail("ncc_window", w, "must be an odd integer >= 3")
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
        if not isinstance(self.noise_correction, (bool, np.bool_)):
            fail("noise_correction", self.noise_correction, "must be True or False")
        if not isinstance(self.largest_blob, (bool, np.bool_)):
            fail("largest_blob", self.largest_blob, "must be True or False")
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

    def segment(self, frame, return_stages: bool = False):
        """Foreground mask of one frame (streaming API).

        Parameters
        ----------
        frame : array (H, W) or (H, W, 3) uint8, same size as the background
        return_stages : bool
            Also return the intermediate masks.

        Returns
        -------
        array (H, W) bool, or with ``return_stages`` a dict {stage name: (H, W) bool} over
        :data:`STAGES` (``"final"`` is the mask).
        """
        self._check_fitted()
        arr = as_single_frame(frame, "frame")
        self._check_shape(arr.shape[:2], "frame")
        stages = self._segment_gray(to_gray(arr[None]))
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
            chunk = self._segment_gray(to_gray(stack[start : start + _BATCH_CHUNK]))
            for k in out:
                out[k][start : start + _BATCH_CHUNK] = chunk[k]
        return out if return_stages else out["final"]

    def _segment_gray(self, gray: np.ndarray) -> dict[str, np.ndarray]:
        """Pipeline on graylevel frames (N, H, W) uint8 -> {stage: (N, H, W) bool}."""
        # Stage 1, vectorised over the stack: |f - mean| > k sigma, for integer f exactly
        # f > floor(mean + k sigma) or f < ceil(mean - k sigma) (bounds precomputed in _finalise).
        cand = (gray > self._upper) | (gray < self._lower)
        out = {k: np.empty(gray.shape, bool) for k in STAGES}
        out["candidates"][:] = cand
        for i in range(gray.shape[0]):
            kept = cand[i]
            if self._bg is not None and kept.any():
                support = kept if self.ncc_support == "candidates" else None
                shadow = shadow_mask(gray[i], self._bg, support, self.min_support, self.ncc_threshold, self.shadow_ratio)
                kept = kept & ~shadow
            out["shadow_rejected"][i] = kept
            m = cleanup.median(kept.view(np.uint8) * np.uint8(255), self.median_size)
            out["median"][i] = m > 0
            m = cleanup.open_close(m, self.open_size, self.close_size)
            out["morphology"][i] = m > 0
            if self.largest_blob:
                m = cleanup.largest_blob(m)
            out["final"][i] = m > 0
        return out
