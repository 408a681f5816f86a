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
equal those of full-image filtering).

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
    """

    window: int
    min_texture: float
    b: np.ndarray
    bb: np.ndarray
    mean: np.ndarray
    var: np.ndarray
    noise_var: np.ndarray | None = None
    noise_mean: np.ndarray | None = None

    def crop(self, rows: slice, cols: slice) -> BackgroundWindowStats:
        """The same statistics on the rectangle ``[rows, cols]`` of the image (views, no copy). The NCC of a
        cropped frame with them equals the full image's at every pixel at least ``window // 2`` pixels inside
        the crop's edges that are not the image's edges (the windows there lie inside the crop)."""
        def cut(a):
            return None if a is None else a[rows, cols]

        return BackgroundWindowStats(self.window, self.min_texture, cut(self.b), cut(self.bb), cut(self.mean),
                                     cut(self.var), cut(self.noise_var), cut(self.noise_mean))


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
    return BackgroundWindowStats(window, float(min_texture), b, bb, mean, var, nv, nm)


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
    region, _, sub_ncc, sub_ratio = _ncc_region(frame, bg, support, min_support)
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
        Pixels to test (the candidates, the only pixels whose answer the pipeline uses); None: all.
        The window sums are box-filtered as without it; the NCC itself (about 30 array operations)
        is then computed at those pixels only, with the same float32 operations, so the answers
        there are the same bit for bit.

    Returns (H, W) bool: the same values as thresholding :func:`local_ncc`'s maps (False outside
    ``at``), but only the region where the NCC can be defined is touched.
    """
    out = np.zeros(np.shape(frame), bool)
    region, sel, ncc, ratio = _ncc_region(frame, bg, support, min_support, at)
    if region is not None:
        hit = (ncc > threshold) & (ratio >= ratio_bounds[0]) & (ratio <= ratio_bounds[1])
        if sel is None:
            out[region] = hit
        else:
            out[region][sel] = hit
    return out


def _ncc_region(frame, bg: BackgroundWindowStats, support, min_support: float, at=None):
    """NCC and ratio on the smallest rectangle holding every pixel with a defined NCC.

    Returns (region, sel, ncc, ratio): region a (slice, slice) of the image or None (nothing
    defined); without ``at``, sel is None and ncc and ratio are float32 arrays of the region's shape
    (0 / nan where undefined inside it); with ``at`` ((H, W) bool), sel is the (region-shaped) bool
    mask of the pixels of ``at`` whose NCC is defined (with ``support``; every pixel of ``at`` over
    full windows) and ncc, ratio are 1-D, at those pixels in raster order.
    """
    w = bg.window
    if support is None:
        f = np.asarray(frame, np.float32) - _CENTER
        mf = box(f, w)
        var_f = box(f * f, w) - mf * mf
        cov = box(f * bg.b, w) - mf * bg.mean
        terms = (mf, bg.mean, var_f, bg.var, cov, bg.noise_mean)
        sel = None if at is None else np.asarray(at, bool)
        if sel is not None:
            terms = tuple(None if t is None else t[sel] for t in terms)
        ncc, ratio = _finish(*terms, True, bg.min_texture)
        return (slice(None), slice(None)), sel, ncc, ratio
    h, wd = support.shape
    # Candidates per window, counted exactly in integers; the NCC is defined where the count
    # reaches min_support of the window. Only the bounding box of those pixels (plus the
    # window's reach) is filtered further: isolated noise candidates never qualify.
    need = max(1, int(np.ceil(float(min_support) * w * w - 1e-9)))
    support8 = np.ascontiguousarray(support, bool).view(np.uint8)
    count = cv2.boxFilter(support8, cv2.CV_16U, (w, w), normalize=False, borderType=cv2.BORDER_REFLECT_101)
    enough = count >= need
    rows, cols = np.flatnonzero(enough.any(axis=1)), np.flatnonzero(enough.any(axis=0))
    if rows.size == 0:
        return None, None, None, None
    r = w // 2
    y0, y1 = max(rows[0] - r, 0), min(rows[-1] + r + 1, h)  # input crop: the box's reach
    x0, x1 = max(cols[0] - r, 0), min(cols[-1] + r + 1, wd)
    oy, ox = slice(rows[0] - y0, rows[-1] + 1 - y0), slice(cols[0] - x0, cols[-1] + 1 - x0)  # output, in crop
    region = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    f = np.asarray(frame[y0:y1, x0:x1], np.float32) - _CENTER
    c = support[y0:y1, x0:x1].astype(np.float32)
    b, bb = bg.b[y0:y1, x0:x1], bg.bb[y0:y1, x0:x1]
    ok_support = enough[region]
    cf = c * f
    products = [cf, c * b, cf * f, c * bb, cf * b]
    if bg.noise_var is not None:
        products.append(c * bg.noise_var[y0:y1, x0:x1])
    if at is None:
        sel = None
        inv = np.zeros(ok_support.shape, np.float32)
        np.divide(np.float32(w * w), count[region], out=inv, where=ok_support)  # 1 / E_W[c]
        sums = [box(p, w)[oy, ox] for p in products]
    else:  # only the pixels of `at` with enough support: gather the window sums there (flat takes: fast)
        sel = ok_support & np.asarray(at, bool)[region]
        in_crop = np.zeros(f.shape, bool)
        in_crop[oy, ox] = sel
        jc = np.flatnonzero(in_crop)  # the same pixels, in raster order, as flat indices into the crop
        inv = np.float32(w * w) / np.take(count[y0:y1, x0:x1], jc)
        sums = [np.take(box(p, w), jc) for p in products]
    mf = sums[0] * inv
    mb = sums[1] * inv
    var_f = sums[2] * inv - mf * mf
    var_b = sums[3] * inv - mb * mb
    cov = sums[4] * inv - mf * mb
    noise = sums[5] * inv if len(sums) > 5 else None
    ncc, ratio = _finish(mf, mb, var_f, var_b, cov, noise, ok_support if sel is None else True, bg.min_texture)
    if sel is None:
        ratio[~ok_support] = np.nan
    return region, sel, ncc, ratio


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
