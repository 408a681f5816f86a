"""Fuzz: contour extraction on odd masks (complements the random-mask test in tests/shared/test_contours.py).

Empty masks, single pixels, holes, blobs touching the border, several blobs, thin lines, odd
dtypes and memory layouts. Each either works -- 200 finite points, clockwise (shoelace area >= 0),
inside the image, on the boundary of the largest blob -- or raises the documented error
(``EmptyMaskError`` for no foreground, ``ValueError`` for a non-2-D mask). cv2 runs with a
deadline, and a batch of extreme masks runs in a child process to catch interpreter crashes.
"""

from __future__ import annotations

import subprocess
import sys

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from silpose.shared.contours import EmptyMaskError, extract_contour, extract_contours, signed_area

N = 200
FUZZ = settings(max_examples=100, deadline=1000, derandomize=True)


def _largest_blob(mask: np.ndarray) -> np.ndarray:
    """Brute-force reference: the largest 8-connected blob (ties: topmost, then leftmost bounding box)."""
    n, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    best = None
    for lab in range(1, n):
        yy, xx = np.nonzero(labels == lab)
        key = (-len(yy), yy.min(), xx.min(), yy.mean(), xx.mean())
        if best is None or key < best[0]:
            best = (key, lab)
    return labels == best[1]


def check_contour(mask: np.ndarray) -> None:
    """Run extract_contour and check the documented outcome."""
    m = np.asarray(mask) != 0
    if not m.any():
        with pytest.raises(EmptyMaskError):
            extract_contour(mask, N)
        return
    c = extract_contour(mask, N)
    h, w = m.shape
    p = c.points
    assert p.shape == (N, 2) and p.dtype == np.float32 and np.all(np.isfinite(p))
    assert np.all(p >= 0) and np.all(p[:, 0] <= w - 1) and np.all(p[:, 1] <= h - 1)
    assert signed_area(p) >= -1e-3  # clockwise on screen (zero for lines and single pixels)
    blob = _largest_blob(m)
    assert c.area == int(blob.sum())
    # On the boundary of the largest blob: every point lies on a segment between two 8-adjacent
    # boundary-pixel centres of that blob, so within sqrt(2)/2 px of one of them.
    boundary = blob & ~cv2.erode(blob.astype(np.uint8), np.ones((3, 3), np.uint8), borderValue=0).astype(bool)
    yy, xx = np.nonzero(boundary)
    centres = np.stack([xx, yy], axis=1).astype(np.float64)
    d = np.sqrt(((p[:, None, :].astype(np.float64) - centres[None]) ** 2).sum(-1)).min(1)
    assert d.max() <= np.sqrt(0.5) + 1e-4, d.max()
    on_border = blob[0].any() or blob[-1].any() or blob[:, 0].any() or blob[:, -1].any()
    assert c.touches_border == on_border


# ------------------------------------------------------------------ strategies

sizes = st.tuples(st.integers(1, 40), st.integers(1, 40))


@st.composite
def shapes_mask(draw):
    """A canvas with a few rectangles, ellipses, lines, single pixels and holes, some on the border."""
    h, w = draw(sizes)
    m = np.zeros((h, w), np.uint8)
    for _ in range(draw(st.integers(0, 5))):
        kind = draw(st.sampled_from(["rect", "ellipse", "line", "pixel", "hole", "border"]))
        x0, x1 = sorted(draw(st.tuples(st.integers(-3, w + 2), st.integers(-3, w + 2))))
        y0, y1 = sorted(draw(st.tuples(st.integers(-3, h + 2), st.integers(-3, h + 2))))
        if kind == "rect":
            cv2.rectangle(m, (x0, y0), (x1, y1), 1, -1)
        elif kind == "ellipse":
            cv2.ellipse(m, ((x0 + x1) // 2, (y0 + y1) // 2), (max(x1 - x0, 1), max(y1 - y0, 1)), 0, 0, 360, 1, -1)
        elif kind == "line":  # one pixel thin, any direction
            cv2.line(m, (x0, y0), (x1, y1), 1, 1, lineType=cv2.LINE_8)
        elif kind == "pixel":
            m[draw(st.integers(0, h - 1)), draw(st.integers(0, w - 1))] = 1
        elif kind == "hole":
            cv2.rectangle(m, (x0, y0), (x1, y1), 0, -1)
        else:  # a band along one image edge
            side = draw(st.integers(0, 3))
            k = draw(st.integers(1, 3))
            (m.__setitem__((slice(0, k), slice(None)), 1) if side == 0 else
             m.__setitem__((slice(h - k, h), slice(None)), 1) if side == 1 else
             m.__setitem__((slice(None), slice(0, k)), 1) if side == 2 else
             m.__setitem__((slice(None), slice(w - k, w)), 1))
    return m


@FUZZ
@given(mask=shapes_mask())
def test_shapes_holes_lines_pixels_and_border_blobs(mask):
    check_contour(mask)


@FUZZ
@given(mask=arrays(np.bool_, sizes, elements=st.booleans()))
def test_random_masks_up_to_40_px(mask):
    check_contour(mask)


@FUZZ
@given(
    mask=shapes_mask(),
    dtype=st.sampled_from([np.bool_, np.uint8, np.int8, np.uint16, np.int32, np.int64, np.float32, np.float64]),
    layout=st.sampled_from(["c", "fortran", "transposed", "reversed", "strided"]),
    scale=st.sampled_from([1, -1, 255, 0.5]),
)
def test_dtypes_and_memory_layouts_give_the_same_contour(mask, dtype, layout, scale):
    """Non-zero is foreground for any dtype; the memory layout never matters."""
    m = (mask * scale).astype(dtype)
    ref = mask
    if layout == "fortran":
        m = np.asfortranarray(m)
    elif layout == "transposed":
        m, ref = np.ascontiguousarray(m.T).T, mask  # same values, transposed memory
    elif layout == "reversed":
        m, ref = m[::-1, ::-1], mask[::-1, ::-1]
    elif layout == "strided":
        big = np.zeros((m.shape[0] * 2, m.shape[1] * 3), dtype)
        big[::2, ::3] = m
        m = big[::2, ::3]
    check_contour(m)
    if (m != 0).any():  # (scale 0.5 in an integer dtype empties the mask)
        np.testing.assert_array_equal(extract_contour(m, N).points, extract_contour(np.ascontiguousarray(ref), N).points)


@settings(max_examples=40, deadline=1000, derandomize=True)
@given(k=st.integers(1, 5), mask=shapes_mask())
def test_stacks_name_the_empty_view(k, mask):
    masks = np.stack([mask] * k)
    if not mask.any():
        with pytest.raises(EmptyMaskError, match=f"mask 0 of {k}"):
            extract_contours(masks, N)
        return
    out = extract_contours(masks, N)
    assert out["points"].shape == (k, N, 2) and np.all(np.isfinite(out["points"]))


@pytest.mark.parametrize("bad", [np.zeros(5), np.zeros((2, 3, 4)), np.zeros(()), np.zeros((0, 5)), np.zeros((5, 0))])
def test_wrong_dimensions_raise_value_error(bad):
    with pytest.raises(ValueError):  # EmptyMaskError is a ValueError
        extract_contour(bad, N)


def test_nan_in_a_float_mask_counts_as_foreground_like_numpy_nonzero():
    m = np.zeros((5, 5))
    m[2, 2] = np.nan
    c = extract_contour(m, N)
    assert c.area == 1 and np.allclose(c.points, [2, 2])


_EXTREME = r"""
import numpy as np
from silpose.shared.contours import extract_contour
rng = np.random.default_rng(0)
masks = [
    np.ones((1, 1)), np.ones((1, 20000)), np.ones((20000, 1)), np.ones((2000, 2000), bool),
    rng.random((1500, 1500)) < 0.5,  # about 10^5 tiny blobs
    np.indices((1200, 1200)).sum(0) % 2 == 0,  # checkerboard: one huge 8-connected blob with 720,000 holes
    np.eye(3000, dtype=bool), np.eye(3000, dtype=bool)[::-1],
]
for m in masks:
    c = extract_contour(m, 200)
    assert np.all(np.isfinite(c.points))
print("survived", flush=True)
"""


def test_extreme_masks_do_not_crash_or_hang_the_interpreter():
    r = subprocess.run([sys.executable, "-c", _EXTREME], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "survived" in r.stdout, (r.returncode, r.stderr[-3000:])
