"""Compiled pass of colour background subtraction (numba, :mod:`.background`): a frame's gain division and candidates.

A colour frame's first two steps touch every pixel (module docstring of :mod:`.background`, steps 1-2):
- **the gain's division**: every value divided by the frame's gain in its channel
  (:meth:`~.background.BackgroundModel.frame_gain`, a median over a grid of pixels, stays numpy's), rounded and
  saturated;
- **the candidates**: the squared colour difference from the background mean, summed over the channels, and the
  same weighted by the inverse variances, whose excess over ``3 k_sigma^2`` makes a pixel a candidate.

As OpenCV calls these were eleven passes over the frame (split, three scalings, merge, a float copy, subtract,
square, two channel sums, scale, compare). Here they are one pass over each row. The arithmetic is OpenCV's,
operation for operation, in float32: a value times the inverse gain rounded half to even and saturated
(``cv2.convertScaleAbs``), differences squared, channels summed left to right (``cv2.transform`` by a row of ones).
So the answers are the same bit for bit (``tests/segment/test_colour_kernels.py`` against those OpenCV calls).
Measured on a 922x519 frame of a full-HD recording at its working size, one thread: 2.1 -> 0.83 ms. (The gain's
median by a compiled selection was tried too: 1.37 ms against ``np.partition``'s 1.26 for three rows of 30,000
ratios.) numba is imported with this module (about a second); :mod:`.background` imports it when the first colour
frame is segmented. ``nogil``: camera threads segment at once.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["normalise_and_score"]


@njit(cache=True, nogil=True, boundscheck=False)
def normalise_and_score(frame: np.ndarray, inv_row: np.ndarray, mean_rows: np.ndarray, inv_var_rows: np.ndarray,
                        threshold: np.float32, out: np.ndarray, sq: np.ndarray, score: np.ndarray,
                        cand: np.ndarray) -> None:  # pragma: no cover (compiled)
    """One colour frame's gain division and candidates, row by row (module docstring).

    Args:
        frame: (H, 3 W) uint8, a BGR frame's rows.
        inv_row: (3 W,) float32, the three inverse gains repeated along a row (ones: no gain).
        mean_rows, inv_var_rows: (H, 3 W) float32, the background's mean and ``1 / max(std, min_std)^2``.
        threshold: float32, ``3 k_sigma^2``.
    Writes:
        out (H, 3 W) uint8: ``saturate(round_half_even(|f g^-1|))``, the frame the later steps read;
        sq (H, W) float32: ``sum_c (out_c - mean_c)^2``; score (H, W) float32: ``sum_c (out_c - mean_c)^2 / var_c``;
        cand (H, W) bool: ``score > threshold``.
    """
    h, w3 = frame.shape[0], frame.shape[1]
    w = w3 // 3
    d2 = np.empty(w3, np.float32)
    e2 = np.empty(w3, np.float32)
    top = np.float32(255)
    for y in range(h):
        f, o, m, iv = frame[y], out[y], mean_rows[y], inv_var_rows[y]
        for i in range(w3):
            g = min(np.rint(abs(np.float32(f[i]) * inv_row[i])), top)
            o[i] = np.uint8(g)
            d = g - m[i]
            d2[i] = d * d
            e2[i] = d2[i] * iv[i]
        s, t, c = sq[y], score[y], cand[y]
        for x in range(w):
            s[x] = (d2[3 * x] + d2[3 * x + 1]) + d2[3 * x + 2]
            v = (e2[3 * x] + e2[3 * x + 1]) + e2[3 * x + 2]
            t[x] = v
            c[x] = v > threshold
