"""What a person looks like in each camera: the cue that tells people apart where their motion cannot.

Observation (:func:`observe`), from one camera's blob of a person standing alone in that view (view status
``ok``, :mod:`.views`), the person at floor point (x, y) metres:

- ``stature``, metres: the height above the floor at which the vertical through (x, y) meets the ray of the
  blob's top row (closed form: with ``K (R X + t) = a + z b`` for ``X = (x, y, z)``, the image row ``v`` of
  height ``z`` is ``(a_1 + z b_1) / (a_2 + z b_2)``, so ``z = (v a_2 - a_1) / (b_1 - v b_2)``). Independent of the
  distance to the camera and of its tilt; off by the floor point's error times the ray's slope.
- ``width``, metres: the blob's area over its height (mean width, px) at the person's depth (the camera depth of
  (x, y, :data:`WIDTH_AT_M`)): ``width_px * depth / fx``. Varies with the gait and the heading.
- ``colour`` (colour videos only): (2, :data:`HIST_BINS` ** 3) histograms of the blob's pixels in BGR, quantised to
  :data:`HIST_BINS` levels per channel, of its upper and lower parts (rows above / below the share
  :data:`UPPER_SHARE` of its height from the top: shirt and trousers), each summing to 1; None for mask videos.

Model (:class:`PersonLooks`): per camera, running means of the three cues (the first :data:`MEMORY` observations
averaged, then an exponential mean with weight ``1 / MEMORY``: slow, so a few wrong views do not turn it into
someone else) and their counts.

Distance (:meth:`PersonLooks.distance`) of an observation (one per camera, None where the view is not the
person's alone) to the model: the mean, over the cues and cameras both have, of the squared standardised
differences -- ``((stature - s) / STATURE_SD_M)^2``, ``(ln(width / w) / WIDTH_SD)^2`` and, per part, ``(b /
COLOUR_SD)^2`` with ``b`` the Bhattacharyya distance ``sqrt(1 - sum sqrt(p q))`` of the histograms -- each capped
at :data:`CAP`. A camera the model has no observation from is compared with the model's mean over its
cameras (statures and widths in metres agree across cameras). About 1 for the same person, larger for someone
else; NaN when nothing is comparable. Masks carry statures and widths only; the cue is then weaker, never
missing. The spreads: measured on the lab recording's walkers (:data:`silpose.datagen.lab.FOUR_WALKERS`, each
one's own clean masks, every 4th frame, 5 cm of noise on the floor point): statures 1.3-1.7 cm per view within
a walker, means within 1 cm of the true statures in every camera -- 2 cm allows for a real segmentation;
widths 6-13 % (log) within a walker, 28-34 cm between them. Colours (the colour videos' frames inside each
walker's own mask, views where nobody else is within 2 px): Bhattacharyya distance to the walker's mean
0.06 / 0.09 median (upper / lower part), 0.11 / 0.13 at the 90th percentile; to another walker's mean 0.21 /
0.91 median (three of the four shirts are the same blue). :data:`COLOUR_SD` 0.1 instead of 0.2 gave 16 identity
switches instead of 10 on the colour videos (the segmented blobs' histograms -- shadows, mixed edges, blobs of
two walkers the floor grid saw as one -- spread more than the clean ones).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .blobs import Blobs

#: quantisation levels per BGR channel of the colour histograms
HIST_BINS = 4
#: share of a blob's height, from its top, that is its upper part (shirt; the hips of an adult are at ~47 %)
UPPER_SHARE = 0.45
#: metres: height whose camera depth scales the blob's width
WIDTH_AT_M = 0.9
#: within-person spreads of one view's cues (standardisation of :meth:`PersonLooks.distance`): stature,
#: metres; width, natural log; colour, Bhattacharyya distance
STATURE_SD_M, WIDTH_SD, COLOUR_SD = 0.02, 0.15, 0.2
#: squared standardised differences are capped here (one wild view does not decide)
CAP = 16.0
#: observations averaged before the model becomes an exponential mean with weight 1 / MEMORY
MEMORY = 50
#: once a camera's model holds SETTLED observations, an observation of that camera farther than OUTLIER from it
#: (:meth:`PersonLooks.distance`) is not learnt: a blob that holds someone else too (two people the floor grid
#: saw as one) does not make the person look like the other
SETTLED, OUTLIER = 5, 9.0


@dataclass
class Look:
    """One view of one person: stature, width (metres), colour ((2, HIST_BINS ** 3) or None)."""

    stature: float
    width: float
    colour: np.ndarray | None = None


#: metres: heights on the vertical where a camera with a lens is projected to find a row's height (5 cm apart)
LENS_HEIGHTS_M = np.linspace(0.0, 3.0, 61)


def stature_at(cam, xy: np.ndarray, row: float) -> float:
    """Metres: height at which the vertical through floor point ``xy`` (2,) projects to image row ``row`` (px).

    Without lens distortion, the pinhole's closed form; with it (``dist`` or a fisheye), the rows of
    :data:`LENS_HEIGHTS_M` through ``cam.project``, interpolated (NaN where they do not fall steadily with height)."""
    if getattr(cam, "fisheye", False) or np.any(np.asarray(cam.dist)):
        pts = np.column_stack([np.full(LENS_HEIGHTS_M.size, xy[0]), np.full(LENS_HEIGHTS_M.size, xy[1]), LENS_HEIGHTS_M])
        rows = cam.project(pts)[:, 1]
        if not (np.all(np.isfinite(rows)) and np.all(np.diff(rows) < 0)) or not rows[-1] <= row <= rows[0]:
            return float("nan")
        return float(np.interp(row, rows[::-1], LENS_HEIGHTS_M[::-1]))
    P = np.asarray(cam.K, float) @ np.asarray(cam.R, float)
    a = P @ np.array([xy[0], xy[1], 0.0]) + np.asarray(cam.K, float) @ np.asarray(cam.t, float).ravel()
    b = P[:, 2]
    den = b[1] - row * b[2]
    return float((row * a[2] - a[1]) / den) if abs(den) > 1e-12 else float("nan")


def colour_histograms(pixels: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(2, HIST_BINS ** 3): BGR histograms of ``pixels`` (N, 3) uint8, upper ones (``upper`` (N,) bool) and the
    rest, each normalised to sum 1 (zeros when a part has no pixel)."""
    q = (np.asarray(pixels, np.int64) * HIST_BINS) // 256
    code = (q[:, 0] * HIST_BINS + q[:, 1]) * HIST_BINS + q[:, 2]
    out = np.zeros((2, HIST_BINS ** 3))
    for i, sel in enumerate((upper, ~upper)):
        h = np.bincount(code[sel], minlength=HIST_BINS ** 3).astype(float)
        out[i] = h / h.sum() if h.sum() > 0 else h
    return out


def blob_histograms(frame: np.ndarray, blobs: Blobs, label: int) -> np.ndarray:
    """:func:`colour_histograms` of blob ``label``'s pixels in ``frame`` (H, W, 3) uint8 BGR, its upper part the rows
    above :data:`UPPER_SHARE` of its box's height: the same counts by ``cv2.calcHist`` on the box, the blob its mask
    (a 28,000 px blob: 0.18 ms, against 1.2 ms for gathering its pixels first)."""
    x, y, w, h = (int(v) for v in blobs.bbox[label])
    ox, oy = blobs.origin
    mask = np.empty((h, w), np.uint8)
    np.equal(blobs.labels[y - oy : y - oy + h, x - ox : x - ox + w], label, out=mask.view(bool))
    img = frame[y : y + h, x : x + w]
    split = int(np.ceil(UPPER_SHARE * h))  # rows r < UPPER_SHARE h are the upper part
    out = np.zeros((2, HIST_BINS ** 3))
    for i, rows in enumerate((slice(0, split), slice(split, h))):
        part = np.ascontiguousarray(img[rows])
        if not part.size:
            continue
        hist = cv2.calcHist([part], [0, 1, 2], np.ascontiguousarray(mask[rows]), [HIST_BINS] * 3, [0, 256] * 3)
        hist = hist.ravel().astype(np.float64)  # bins (b, g, r) in C order: colour_histograms' codes
        total = hist.sum()
        out[i] = hist / total if total > 0 else hist
    return out


def observe(cam, blobs: Blobs, label: int, xy: np.ndarray, frame: np.ndarray | None = None) -> Look | None:
    """The :class:`Look` of blob ``label`` of ``blobs`` (the person at floor point ``xy`` (2,) metres, alone in
    the view) in camera ``cam`` (at the masks' resolution); ``frame`` (H, W, 3) uint8 BGR at that resolution for
    the colour histograms (None: masks). None when the person is behind the camera."""
    xy = np.asarray(xy, float)
    x, y, w, h = (int(v) for v in blobs.bbox[label])
    depth = float(cam.to_camera(np.array([[xy[0], xy[1], WIDTH_AT_M]]))[0, 2])
    if depth <= 0 or h <= 0:
        return None
    stature = stature_at(cam, xy, y - 0.5)  # the top edge of the top row
    width = float(blobs.area[label]) / h * depth / float(cam.K[0, 0])
    colour = blob_histograms(frame, blobs, label) if frame is not None else None
    return Look(stature, width, colour)


def _bhattacharyya(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(parts,) Bhattacharyya distances of histograms ``p``, ``q`` (parts, bins) each summing to 1."""
    return np.sqrt(np.clip(1.0 - np.sqrt(p * q).sum(axis=-1), 0.0, 1.0))


class PersonLooks:
    """One person's appearance per camera (module docstring). K: cameras."""

    def __init__(self, n_cameras: int):
        K = int(n_cameras)
        self.count = np.zeros(K, int)
        self.stature = np.zeros(K)
        self.width = np.zeros(K)
        self.colour: np.ndarray | None = None  # (K, 2, bins)
        self.colour_count = np.zeros(K, int)

    @property
    def seen(self) -> bool:
        return bool(self.count.any())

    def update(self, looks: list[Look | None]) -> None:
        """Add one step's observations, one per camera (None: no view of the person alone); outliers of a settled
        camera are left out (:data:`OUTLIER`)."""
        for k, o in enumerate(looks):
            if o is None or not np.isfinite(o.stature) or o.width <= 0:
                continue
            if self.count[k] >= SETTLED and self.distance([o if j == k else None for j in range(len(looks))]) > OUTLIER:
                continue
            self.count[k] += 1
            a = 1.0 / min(self.count[k], MEMORY)
            self.stature[k] += a * (o.stature - self.stature[k])
            self.width[k] += a * (o.width - self.width[k])
            if o.colour is not None:
                if self.colour is None:
                    self.colour = np.zeros((len(self.count),) + o.colour.shape)
                self.colour_count[k] += 1
                a = 1.0 / min(self.colour_count[k], MEMORY)
                self.colour[k] += a * (o.colour - self.colour[k])

    def views(self) -> list[Look | None]:
        """The model's means as one observation per camera (None where it has none): to compare two models."""
        return [Look(float(self.stature[k]), float(self.width[k]),
                     None if self.colour is None or not self.colour_count[k] else self.colour[k].copy())
                if self.count[k] else None for k in range(len(self.count))]

    def distance(self, looks: list[Look | None]) -> float:
        """Mean capped squared standardised difference of the observations ``looks`` (one per camera) to the
        model (module docstring); NaN when nothing is comparable."""
        if not self.seen:
            return float("nan")
        n = self.count.astype(float)
        pooled_s = float((n * self.stature).sum() / n.sum())
        pooled_w = float((n * self.width).sum() / n.sum())
        terms = []
        for k, o in enumerate(looks):
            if o is None or not np.isfinite(o.stature) or o.width <= 0:
                continue
            s, w = (self.stature[k], self.width[k]) if self.count[k] else (pooled_s, pooled_w)
            terms.append(((o.stature - s) / STATURE_SD_M) ** 2)
            terms.append((np.log(o.width / max(w, 1e-6)) / WIDTH_SD) ** 2)
            if o.colour is not None and self.colour is not None:
                if self.colour_count[k]:
                    ref = self.colour[k]
                else:
                    c = self.colour_count.astype(float)
                    ref = (c[:, None, None] * self.colour).sum(axis=0) / c.sum() if c.sum() else None
                if ref is not None:
                    terms += list((_bhattacharyya(o.colour, ref) / COLOUR_SD) ** 2)
        return float(np.mean(np.minimum(terms, CAP))) if terms else float("nan")
