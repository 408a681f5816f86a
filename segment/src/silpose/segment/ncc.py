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
(the background terms are computed once, :class:`BackgroundWindowStats`), 6 over candidates.

NCC is set to 0 (never a shadow) where it means nothing: fewer than ``min_support`` of the
window's pixels are candidates, the background is flatter than ``min_texture`` graylevels
(standard deviation over the support), or the frame is flat.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Graylevels are centred before squaring so E[x^2] - E[x]^2 in float32 loses less precision.
_CENTER = np.float32(128.0)
_FLAT_FRAME_VAR = np.float32(1e-4)


@dataclass(frozen=True)
class BackgroundWindowStats:
    """Background image b and its full-window statistics (arrays (H, W) float32).

    window : odd window side in pixels
    min_texture : graylevels; background standard deviations below it give NCC 0
    b : centred background ``b - 128``; bb : ``b * b`` (centred)
    mean : ``E_W[b - 128]``; var : ``Var_W b`` in graylevels^2 (full windows)
    """

    window: int
    min_texture: float
    b: np.ndarray
    bb: np.ndarray
    mean: np.ndarray
    var: np.ndarray


def box(img: np.ndarray, window: int) -> np.ndarray:
    """Mean of ``img`` (H, W) over the ``window`` x ``window`` square around each pixel (reflect-101)."""
    import cv2

    return cv2.boxFilter(img, -1, (window, window), normalize=True, borderType=cv2.BORDER_REFLECT_101)


def background_window_stats(background: np.ndarray, window: int, min_texture: float = 2.0) -> BackgroundWindowStats:
    """Precompute the background terms of the local NCC.

    Parameters
    ----------
    background : array (H, W) float, graylevels (the per-pixel background mean)
    window : odd int >= 3, window side in pixels
    min_texture : float >= 0, graylevels
    """
    b = np.asarray(background, np.float32) - _CENTER
    bb = b * b
    mean = box(b, window)
    var = box(bb, window) - mean * mean
    return BackgroundWindowStats(window, float(min_texture), b, bb, mean, var)


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
        inf or nan where ``E[b] = 0``)
    """
    f = np.asarray(frame, np.float32) - _CENTER
    w = bg.window
    if support is None:
        mf = box(f, w)
        var_f = box(f * f, w) - mf * mf
        cov = box(f * bg.b, w) - mf * bg.mean
        mb, var_b = bg.mean, bg.var
        enough = True
    else:
        c = support.astype(np.float32)
        frac = box(c, w)
        enough = frac >= max(float(min_support), 0.5 / (w * w))  # at least one pixel
        inv = np.zeros_like(frac)
        np.divide(1.0, frac, out=inv, where=enough)
        cf = c * f
        mf = box(cf, w) * inv
        mb = box(c * bg.b, w) * inv
        var_f = box(cf * f, w) * inv - mf * mf
        var_b = box(c * bg.bb, w) * inv - mb * mb
        cov = box(cf * bg.b, w) * inv - mf * mb
    var_b = np.maximum(var_b, 0.0)
    var_f = np.maximum(var_f, 0.0)
    ok = enough & (var_b >= np.float32(max(bg.min_texture, 1e-3)) ** 2) & (var_f > _FLAT_FRAME_VAR)
    ncc = np.zeros_like(f)
    np.divide(cov, np.sqrt(var_f * var_b), out=ncc, where=ok)
    np.clip(ncc, -1.0, 1.0, out=ncc)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (mf + _CENTER) / (mb + _CENTER)
    return ncc, ratio
