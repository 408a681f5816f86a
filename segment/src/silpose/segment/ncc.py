"""Local normalised cross-correlation between a frame and the background, with box filters.

Shadows change the graylevel a lot but keep the background texture: inside a small window the
shadowed frame is close to ``a * background + c`` and so correlates highly with it (paper
section 6, following its reference [12]). With ``E[.]`` a mean over the window ``W`` around a
pixel,

    NCC = (E[f b] - E[f] E[b]) / sqrt(Var f * Var b),   Var x = E[x^2] - E[x]^2.

Paper section 6 correlates "with other candidate pixels in a small neighbourhood around a
candidate pixel": the means are then taken over the candidate pixels of the window only,
``E_c[x] = box(c x) / box(c)`` with ``c`` the 0/1 candidate mask. This matters at a shadow's
edge, where a full window mixes lit and shadowed background (two gains, low NCC) but the
candidates inside it all lie in the shadow (one gain, high NCC). Both variants are plain
``cv2.boxFilter`` calls (normalised, ``BORDER_REFLECT_101``): 3 per frame over full windows
(the background terms are computed once, :class:`BackgroundWindowStats`); over candidates, one
integer count of candidates per window, then 5 float filters (6 with the noise correction) restricted to the bounding box of
the pixels whose window holds enough candidates (cropped with the window's reach, so the values
equal those of full-image filtering). The pipeline needs the answer at the candidates only
(:func:`shadow_mask`'s ``at``): there a quick integer test of the brightness ratio comes first
(uint8 box sums of the frame and of the background rounded up and down), and the float sums are
filtered only over the bounding box of the candidates whose window may have darkened within the
ratio bounds; the NCC is then computed at those pixels alone (1-D arrays).

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


@dataclass(frozen=True)
class BackgroundWindowStats:
    """Background image b and its full-window statistics (arrays (H, W) float32).

    window : odd window side in pixels
    min_texture : graylevels; background standard deviations below it give NCC 0
    b : centred background ``b - 128``; bb : ``b * b`` (centred)
    mean : ``E_W[b - 128]``; var : ``Var_W b`` in graylevels^2 (full windows)
    noise_var : per-pixel noise variance ``s^2`` (graylevels^2) or None (no noise correction)
    noise_mean : ``E_W[s^2]`` (full windows) or None
    floor, ceil : (H, W) uint8, the background rounded down and up (graylevels 0-255), or None: integer
        bounds on the window sums of the background, for :func:`shadow_mask`'s quick brightness test
    """

    window: int
    min_texture: float
    b: np.ndarray
    bb: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    noise_var: np.ndarray | None = None
    noise_mean: np.ndarray | None = None
    floor: np.ndarray | None = None
    ceil: np.ndarray | None = None

    def crop(self, rows: slice, cols: slice) -> BackgroundWindowStats:
        """The same statistics on the rectangle ``[rows, cols]`` of the image (views, no copy). The NCC of a
        cropped frame with them equals the full image's at every pixel at least ``window // 2`` pixels inside
        the crop's edges that are not the image's edges (the windows there lie inside the crop)."""
        def cut(a):
            return None if a is None else a[rows, cols]

        return BackgroundWindowStats(self.window, self.min_texture, cut(self.b), cut(self.bb), cut(self.mean),
                                     cut(self.var), cut(self.noise_var), cut(self.noise_mean), cut(self.floor),
                                     cut(self.ceil))


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
    nv = nm = None
    if noise_var is not None:
        nv = np.asarray(noise_var, np.float32)
        nm = box(nv, window)
    level = np.asarray(background, np.float64)
    floor = np.clip(np.floor(level), 0, 255).astype(np.uint8)
    ceil = np.clip(np.ceil(level), 0, 255).astype(np.uint8)
    return BackgroundWindowStats(window, float(min_texture), b, bb, mean, var, nv, nm, floor, ceil)


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
        With ``support``, a quick brightness test in integers comes first at those pixels (see
        :func:`_shadow_at`: it drops only pixels whose ratio is outside ``ratio_bounds``); the window
        sums are then box-filtered over the bounding box of the pixels left only (a shadow darkens: on
        a person brighter than the room that is the cast shadow alone), and the NCC computed at those
        pixels only. Same float32 operations on the same window sums (up to the last bit of a sum,
        which OpenCV's running box sums take from where the crop starts), so the same answers.

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


def _support_crop(support: np.ndarray, w: int, min_support: float):
    """Candidates per window, counted exactly in integers; the NCC is defined where the count reaches
    ``min_support`` of the window. Only the bounding box of those pixels (plus the window's reach) is filtered
    further: isolated noise candidates never qualify.

    Returns None (no such pixel) or (count, enough, crop, region, inner): count (H, W) uint16 and enough (H, W)
    bool; crop and region (slice, slice) of the image, the box filters' input (region grown by the window's reach,
    clipped) and the pixels with a defined NCC's bounding box; inner: region as (slice, slice) of the crop."""
    h, wd = support.shape
    need = max(1, int(np.ceil(float(min_support) * w * w - 1e-9)))
    support8 = np.ascontiguousarray(support, bool).view(np.uint8)
    count = cv2.boxFilter(support8, cv2.CV_16U, (w, w), normalize=False, borderType=cv2.BORDER_REFLECT_101)
    enough = count >= need
    x, y, bw, bh = cv2.boundingRect(enough.view(np.uint8))
    if bw == 0:
        return None
    r = w // 2
    y0, y1 = max(y - r, 0), min(y + bh + r, h)  # input crop: the box's reach
    x0, x1 = max(x - r, 0), min(x + bw + r, wd)
    crop = (slice(y0, y1), slice(x0, x1))
    region = (slice(y, y + bh), slice(x, x + bw))
    inner = (slice(y - y0, y + bh - y0), slice(x - x0, x + bw - x0))
    return count, enough, crop, region, inner


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
    found = _support_crop(support, w, min_support)
    if found is None:
        return None, None, None
    count, enough, crop, region, (oy, ox) = found
    f = np.asarray(frame[crop], np.float32) - _CENTER
    c = support[crop].astype(np.float32)
    b, bb = bg.b[crop], bg.bb[crop]
    ok_support = enough[region]
    inv = np.zeros(ok_support.shape, np.float32)
    np.divide(np.float32(w * w), count[region], out=inv, where=ok_support)  # 1 / E_W[c]
    cf = c * f
    mf = box(cf, w)[oy, ox] * inv
    mb = box(c * b, w)[oy, ox] * inv
    var_f = box(cf * f, w)[oy, ox] * inv - mf * mf
    var_b = box(c * bb, w)[oy, ox] * inv - mb * mb
    cov = box(cf * b, w)[oy, ox] * inv - mf * mb
    noise = None if bg.noise_var is None else box(c * bg.noise_var[crop], w)[oy, ox] * inv
    ncc, ratio = _finish(mf, mb, var_f, var_b, cov, noise, ok_support, bg.min_texture)
    ratio[~ok_support] = np.nan
    return region, ncc, ratio


def _shadow_at(frame, bg: BackgroundWindowStats, support, min_support: float, threshold: float, ratio_bounds, at):
    """:func:`shadow_mask` at the pixels ``at`` with candidate ``support`` (see there): (H, W) bool.

    1. A quick brightness test at the pixels of ``at`` with enough support, in integers: the window sums of the
       candidates' graylevels ``S_f`` and of the background rounded up and down (``S_ceil >= S_b >= S_floor``),
       three uint8 box filters. A shadow's ratio ``S_f / S_b`` lies in ``ratio_bounds``, so it has
       ``lo S_floor <= S_f <= hi S_ceil`` (with a margin far above float32 rounding): the others are not shadows.
    2. The window sums of the NCC in float32 (as :func:`local_ncc`) over the bounding box of the pixels left and
       the windows' reach, the NCC and the exact ratio test there."""
    w, r = bg.window, bg.window // 2
    out = np.zeros(np.shape(frame), bool)
    found = _support_crop(support, w, min_support)
    if found is None:
        return out
    count, enough, crop, region, inner = found
    tested = np.zeros(count[crop].shape, bool)  # the pixels of `at` with a defined NCC, in the crop
    tested[inner] = enough[region] & at[region]
    c8 = np.ascontiguousarray(support[crop]).view(np.uint8)
    frame8 = np.asarray(frame[crop], np.uint8)
    if bg.floor is not None:
        def window_sum(levels):  # float32 sums of integers below 2^24 (255 w^2): exact
            return cv2.boxFilter(levels * c8, cv2.CV_32F, (w, w), normalize=False, borderType=cv2.BORDER_REFLECT_101)

        lo, hi = ratio_bounds
        s_f = window_sum(frame8)
        # S_f - hi S_ceil <= 0 <= S_f - lo S_floor, with 2 graylevels of slack in the sums against float rounding
        tested &= cv2.scaleAdd(window_sum(bg.ceil[crop]), -float(hi), s_f) <= np.float32(2.0)
        tested &= cv2.scaleAdd(window_sum(bg.floor[crop]), -float(lo), s_f) >= np.float32(-2.0)
    j = np.flatnonzero(tested)  # raster order; flat indices into the crop's arrays
    if not j.size:
        return out
    # The window sums over those pixels' bounding box and the windows' reach only (inside the crop, whose edges
    # are the image's or at least r pixels from any pixel tested).
    ch, cw = tested.shape
    rows, cols = np.divmod(j, cw)
    y0, y1, x0, x1 = max(rows.min() - r, 0), min(rows.max() + r + 1, ch), max(cols.min() - r, 0), min(cols.max() + r + 1, cw)
    sub = (slice(y0, y1), slice(x0, x1))
    js = (rows - y0) * (x1 - x0) + (cols - x0)
    f = frame8[sub].astype(np.float32) - _CENTER
    c = c8[sub].astype(np.float32)
    b = bg.b[crop][sub]
    cf = c * f
    inv = np.float32(w * w) / np.take(count[crop][sub], js)  # 1 / E_W[c]
    mf = np.take(box(cf, w), js) * inv
    mb = np.take(box(c * b, w), js) * inv
    var_f = np.take(box(cf * f, w), js) * inv - mf * mf
    var_b = np.take(box(c * bg.bb[crop][sub], w), js) * inv - mb * mb
    cov = np.take(box(cf * b, w), js) * inv - mf * mb
    noise = None if bg.noise_var is None else np.take(box(c * bg.noise_var[crop][sub], w), js) * inv
    ncc, ratio = _finish(mf, mb, var_f, var_b, cov, noise, True, bg.min_texture)
    hit = (ncc > threshold) & (ratio >= ratio_bounds[0]) & (ratio <= ratio_bounds[1])
    out[rows[hit] + crop[0].start, cols[hit] + crop[1].start] = True
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
