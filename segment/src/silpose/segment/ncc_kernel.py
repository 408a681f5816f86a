"""Compiled local NCC over candidate windows (numba, :mod:`.ncc`): exact integer window sums at chosen pixels.

The NCC of paper section 6 over the candidate pixels ``c`` of the ``w x w`` window around a pixel needs seven
window sums (module docstring of :mod:`.ncc`): ``n = sum c``, ``S_f = sum c f``, ``S_ff = sum c f^2``, ``S_b``,
``S_bb``, ``S_fb`` and, with the noise correction, ``S_s = sum c s^2``. With the graylevels centred
(``f = frame - 128``, an integer) and the background mean ``b`` (centred) and noise variance ``s^2`` in integer
quanta of ``1 / QUANTUM`` graylevel (``B = round(b QUANTUM)``, :data:`.ncc.QUANTUM`: at most half a quantum from
the fitted values), every sum is an integer, kept exactly in int64. Then

    Var f = (n S_ff - S_f^2) / n^2,   Var b = (n S_BB - S_B^2) / (n QUANTUM)^2,   Cov = (n S_fB - S_f S_B) / (n^2 QUANTUM)

with the subtractions still exact in integers (no cancellation, unlike ``E[x^2] - E[x]^2`` in float32), and

    NCC = Cov / sqrt(Var f Var b),   ratio = (S_f / n + 128) / (S_B / (n QUANTUM) + 128)

in float64. Exact sums do not depend on where a sum starts, so an answer at a pixel is the same whichever other
pixels are asked for or however the frame is cropped around it (the region of interest of :mod:`.background`).

The sums slide: per column, the sum over the window's rows is updated as the window moves down one row (the row
entering added, the row leaving taken away); along a row, the window's sums of those column sums likewise, from the
row's first pixel asked for to its last. About 30 integer operations per pixel of the examined rectangle, whatever
the window, and no temporary image. Where the brightness ratio is outside its bounds the NCC is not computed (no
shadow whatever it is) unless its map is asked for. Measured in one process, one thread, the same shadow pixels:
the seven float32 box filters, products and gathers this replaces took 0.69-0.75 ms per frame against 0.23-0.24 ms
here (the 32 candidates' regions of ``data/smoke/frames``, Blender renders at 320x240). On 200 frames of a 1080p
colour recording at its working size (50,500-pixel rectangles, 16,000 pixels asked for), idle machine: 0.59-0.69 ms
sliding along whole rows with the NCC at every pixel; 0.46-0.50 ms sliding over the pixels asked for and skipping
the NCC where the ratio rules a shadow out, with the row updates written out twice; 0.51-0.57 ms as here, each
update written once (a helper for the rows, one running difference along a row). Running totals along a row instead
of sliding took 0.52-0.55 ms. Borders are reflect-101, as ``cv2.BORDER_REFLECT_101``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["window_ncc_at"]


@njit(cache=True, nogil=True, boundscheck=False)
def _reflect(i: int, n: int) -> int:  # pragma: no cover (compiled)
    """Index ``i`` of a line of ``n`` pixels, reflected at both ends without repeating the edge (reflect-101), as
    often as it takes: a window may reach beyond a line shorter than itself."""
    if n == 1:
        return 0
    period = 2 * n - 2
    i %= period  # Python's sign: 0 <= i < period
    return i if i < n else period - i


@njit(cache=True, nogil=True, boundscheck=False)
def _add_row(frame_row, support_row, b_row, noise_row, column, sign: int, sums) -> None:  # pragma: no cover
    """Adds (``sign`` 1) or takes away (-1) one image row's candidates to the column sums ``sums`` (width, 7): n,
    S_f, S_ff, S_B, S_BB, S_fB, S_s (``noise_row`` of length 0: no S_s). ``column``: the image column of each."""
    for k in range(column.shape[0]):
        xa = column[k]
        if support_row[xa]:
            f = np.int64(frame_row[xa]) - 128
            bk = np.int64(b_row[xa])
            sums[k, 0] += sign
            sums[k, 1] += sign * f
            sums[k, 2] += sign * f * f
            sums[k, 3] += sign * bk
            sums[k, 4] += sign * bk * bk
            sums[k, 5] += sign * f * bk
            if noise_row.shape[0] > 0:
                sums[k, 6] += sign * noise_row[xa]


@njit(cache=True, nogil=True, boundscheck=False, error_model="numpy")
def window_ncc_at(frame: np.ndarray, support: np.ndarray, b_q: np.ndarray, noise_q: np.ndarray, quantum: float,
                  at: np.ndarray, rows: tuple, cols: tuple, window: int, need: int, min_var_b: float, min_var_f: float,
                  threshold: float, lo: float, hi: float, hit: np.ndarray, ncc_out: np.ndarray,
                  ratio_out: np.ndarray) -> None:  # pragma: no cover (compiled)
    """The NCC and brightness ratio over candidate windows at the pixels ``at`` of a rectangle (module docstring).

    Args:
        frame: (H, W) uint8 graylevels; support: (H, W) bool, the candidates the windows' statistics run over.
        b_q: (H, W) int32, the centred background mean in quanta (``round((mean - 128) quantum)``).
        noise_q: (H, W) int64, the noise variance in quanta, or (0, 0): no noise correction.
        quantum: quanta per graylevel.
        at: (H, W) bool, the pixels to answer; rows, cols: (start, stop) of the rectangle examined (only its
            pixels of ``at`` are answered; the windows reach ``window // 2`` beyond it, reflected at the image's
            edges).
        window: odd side w; need: candidates a window must hold for a defined NCC (``ceil(min_support w^2)``).
        min_var_b, min_var_f: graylevels^2; the background's and the frame's variance over the support below them
            give NCC 0 (``min_texture^2`` and the flat-frame bound).
        threshold, lo, hi: a shadow has ``NCC > threshold`` and ``lo <= ratio <= hi``.
    Writes, at the pixels of ``at`` in the rectangle whose window holds ``need`` candidates:
        hit (H, W) bool: the shadow test; ncc_out, ratio_out (H, W) float32 (or (0, 0): not written): the NCC
        (noise-corrected with ``noise_q``: divided by ``sqrt(max(1 - E[s^2] / Var f, 1/2))``, clipped to [-1, 1],
        0 where a variance is below its bound) and the ratio.
    """
    h, w = frame.shape
    r = window // 2
    y0, y1 = rows
    x0, x1 = cols
    width = x1 - x0 + 2 * r
    has_noise = noise_q.shape[0] > 0
    no_noise = np.zeros(0, np.int64)
    maps = ncc_out.shape[0] > 0
    q = np.float64(quantum)
    column = np.empty(width, np.int64)  # image column of each column of the sums (reflected)
    for k in range(width):
        column[k] = _reflect(x0 - r + k, w)
    sums = np.zeros((width + 1, 7), np.int64)  # per column, over the window's rows: n, S_f, S_ff, S_B, S_BB, S_fB,
    # S_s; the last row stays zero (a column taken away before the window is full)
    for entering in range(y0 - r, y1 + r):
        ya = _reflect(entering, h)
        _add_row(frame[ya], support[ya], b_q[ya], noise_q[ya] if has_noise else no_noise, column, 1, sums)
        y = entering - r  # the row whose window (rows y - r .. y + r) the column sums now hold
        if y < y0:
            continue
        first, last = x1, x0 - 1  # the row's pixels of ``at`` in the rectangle: the sums slide over them only
        for x in range(x0, x1):
            if at[y, x]:
                if first == x1:
                    first = x
                last = x
        s0 = s1 = s2 = s3 = s4 = s5 = s6 = np.int64(0)
        for x in range(first - window + 1, last + 1):  # the window filled first, then slid
            k, gone = x - x0 + window - 1, (x - x0 - 1 if x > first else width)  # columns x + r in, x - r - 1 out
            s0 += sums[k, 0] - sums[gone, 0]
            s1 += sums[k, 1] - sums[gone, 1]
            s2 += sums[k, 2] - sums[gone, 2]
            s3 += sums[k, 3] - sums[gone, 3]
            s4 += sums[k, 4] - sums[gone, 4]
            s5 += sums[k, 5] - sums[gone, 5]
            s6 += sums[k, 6] - sums[gone, 6]
            if x < first or not (at[y, x] and s0 >= need):
                continue
            n = np.float64(s0)
            ratio = (np.float64(s1) / n + 128.0) / (np.float64(s3) / (n * q) + 128.0)
            if not (maps or lo <= ratio <= hi):  # no shadow whatever the NCC
                continue
            var_f = np.float64(s0 * s2 - s1 * s1) / (n * n)
            var_b = np.float64(s0 * s4 - s3 * s3) / (n * n * q * q)
            c = 0.0
            if var_b >= min_var_b and var_f > min_var_f:
                cov = np.float64(s0 * s5 - s1 * s3) / (n * n * q)
                denom = var_f * var_b
                if has_noise:
                    reliability = 1.0 - np.float64(s6) / (n * q) / var_f
                    denom *= max(reliability, 0.5)
                c = min(max(cov / np.sqrt(denom), -1.0), 1.0)
            hit[y, x] = c > threshold and lo <= ratio <= hi
            if maps:
                ncc_out[y, x] = c
                ratio_out[y, x] = ratio
        ya = _reflect(y - r, h)  # the row leaving the window
        _add_row(frame[ya], support[ya], b_q[ya], noise_q[ya] if has_noise else no_noise, column, -1, sums)
