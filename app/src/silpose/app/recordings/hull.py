"""Multi-view consistency of a person's silhouettes: each view's foreground cut down to the person's visual hull.

Background subtraction against plates shot earlier also finds whatever changed since -- a prop, a lamp, someone
standing still at the back. When such clutter touches a person in one camera's image, their blob holds it and
may reach the image border, and the view is lost ("border", "clutter"), although the other cameras see the
person clear of it. Clutter in one camera has no support in the others; the person has. So, per detected person
(floor point ``xy``, :mod:`.floor`), silpose carves a coarse voxel volume -- the cylinder of radius
:data:`~.views.BODY_RADIUS_M` and height :data:`~.views.BODY_HEIGHT_M` standing at ``xy``, the volume the view
rules already allow a person (:func:`~.views.body_box`) -- in cubes of :data:`VOXEL_M`:

- a camera *sees* a voxel when its centre projects inside the image, in front of the camera (cameras with no
  mask this step, or an empty one, see nothing: they say nothing);
- a voxel is *foreground* in a camera when some foreground pixel lies within ``r`` px (a square window,
  Chebyshev distance) of its centre's image, ``r`` = the camera's :func:`footprint_px`: the projected
  half-diagonal of a voxel at the workspace centre, so a limb thinner than a voxel is not carved away
  between voxel centres (a conservative hull);
- a voxel is *kept* when every camera that sees it finds it foreground, and at least 2 cameras see it. Letting
  one camera miss it where at least three others agree (the floor grid's tolerant rule, :mod:`.floor`) was tried
  and rejected: plates shot earlier leave clutter in several
  cameras at once, and two cameras whose masks are mostly clutter then agree with any third about almost the
  whole cylinder. Measured on Pose2Sim's single-person demo (docs/real-recordings.md, section 1: cam01 and cam02
  mostly clutter), person-frames with >= 3 / 4 usable views: 88 / 17 % with one miss allowed, 95 / 71 % with
  none (0 / 0 % uncut). Holes smaller than the footprint (above) are closed by it; a larger hole in one camera
  (clothes the colour of the background) carves that part of the person from every view.

Each camera's *support* is the image of the kept voxels of every person: their centres' pixels dilated by
``r + SLACK_PX``. The pipeline (for colour videos; mask videos with ``carve=True``, ``--carve``) intersects the
camera's mask with its support before the blobs are labelled and
the view rules (:func:`~.views.assign_views`) judge them: clutter with no support is cut off; a person really cut
by the image border still touches it ("border"); two people whose hulls overlap in the image still share a blob
("merged"). The share of the person's original blob that was cut is reported per view (``view_cut``,
:mod:`.writers`).

Cost: the voxel centres of the room (the floor grid's area plus the cylinder's radius) are projected into each
camera once, lazily, in tiles of :data:`TILE` x :data:`TILE` columns when a person first comes near them
(projection through a distorted lens is ~2 us per point, so a room of ~300,000 voxels would cost seconds up
front; measured on the Pose2Sim rig, loaded machine: 0.4-1.9 s for the first person's ~60,000 voxels x 4
cameras, then nothing); per step and person, camera after camera, a lookup of the voxels no camera has rejected
yet (~47,000 in the cylinder at first, a few thousand at the end), and per camera a dilation of the mask and of
the support over the people's pixels and a second labelling. Measured with ``python -m benchmarks.run --only
recordings`` (the lab recording, two walkers, four 644x486 mask videos, 150 steps, carving forced on -- it is off by
default for mask videos, ``RecordingOptions.carve`` -- each carved run next to an uncut one in the same session, six sessions at load 2.5-12 while the code was made faster): CPU per step 1.24x
to 1.96x the uncut run's (last three: 23.2 vs 17.2 ms at load 6-8, 32.3 vs 22.3 ms at load 2.5-5, 30.2 vs 16.9 ms
at load 3), time steps/s 0.34x to 0.91x (last three: 0.91x, 0.54x, 0.56x: 31.8 vs 56.3 -- the carving's per-step
work is serial, the cameras' is threaded, so the wall-time cost is largest on an idle machine); the same joints in every session (70 % of person-frames with >= 3
views, 9.09 cm world error, either way).
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .views import BODY_HEIGHT_M, BODY_RADIUS_M

#: metres: side of the carving's cubes (at the working resolution a 1.75 m person is ~160 px tall, so a voxel
#: is ~4-5 px)
VOXEL_M = 0.05
#: pixels added to the support's dilation beyond a voxel's footprint (rounding of the centres' pixels)
SLACK_PX = 2
#: columns per side of the lazily projected tiles
TILE = 8


def footprint_px(cam, centre_xy, voxel: float = VOXEL_M) -> int:
    """Pixels (>= 1, rounded up) of a voxel's projected half-diagonal, ``sqrt(3) / 2 * voxel * f / depth``, at the
    workspace centre ``centre_xy`` (2,) 1 m above the floor in camera ``cam``."""
    depth = float(cam.to_camera(np.array([[centre_xy[0], centre_xy[1], 1.0]]))[0, 2])
    if not depth > 0:
        return 1
    return max(1, int(math.ceil(0.5 * math.sqrt(3.0) * voxel * float(cam.K[0, 0]) / depth)))


class PersonHulls:
    """The carving of the module docstring over one rig's room.

    Args:
        cameras: the cameras (``Camera``, at the masks' resolution), in the order masks are given.
        bounds: ((x_min, x_max), (y_min, y_max)) metres where people can be found (the floor grid's area);
            voxels cover it plus ``radius``.
        centre: (2,) metres, where :func:`footprint_px` is measured (the workspace centre).
        voxel, radius, height: metres.
    Attributes:
        xs (nx,), ys (ny,), zs (nz,): voxel centres, metres; footprint: (K,) px per camera.
    """

    def __init__(self, cameras, bounds, centre, voxel: float = VOXEL_M, radius: float = BODY_RADIUS_M,
                 height: float = BODY_HEIGHT_M):
        (x0, x1), (y0, y1) = bounds
        self.cameras = list(cameras)
        self.voxel, self.radius = float(voxel), float(radius)
        pad = self.radius + self.voxel
        self.xs = np.arange(x0 - pad, x1 + pad + 1e-9, self.voxel)
        self.ys = np.arange(y0 - pad, y1 + pad + 1e-9, self.voxel)
        self.zs = np.arange(0.5 * self.voxel, float(height), self.voxel)
        ny, nx, nz = len(self.ys), len(self.xs), len(self.zs)
        self.footprint = np.array([footprint_px(c, centre, self.voxel) for c in self.cameras], int)
        # per camera: (ny, nx, nz) flat pixel index of each voxel centre, H * W (a padding pixel that is never
        # foreground) where the camera does not see it; filled tile by tile (_ensure)
        self.index = [np.zeros((ny, nx, nz), np.int32) for _ in self.cameras]
        self.ready = np.zeros((-(-ny // TILE), -(-nx // TILE)), bool)
        # per camera and tile: x0, y0, x1, y1 px (exclusive) of its seen voxel centres (empty: x0 >= x1)
        self.tile_box = [np.zeros(self.ready.shape + (4,), np.int32) for _ in self.cameras]
        self._fg: list[np.ndarray | None] = [None] * len(self.cameras)  # per camera: its dilated mask, flat + 1

    # -- geometry ---------------------------------------------------------------------------------------------
    def _ensure(self, r0: int, r1: int, c0: int, c1: int) -> None:
        """Project the voxel columns of every tile overlapping rows r0:r1, columns c0:c1 that is not yet done."""
        t = np.argwhere(~self.ready[r0 // TILE : (r1 - 1) // TILE + 1, c0 // TILE : (c1 - 1) // TILE + 1])
        if not len(t):
            return
        t += (r0 // TILE, c0 // TILE)
        ny, nx = len(self.ys), len(self.xs)
        rows, cols, starts = [], [], []
        nz = len(self.zs)
        for tr, tc in t:
            rr, cc = np.meshgrid(np.arange(tr * TILE, min(ny, tr * TILE + TILE)),
                                 np.arange(tc * TILE, min(nx, tc * TILE + TILE)), indexing="ij")
            starts.append(sum(len(r) for r in rows) * nz)  # each tile's voxels are one run of the points below
            rows.append(rr.ravel())
            cols.append(cc.ravel())
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        pts = np.stack([np.repeat(self.xs[cols], nz), np.repeat(self.ys[rows], nz), np.tile(self.zs, len(rows))], -1)
        for k, cam in enumerate(self.cameras):
            w, h = cam.width, cam.height
            flat = self._flat_index(cam, pts)
            self.index[k][rows, cols] = flat.reshape(len(rows), nz)
            seen = flat < w * h
            x, y = flat % w, flat // w
            lo = np.stack([np.minimum.reduceat(np.where(seen, x, w), starts), np.minimum.reduceat(np.where(seen, y, h), starts)], -1)
            hi = np.stack([np.maximum.reduceat(np.where(seen, x + 1, 0), starts),
                           np.maximum.reduceat(np.where(seen, y + 1, 0), starts)], -1)
            self.tile_box[k][t[:, 0], t[:, 1]] = np.concatenate([lo, hi], -1)
        self.ready[t[:, 0], t[:, 1]] = True

    @staticmethod
    def _flat_index(cam, pts: np.ndarray) -> np.ndarray:
        """(N,) int32 ``y * W + x`` of the rounded images of world points ``pts`` (N, 3); ``W * H`` where unseen."""
        depth = cam.to_camera(pts)[:, 2]
        with np.errstate(invalid="ignore"):
            px = np.round(cam.project(pts))
            seen = (depth > 0) & np.isfinite(px).all(axis=1)
            x, y = np.where(seen, px[:, 0], -1), np.where(seen, px[:, 1], -1)
        seen &= (x >= 0) & (x < cam.width) & (y >= 0) & (y < cam.height)
        flat = np.where(seen, y * cam.width + x, cam.width * cam.height)
        return flat.astype(np.int32)

    def _box(self, xy) -> tuple:
        """Rows, columns of the voxel columns around floor point ``xy`` (2,) and the (rows, cols) bool mask of those
        within the radius (the tiles they need are projected)."""
        x, y = float(xy[0]), float(xy[1])
        c0 = max(0, int(np.searchsorted(self.xs, x - self.radius)))
        c1 = min(len(self.xs), int(np.searchsorted(self.xs, x + self.radius, side="right")))
        r0 = max(0, int(np.searchsorted(self.ys, y - self.radius)))
        r1 = min(len(self.ys), int(np.searchsorted(self.ys, y + self.radius, side="right")))
        if r0 >= r1 or c0 >= c1:
            return slice(0, 0), slice(0, 0), np.zeros((0, 0), bool)
        self._ensure(r0, r1, c0, c1)
        inside = (self.xs[None, c0:c1] - x) ** 2 + (self.ys[r0:r1, None] - y) ** 2 <= self.radius**2
        return slice(r0, r1), slice(c0, c1), inside

    def centres(self, xy) -> np.ndarray:
        """(rows, cols, nz, 3) metres: the voxel centres of the box around floor point ``xy`` (2,) (as :meth:`keep`'s
        arrays)."""
        rs, cs, _ = self._box(xy)
        X, Y, Z = np.meshgrid(self.ys[rs], self.xs[cs], self.zs, indexing="ij")
        return np.stack([Y, X, Z], -1)

    # -- per step ---------------------------------------------------------------------------------------------
    def prepare(self, people_xy) -> list:
        """The boxes of the people at floor points ``people_xy`` (P, 2), their tiles projected (call before
        :meth:`evidence` runs in threads; the other methods take these boxes). A box is (rows, cols, inside,
        where): the voxel columns' row and column slices, the (rows, cols) bool mask of those within the radius,
        and the (rows * cols * nz,) positions of the box's voxels in the room grid (flattened)."""
        out = []
        ny, nx, nz = self.index[0].shape if self.index else (0, 0, 0)
        for xy in np.asarray(people_xy, float).reshape(-1, 2):
            rs, cs, inside = self._box(xy)
            r = np.arange(rs.start, rs.stop)[:, None, None]
            c = np.arange(cs.start, cs.stop)[None, :, None]
            where = ((r * nx + c) * nz + np.arange(nz)[None, None, :]).reshape(-1)
            out.append((rs, cs, inside, where))
        return out

    def _roi(self, k: int, boxes, pad: int, shape) -> tuple[int, int, int, int]:
        """x0, y0, x1, y1 px (exclusive, clipped to ``shape`` (H, W)): camera ``k``'s pixels of every voxel of
        ``boxes``, ``pad`` px around them."""
        h, w = shape
        x0, y0, x1, y1 = w, h, 0, 0
        for rs, cs, _, _ in boxes:
            tb = self.tile_box[k][rs.start // TILE : (rs.stop - 1) // TILE + 1, cs.start // TILE : (cs.stop - 1) // TILE + 1]
            if tb.size:
                x0, y0 = min(x0, int(tb[..., 0].min())), min(y0, int(tb[..., 1].min()))
                x1, y1 = max(x1, int(tb[..., 2].max())), max(y1, int(tb[..., 3].max()))
        return max(0, x0 - pad), max(0, y0 - pad), min(w, x1 + pad), min(h, y1 + pad)

    def evidence(self, k: int, mask: np.ndarray | None, boxes) -> bool:
        """Take camera ``k``'s (H, W) mask (non-zero = foreground) for :meth:`keep`: dilated by its footprint over the
        pixels of :meth:`prepare`'s ``boxes``. False (the camera says nothing) for None or an empty mask.
        Thread-safe for distinct ``k``."""
        if mask is None or not mask.any():
            return False
        r = int(self.footprint[k])
        h, w = mask.shape
        if self._fg[k] is None or self._fg[k].size != h * w + 1:
            self._fg[k] = np.zeros(h * w + 1, np.uint8)  # the last pixel: unseen voxels, never foreground
        x0, y0, x1, y1 = self._roi(k, boxes, 0, mask.shape)
        if x0 < x1 and y0 < y1:
            ex0, ey0, ex1, ey1 = max(0, x0 - r), max(0, y0 - r), min(w, x1 + r), min(h, y1 + r)
            dil = cv2.dilate((mask[ey0:ey1, ex0:ex1] > 0).view(np.uint8), np.ones((2 * r + 1, 2 * r + 1), np.uint8))
            # pixels outside this step's boxes keep older values: no voxel of these boxes reads them
            self._fg[k][:-1].reshape(h, w)[y0:y1, x0:x1] = dil[y0 - ey0 : y1 - ey0, x0 - ex0 : x1 - ex0]
        return True

    def keep(self, live, boxes) -> list[np.ndarray]:
        """Per box: the kept voxels (module docstring) as (N,) positions in the room grid (flattened; :meth:`in_box`
        makes them a (rows, cols, nz) bool array), from the cameras ``live`` (K,) bool whose :meth:`evidence` was
        taken this step. Camera after camera, only the voxels no camera has rejected yet are looked up (a person
        fills a few per cent of their cylinder)."""
        cams = [k for k, ok in enumerate(live) if ok]
        out = []
        for rs, cs, inside, where in boxes:
            nz = len(self.zs)
            alive = where[np.repeat(inside.reshape(-1), nz)]  # the room-grid positions of the cylinder's voxels
            seen = np.zeros(len(alive), np.uint8)
            for k in cams:
                idx = self.index[k].reshape(-1)[alive]
                sentinel = self._fg[k].size - 1
                sees = idx != sentinel
                ok = self._fg[k][idx].view(bool) | ~sees
                alive, seen = alive[ok], seen[ok] + sees[ok]
            out.append(alive[seen >= 2])
        return out

    @staticmethod
    def in_box(kept: np.ndarray, box) -> np.ndarray:
        """(rows, cols, nz) bool: :meth:`keep`'s positions ``kept`` (N,) of one of :meth:`prepare`'s boxes, as the
        box's voxels (as :meth:`centres`)."""
        rs, cs, inside, where = box
        return np.isin(where, kept).reshape(inside.shape + (-1,))

    def support(self, k: int, kept: list[np.ndarray], boxes, shape: tuple[int, int]) -> np.ndarray:
        """(H, W) uint8 {0, 1}: the image in camera ``k`` of the kept voxels of every box (``kept``: :meth:`keep`'s
        positions), dilated by the footprint plus :data:`SLACK_PX` (``shape`` = (H, W) of the camera's masks)."""
        h, w = shape
        img = np.zeros(h * w + 1, np.uint8)
        for keep in kept:
            img[self.index[k].reshape(-1)[keep]] = 1
        img = img[:-1].reshape(h, w)
        r = int(self.footprint[k]) + SLACK_PX
        x0, y0, x1, y1 = self._roi(k, boxes, r, shape)
        out = np.zeros((h, w), np.uint8)
        if x0 < x1 and y0 < y1:
            out[y0:y1, x0:x1] = cv2.dilate(img[y0:y1, x0:x1], np.ones((2 * r + 1, 2 * r + 1), np.uint8))
        return out

    def carve(self, masks: list, people_xy) -> list[np.ndarray | None]:
        """Every camera's support (:meth:`support`) of the people at floor points ``people_xy`` (P, 2), from the
        cameras' (H, W) masks (None: no mask); None for a camera without a mask, and for every camera when fewer
        than 2 masks have foreground (nothing to compare)."""
        boxes = self.prepare(people_xy)
        live = [self.evidence(k, m, boxes) for k, m in enumerate(masks)]
        if sum(live) < 2:
            return [None] * len(masks)
        kept = self.keep(live, boxes)
        return [None if m is None else self.support(k, kept, boxes, m.shape) for k, m in enumerate(masks)]
