"""Local normalised cross-correlation between a frame and the background, over windows of candidate pixels.

Shadows change the graylevel a lot but keep the background texture: inside a small window the
shadowed frame is close to ``a * background + c`` and so correlates highly with it (paper
section 6, following its reference [12]). With ``E[.]`` a mean over the window ``W`` around a
pixel,

    NCC = (E[f b] - E[f] E[b]) / sqrt(Var f * Var b),   Var x = E[x^2] - E[x]^2.

Paper section 6 correlates "with other candidate pixels in a small neighbourhood around a
candidate pixel": the means are then taken over the candidate pixels of the window only,
``E_c[x] = box(c x) / box(c)`` with ``c`` the 0/1 candidate mask. This matters at a shadow's
edge, where a full window mixes lit and shadowed background (two gains, low NCC) but the
candidates inside it all lie in the shadow (one gain, high NCC). Over full windows the means are
plain ``cv2.boxFilter`` calls (normalised, ``BORDER_REFLECT_101``), 3 per frame (the background terms are
computed once, :class:`BackgroundWindowStats`). Over candidates they come from exact integer window sums in a
compiled kernel (:mod:`.ncc_kernel`; the background in quanta of 1 / :data:`QUANTUM` graylevel), taken only over
the bounding box of the pixels asked for whose window holds enough candidates (one integer box filter counts
them). The pipeline needs the answer at the candidates only (:func:`shadow_mask`'s ``at``); the sums being exact,
the answer at a pixel does not depend on which other pixels are asked for or on how the frame is cropped.

Noise correction (optional; an addition to the paper): camera noise of variance ``s^2`` in the
frame caps the NCC of even a perfect shadow at ``sqrt(1 - s^2 / Var f)``, which falls below a
0.9 threshold in deep shadows on a noisy camera (little texture left, same noise). Given the
per-pixel noise variance learnt from the background frames, the NCC is divided by that
expected ceiling (Spearman's correction for attenuation),

    NCC_c = NCC / sqrt(max(1 - E[s^2] / Var f, 1/2)),

with the gain capped at sqrt(2) so windows with little signal (flat foreground) are not blown
up. The background mean's own noise (``s^2 / N``) is neglected; the per-pixel variance also holds
the illumination flicker, a gain that does not lower the NCC, so ``s^2`` is a slight overestimate
(the correction errs towards calling shadows).

NCC is set to 0 (never a shadow) where it means nothing: fewer than ``min_support`` of the
window's pixels are candidates, the background is flatter than ``min_texture`` graylevels
(standard deviation over the support), or the frame is flat.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

# Graylevels are centred before squaring so E[x^2] - E[x]^2 in float32 loses less precision.
_CENTER = np.float32(128.0)
_FLAT_FRAME_VAR = np.float32(1e-4)
_MIN_RELIABILITY = np.float32(0.5)  # caps the noise correction's gain at sqrt(2)
QUANTUM = 4096
"""Quanta per graylevel of the background values in the exact window sums (:mod:`.ncc_kernel`): at most 1.2e-4
graylevels from the fitted values."""
MAX_NCC_WINDOW = 63
"""Largest window side of the exact sums: ``n S_BB`` is at most ``w^4 (128 QUANTUM)^2``, below 2^63 up to it."""


@dataclass(frozen=True)
class BackgroundWindowStats:
    """Background image b and its full-window statistics (arrays (H, W) float32).

    window : odd window side in pixels
    min_texture : graylevels; background standard deviations below it give NCC 0
    b : centred background ``b - 128``; bb : ``b * b`` (centred)
    mean : ``E_W[b - 128]``; var : ``Var_W b`` in graylevels^2 (full windows)
    noise_var : per-pixel noise variance ``s^2`` (graylevels^2) or None (no noise correction)
    noise_mean : ``E_W[s^2]`` (full windows) or None
    b_q : (H, W) int32, ``b`` in quanta of 1 / :data:`QUANTUM` graylevel (rounded), and
    noise_q : (H, W) int64, ``noise_var`` likewise, or None: the exact integer sums of the NCC over candidate
        windows (:mod:`.ncc_kernel`)
    """

    window: int
    min_texture: float
    b: np.ndarray
    bb: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    noise_var: np.ndarray | None = None
    noise_mean: np.ndarray | None = None
    b_q: np.ndarray | None = None
    noise_q: np.ndarray | None = None

    def crop(self, rows: slice, cols: slice) -> BackgroundWindowStats:
        """The same statistics on the rectangle ``[rows, cols]`` of the image (views, no copy). The NCC of a
        cropped frame with them equals the full image's at every pixel at least ``window // 2`` pixels inside
        the crop's edges that are not the image's edges (the windows there lie inside the crop)."""
        def cut(a):
            return None if a is None else a[rows, cols]

        return BackgroundWindowStats(self.window, self.min_texture, cut(self.b), cut(self.bb), cut(self.mean),
                                     cut(self.var), cut(self.noise_var), cut(self.noise_mean), cut(self.b_q),
                                     cut(self.noise_q))


def box(img: np.ndarray, window: int) -> np.ndarray:
    """Mean of ``img`` (H, W) over the ``window`` x ``window`` square around each pixel (reflect-101)."""
    return cv2.boxFilter(img, -1, (window, window), normalize=True, borderType=cv2.BORDER_REFLECT_101)


def background_window_stats(
    background: np.ndarray, window: int, min_texture: float = 2.0, noise_var: np.ndarray | None = None
) -> BackgroundWindowStats:
    """Precompute the background terms of the local NCC.

    Parameters
    ----------
    background : array (H, W) float, graylevels (the per-pixel background mean)
    window : odd int >= 3, window side in pixels
    min_texture : float >= 0, graylevels
    noise_var : array (H, W) float or None
        Per-pixel noise variance of a frame, graylevels^2 (the background variance); enables
        the noise correction.
    """
    b = np.asarray(background, np.float32) - _CENTER
    bb = b * b
    mean = box(b, window)
    var = box(bb, window) - mean * mean
    nv = nm = noise_q = None
    if noise_var is not None:
        nv = np.asarray(noise_var, np.float32)
        nm = box(nv, window)
        noise_q = np.rint(nv.astype(np.float64) * QUANTUM).astype(np.int64)
    b_q = np.rint((np.asarray(background, np.float64) - float(_CENTER)) * QUANTUM).astype(np.int32)
    return BackgroundWindowStats(window, float(min_texture), b, bb, mean, var, nv, nm, b_q, noise_q)


def local_ncc(
    frame: np.ndarray, bg: BackgroundWindowStats, support: np.ndarray | None = None, min_support: float = 0.25
) -> tuple[np.ndarray, np.ndarray]:
    """Local NCC of one graylevel frame with the background, and the local brightness ratio.

    Parameters
    ----------
    frame : array (H, W) uint8 or float, graylevels
    bg : :func:`background_window_stats` of the background
    support : array (H, W) bool or None
        Pixels the window statistics run over (the candidates); None = every pixel of the window.
    min_support : float in [0, 1]
        Minimum fraction of the window's pixels in ``support`` for a defined NCC.

    Returns
    -------
    ncc : array (H, W) float32 in [-1, 1]; 0 where undefined (see module docstring)
    ratio : array (H, W) float32, ``E[f] / E[b]`` over the same support (local brightness ratio;
        inf or nan where ``E[b] = 0``, nan where the support is too small)
    """
    h, w = np.shape(frame)
    ncc = np.zeros((h, w), np.float32)
    ratio = np.full((h, w), np.nan, np.float32)
    region, sub_ncc, sub_ratio = _ncc_region(frame, bg, support, min_support)
    if region is not None:
        ncc[region], ratio[region] = sub_ncc, sub_ratio
    return ncc, ratio


def shadow_mask(
    frame: np.ndarray,
    bg: BackgroundWindowStats,
    support: np.ndarray | None,
    min_support: float,
    threshold: float,
    ratio_bounds: tuple[float, float],
    at: np.ndarray | None = None,
) -> np.ndarray:
    """Pixels whose window looks like a shadow: ``NCC > threshold`` and
    ``ratio_bounds[0] <= E[f] / E[b] <= ratio_bounds[1]`` (arguments as in :func:`local_ncc`).

    at : array (H, W) bool or None
        Pixels to test (the candidates: the only pixels whose answer the pipeline uses); None: all.
        With ``support``, the window sums are taken over the bounding box of those pixels only
        (:func:`_shadow_at`), exactly as for the maps, so the answers are the same.

    Returns (H, W) bool: the same values as thresholding :func:`local_ncc`'s maps (False outside
    ``at``), but only the region where the NCC can be defined is touched.
    """
    if at is not None and support is not None:
        return _shadow_at(frame, bg, support, min_support, threshold, ratio_bounds, np.asarray(at, bool))
    out = np.zeros(np.shape(frame), bool)
    region, ncc, ratio = _ncc_region(frame, bg, support, min_support)
    if region is not None:
        out[region] = (ncc > threshold) & (ratio >= ratio_bounds[0]) & (ratio <= ratio_bounds[1])
    if at is not None:
        out &= at
    return out


def _need(window: int, min_support: float) -> int:
    """Candidates a window of side ``window`` must hold for a defined NCC: ``ceil(min_support window^2)``, >= 1."""
    return max(1, int(np.ceil(float(min_support) * window * window - 1e-9)))


def _support_region(support: np.ndarray, w: int, min_support: float):
    """The bounding box of the pixels with a defined NCC: those whose window holds ``min_support`` of its pixels
    in candidates, counted exactly in integers (isolated noise candidates never qualify). Returns (slice, slice)
    of the image, or None (no such pixel)."""
    support8 = np.ascontiguousarray(support, bool).view(np.uint8)
    count = cv2.boxFilter(support8, cv2.CV_16U, (w, w), normalize=False, borderType=cv2.BORDER_REFLECT_101)
    x, y, bw, bh = cv2.boundingRect((count >= _need(w, min_support)).view(np.uint8))
    if bw == 0:
        return None
    return slice(y, y + bh), slice(x, x + bw)


def _ncc_region(frame, bg: BackgroundWindowStats, support, min_support: float):
    """NCC and ratio on the smallest rectangle holding every pixel with a defined NCC.

    Returns (region, ncc, ratio): region a (slice, slice) of the image or None (nothing defined),
    ncc and ratio float32 arrays of the region's shape (0 / nan where undefined inside it).
    """
    w = bg.window
    if support is None:
        f = np.asarray(frame, np.float32) - _CENTER
        mf = box(f, w)
        var_f = box(f * f, w) - mf * mf
        cov = box(f * bg.b, w) - mf * bg.mean
        ncc, ratio = _finish(mf, bg.mean, var_f, bg.var, cov, bg.noise_mean, True, bg.min_texture)
        return (slice(None), slice(None)), ncc, ratio
    region = _support_region(support, w, min_support)
    if region is None:
        return None, None, None
    ncc, ratio = np.zeros(np.shape(frame), np.float32), np.full(np.shape(frame), np.nan, np.float32)
    _window_sums(frame, bg, support, min_support, 0.0, (0.0, 0.0), np.ones(np.shape(frame), bool), region,
                 np.zeros(np.shape(frame), bool), ncc, ratio)
    return region, ncc[region], ratio[region]


def _window_sums(frame, bg: BackgroundWindowStats, support, min_support: float, threshold: float, ratio_bounds,
                 at, rect, hit, ncc=None, ratio=None) -> None:
    """The compiled NCC over candidate windows (:func:`.ncc_kernel.window_ncc_at`) at the pixels of ``at`` in the
    rectangle ``rect`` (slice, slice): writes ``hit`` (H, W) bool and, when given, the ``ncc`` and ``ratio`` maps
    (H, W) float32 there. numba is imported here, with the first frame that needs it."""
    from .ncc_kernel import window_ncc_at

    shapes = {np.shape(a) for a in (frame, support, at, hit, bg.b_q) + (() if bg.noise_q is None else (bg.noise_q,))
              + tuple(m for m in (ncc, ratio) if m is not None)}
    if len(shapes) != 1:  # the compiled loop does not check its indices
        raise ValueError(f"frame, support, at and the background statistics must have one shape, got {sorted(shapes)}")
    w = bg.window
    no_map = np.zeros((0, 0), np.float32)
    # contiguous arrays throughout (a region of interest's statistics are views): one compiled signature
    window_ncc_at(np.ascontiguousarray(frame, np.uint8), np.ascontiguousarray(support, bool),
                  np.ascontiguousarray(bg.b_q),
                  np.zeros((0, 0), np.int64) if bg.noise_q is None else np.ascontiguousarray(bg.noise_q), float(QUANTUM),
                  np.ascontiguousarray(at, bool), (rect[0].start, rect[0].stop), (rect[1].start, rect[1].stop), w,
                  _need(w, min_support), float(max(bg.min_texture, 1e-3)) ** 2, float(_FLAT_FRAME_VAR),
                  float(threshold), float(ratio_bounds[0]), float(ratio_bounds[1]), hit,
                  no_map if ncc is None else ncc, no_map if ratio is None else ratio)


def _shadow_at(frame, bg: BackgroundWindowStats, support, min_support: float, threshold: float, ratio_bounds, at):
    """:func:`shadow_mask` at the pixels ``at`` with candidate ``support`` (see there): (H, W) bool. The compiled
    window sums run over the bounding box of the pixels of ``at`` whose windows may hold enough candidates."""
    out = np.zeros(np.shape(frame), bool)
    region = _support_region(support, bg.window, min_support)
    if region is None:
        return out
    x, y, bw, bh = cv2.boundingRect(np.ascontiguousarray(at[region]).view(np.uint8))
    if bw == 0:
        return out
    rows = slice(region[0].start + y, region[0].start + y + bh)
    cols = slice(region[1].start + x, region[1].start + x + bw)
    _window_sums(frame, bg, support, min_support, threshold, ratio_bounds, at, (rows, cols), out)
    return out


def _finish(mf, mb, var_f, var_b, cov, noise, ok, min_texture: float) -> tuple[np.ndarray, np.ndarray]:
    """NCC = cov / sqrt(var_f var_b) where defined (else 0), noise-corrected when ``noise`` (the
    window mean of the noise variance) is given, and ratio (E[f] + 128) / (E[b] + 128).

    All arrays (h, w) float32 (means centred by -128); ok: bool array or True.
    """
    var_b = np.maximum(var_b, 0.0)
    var_f = np.maximum(var_f, 0.0)
    ok = ok & (var_b >= np.float32(max(min_texture, 1e-3)) ** 2) & (var_f > _FLAT_FRAME_VAR)
    denom = var_f * var_b
    if noise is not None:
        # Correction for attenuation: divide by sqrt(reliability), reliability = 1 - E[s^2] / Var f >= 1/2.
        with np.errstate(divide="ignore", invalid="ignore"):
            reliability = np.maximum(1.0 - noise / var_f, _MIN_RELIABILITY)
        denom = denom * reliability
    ncc = np.zeros(np.shape(mf), np.float32)
    np.divide(cov, np.sqrt(denom), out=ncc, where=ok)
    np.clip(ncc, -1.0, 1.0, out=ncc)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (mf + _CENTER) / (mb + _CENTER)
    return ncc, ratio
