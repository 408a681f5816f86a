"""Colour shadow rule: grow the NCC-accepted shadows through darkened, colour-preserving candidates.

Why: on rendered (and real) frames the local NCC of :mod:`.ncc` accepts only part of a floor
shadow. Windows straddling the shadow's border (penumbra, a gain that changes inside the window)
and shadowed floor whose fine texture the renderer's denoiser or the camera smoothed correlate
poorly, so a rim - often the whole thin shadow of a leg - survives, the closing joins it to the
feet and the largest blob keeps it (measured on ``data/smoke/frames``: median NCC 0.3-0.7 over
the surviving shadow pixels).

What stays in the paper's spirit: a shadow is a change *highly correlated with the background*;
here the correlation is across the colour channels of one pixel. A cast shadow attenuates the
light, so the frame's colour vector ``f`` (B, G, R) stays parallel to the background's mean
colour ``m`` (Horprasert et al.'s brightness and chromaticity distortions):

    alpha = (f . m) / (m . m)            brightness distortion (1 = unchanged, < 1 darker)
    cd    = || f - alpha m ||            chromaticity distortion, graylevels

A candidate is *shadow-like* when ``ratio_bounds[0] <= alpha <= ratio_bounds[1]`` and ``cd <=
chroma_max``. Clothes and skin are often shadow-like too (brown trousers on a beige floor), so the
colour test alone would eat the person; shadow-like pixels become shadows only as 8-connected
components that contain at least one NCC-accepted shadow pixel (a seed): the NCC establishes
"this is a shadow", the colour test delimits it. A component of shadow-like person pixels is
removed only when it touches an accepted shadow through shadow-like pixels.
"""

from __future__ import annotations

import cv2
import numpy as np


def brightness_chroma(frame: np.ndarray, mean: np.ndarray, channel_axis: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Brightness distortion ``alpha`` and chromaticity distortion ``cd`` of a colour frame.

    Parameters
    ----------
    frame : array (H, W, 3) uint8 or float, colour frame (any channel order, same as ``mean``)
    mean : array (H, W, 3) float, per-pixel background mean colour, graylevels
    channel_axis : -1 (channels last, as above) or 0 (channels first: (3, ...) planes, e.g. (3, n)
        pixel lists, whose channels are contiguous rows)

    Returns
    -------
    alpha : array (H, W) float64 (0 where the background is black)
    cd : array (H, W) float64, graylevels

    Any leading shape works: (..., 3) in, (...) out. The sums over the 3 channels are written out
    (``a0 b0 + a1 b1 + a2 b2``): 2-3x faster than ``einsum`` on the few thousand pixels of a frame.
    """
    f = np.asarray(frame, np.float64)
    m = np.asarray(mean, np.float64)
    fc = (f[0], f[1], f[2]) if channel_axis == 0 else (f[..., 0], f[..., 1], f[..., 2])
    mc = (m[0], m[1], m[2]) if channel_axis == 0 else (m[..., 0], m[..., 1], m[..., 2])

    def dot(a, b):
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]

    mm = dot(mc, mc)
    alpha = np.zeros(mm.shape)
    np.divide(dot(fc, mc), mm, out=alpha, where=mm > 0)
    resid = [p - alpha * q for p, q in zip(fc, mc)]
    cd = np.sqrt(dot(resid, resid))
    return alpha, cd


def shadow_like(
    frame_px: np.ndarray, mean_px: np.ndarray, ratio_bounds: tuple[float, float], chroma_max: float, channel_axis: int = -1
) -> np.ndarray:
    """Shadow-like pixels: ``ratio_bounds[0] <= alpha <= ratio_bounds[1]`` and ``cd <= chroma_max``.

    frame_px (..., 3) uint8 or float and mean_px (..., 3) float: colours of the same pixels (e.g. (n, 3)
    lists of candidate pixels; (3, ...) with ``channel_axis=0``, see :func:`brightness_chroma`); returns (...) bool."""
    alpha, cd = brightness_chroma(frame_px, mean_px, channel_axis)
    return (alpha >= ratio_bounds[0]) & (alpha <= ratio_bounds[1]) & (cd <= chroma_max)


def seeded_components(like: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """The 8-connected components of ``like | seeds`` that hold a seed: (H, W) bool, from two (H, W) bool
    masks (``like`` is modified: the seeds are added to it)."""
    like |= seeds
    n, labels = cv2.connectedComponents(like.view(np.uint8), connectivity=8)
    seeded = np.zeros(n, bool)
    seeded[labels[seeds]] = True
    seeded[0] = False
    ids = np.flatnonzero(seeded)
    if ids.size == 1:  # one seeded component (a person's shadow): one comparison, 8x faster than the lookup
        return cv2.compare(labels, int(ids[0]), cv2.CMP_EQ) > 0
    return np.take(seeded, labels)  # (twice as fast as seeded[labels])


def grow_shadows(
    frame: np.ndarray,
    mean: np.ndarray,
    candidates: np.ndarray,
    seeds: np.ndarray,
    ratio_bounds: tuple[float, float],
    chroma_max: float,
) -> np.ndarray:
    """Shadows: the 8-connected components of (shadow-like candidates | seeds) that hold a seed.

    Parameters
    ----------
    frame : array (H, W, 3) uint8, colour frame
    mean : array (H, W, 3) float, background mean colour (same channel order), graylevels
    candidates : array (H, W) bool, candidate pixels
    seeds : array (H, W) bool, NCC-accepted shadow pixels (a subset of ``candidates``)
    ratio_bounds : (low, high), bounds on ``alpha`` for a shadow-like pixel
    chroma_max : float, graylevels, bound on ``cd`` for a shadow-like pixel

    Returns
    -------
    array (H, W) bool, the shadow pixels (includes ``seeds``).
    """
    seeds = np.asarray(seeds, bool)
    if not seeds.any():
        return seeds.copy()
    # Distortions at the candidate pixels only (a few % of the image): (n, 3) gathers.
    candidates = np.asarray(candidates, bool)
    like = np.zeros(seeds.shape, bool)
    like[candidates] = shadow_like(np.asarray(frame)[candidates], np.asarray(mean)[candidates], ratio_bounds, chroma_max)
    return seeded_components(like, seeds)
