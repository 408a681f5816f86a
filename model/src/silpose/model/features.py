"""The shape+structure vector (paper eq. 4) and its layout.

A shape vector is the selected views' *normalised* contours, each ``n x 2`` flattened as
``x0, y0, x1, y1, ...``, concatenated in the order of ``views``, followed by the 19 x 3
root-relative joints (``silpose.shared.skeleton.root_relative``, metres, world orientation)
flattened joint by joint (``x, y, z``) and multiplied by the *structure weight* ``w``::

    o = (c_1, ..., c_K, w * s_1, ..., w * s_z)          (paper eq. 4, d = 2 K n + 3 z)

The weight exists because the mixture of PPCA uses one isotropic noise variance per
component (docs/conventions.md, "Model"): the relative scale of the contour block (normalised units: RMS
distance of the points from their centroid = 1) and the structure block (metres) changes the
fit, so ``w`` is a hyperparameter chosen on validation joint error (``silpose.model.selection``).

:func:`shape_vectors` builds the vectors from pixel contours (the in-memory and the streaming fit
both call it); :func:`normalise_contours` is the contour normalisation every model input goes
through (docs/conventions.md, "Contours").
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from typing import Iterable, Sequence

import numpy as np

from silpose.shared.skeleton import N_JOINTS, root_relative

from .checks import check_contours
from .stature import REFERENCE_STATURE, estimate_stature
from .threads import THREADS, map_threads

LAYOUT_VERSION = 1
#: how the structure block's joints are scaled (see FeatureLayout.joint_frame); files without the
#: field predate it and are "metres"
JOINT_FRAMES = ("metres", "stature")


@dataclass(frozen=True)
class FeatureLayout:
    """Where each block lives in a shape vector.

    Attributes:
        views: rig view indices of the modelled views, in vector order.
        n_points: contour points per view (n).
        n_joints: number of joints (z), 19 for the silpose skeleton.
        structure_weight: factor ``w`` multiplying the root-relative joints (metres -> feature units).
        joint_frame: "metres" (joints as given) or "stature" (the caller has divided the root-relative
            joints by the walker's estimated stature / 1.75 m before ``build``, and multiplies ``split``'s
            joints back; ``silpose.model.stature``). Recorded here so a saved model says which.
    """

    views: tuple[int, ...]
    n_points: int
    n_joints: int = N_JOINTS
    structure_weight: float = 1.0
    joint_frame: str = "metres"

    def __post_init__(self) -> None:
        views = tuple(int(v) for v in self.views)
        object.__setattr__(self, "views", views)
        object.__setattr__(self, "structure_weight", float(self.structure_weight))
        if not views:
            raise ValueError("FeatureLayout.views must name at least one view")
        if len(set(views)) != len(views) or min(views) < 0:
            raise ValueError(f"FeatureLayout.views must be distinct non-negative indices, got {views}")
        if int(self.n_points) < 3:
            raise ValueError(f"FeatureLayout.n_points must be >= 3, got {self.n_points}")
        if int(self.n_joints) < 1:
            raise ValueError(f"FeatureLayout.n_joints must be >= 1, got {self.n_joints}")
        if not np.isfinite(self.structure_weight) or self.structure_weight <= 0:
            raise ValueError(f"FeatureLayout.structure_weight must be finite and > 0, got {self.structure_weight}")
        if self.joint_frame not in JOINT_FRAMES:
            raise ValueError(f"FeatureLayout.joint_frame must be one of {JOINT_FRAMES}, got {self.joint_frame!r}")

    # ------------------------------------------------------------------ sizes and slices
    @property
    def n_views(self) -> int:
        return len(self.views)

    @property
    def view_dim(self) -> int:
        """Dimensions of one view's contour block (2 n)."""
        return 2 * self.n_points

    @property
    def contour_dim(self) -> int:
        """Dimensions of all contour blocks (2 K n)."""
        return self.n_views * self.view_dim

    @property
    def structure_dim(self) -> int:
        """Dimensions of the structure block (3 z)."""
        return 3 * self.n_joints

    @property
    def dim(self) -> int:
        """Total dimension d = 2 K n + 3 z."""
        return self.contour_dim + self.structure_dim

    def view_slice(self, position: int) -> slice:
        """Slice of the ``position``-th modelled view (0 <= position < n_views) in a shape vector."""
        if not 0 <= position < self.n_views:
            raise IndexError(f"view position {position} out of range for {self.n_views} modelled views")
        return slice(position * self.view_dim, (position + 1) * self.view_dim)

    def position_of(self, rig_view: int) -> int:
        """Position in the vector of rig view ``rig_view``; ValueError if it is not modelled."""
        try:
            return self.views.index(int(rig_view))
        except ValueError:
            raise ValueError(f"view {rig_view} is not modelled (modelled views: {self.views})") from None

    @property
    def structure_slice(self) -> slice:
        return slice(self.contour_dim, self.dim)

    # ------------------------------------------------------------------ masks
    def observed_mask(self, present: Sequence[bool] | np.ndarray) -> np.ndarray:
        """(d,) bool: True on the contour dimensions of the present views.

        Args:
            present: (n_views,) bool, one flag per *modelled* view (vector order).
        The structure block is never observed at inference (paper section 4).
        """
        present = np.asarray(present, dtype=bool)
        if present.shape != (self.n_views,):
            raise ValueError(f"present must have shape ({self.n_views},), got {present.shape}")
        mask = np.zeros(self.dim, dtype=bool)
        mask[: self.contour_dim] = np.repeat(present, self.view_dim)
        return mask

    def observed_mask_for_views(self, rig_views: Iterable[int]) -> np.ndarray:
        """(d,) bool observed mask for a subset of rig view indices (each must be modelled)."""
        present = np.zeros(self.n_views, dtype=bool)
        for v in rig_views:
            present[self.position_of(v)] = True
        return self.observed_mask(present)

    # ------------------------------------------------------------------ build / split
    def build(self, contours_norm: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """Shape vectors from normalised contours and joints (paper eq. 4).

        Args:
            contours_norm: (N, n_views, n_points, 2) normalised contours of the modelled views, vector order.
            joints: (N, n_joints, 3) joint positions in metres (absolute or root-relative; made root-relative here).
        Returns:
            (N, d) float64.
        """
        c = np.asarray(contours_norm, dtype=np.float64)
        j = np.asarray(joints, dtype=np.float64)
        if c.ndim != 4 or c.shape[1:] != (self.n_views, self.n_points, 2):
            raise ValueError(
                f"contours_norm must have shape (N, {self.n_views}, {self.n_points}, 2), got {c.shape}"
            )
        if j.ndim != 3 or j.shape[1:] != (self.n_joints, 3):
            raise ValueError(f"joints must have shape (N, {self.n_joints}, 3), got {j.shape}")
        if c.shape[0] != j.shape[0]:
            raise ValueError(f"contours_norm has {c.shape[0]} rows but joints has {j.shape[0]}")
        if self.n_joints == N_JOINTS:
            j = root_relative(j)
        n = c.shape[0]
        out = np.empty((n, self.dim), dtype=np.float64)
        out[:, : self.contour_dim] = c.reshape(n, -1)
        out[:, self.structure_slice] = self.structure_weight * j.reshape(n, -1)
        return out

    def split(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inverse of ``build``: (N, d) -> (contours (N, n_views, n_points, 2), joints (N, n_joints, 3) metres)."""
        X = np.asarray(X)
        if X.ndim != 2 or X.shape[1] != self.dim:
            raise ValueError(f"X must have shape (N, {self.dim}), got {X.shape}")
        n = X.shape[0]
        contours = X[:, : self.contour_dim].reshape(n, self.n_views, self.n_points, 2)
        joints = X[:, self.structure_slice].reshape(n, self.n_joints, 3) / self.structure_weight
        return contours, joints

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict:
        d = asdict(self)
        d["views"] = list(self.views)
        d["layout_version"] = LAYOUT_VERSION
        return d

    @classmethod
    def from_dict(cls, d: dict, source: str = "layout") -> "FeatureLayout":
        if not isinstance(d, dict):
            raise ValueError(f"{source}: feature layout must be a JSON object, got {type(d).__name__}")
        version = d.get("layout_version", LAYOUT_VERSION)
        if version != LAYOUT_VERSION:
            raise ValueError(f"{source}: feature layout version {version!r} is not supported (expected {LAYOUT_VERSION})")
        for key in ("views", "n_points", "n_joints", "structure_weight"):
            if key not in d:
                raise ValueError(f"{source}: feature layout is missing field {key!r}")
        try:
            return cls(
                views=tuple(int(v) for v in d["views"]),
                n_points=int(d["n_points"]),
                n_joints=int(d["n_joints"]),
                structure_weight=float(d["structure_weight"]),
                joint_frame=str(d.get("joint_frame", "metres")),
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{source}: invalid feature layout: {exc}") from None

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    @classmethod
    def from_json(cls, text: str, source: str = "layout") -> "FeatureLayout":
        try:
            d = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{source}: feature layout is not valid JSON: {exc}") from None
        return cls.from_dict(d, source)


#: contours per chunk of :func:`normalise_contours` and :func:`denormalise_contours`: a chunk's arrays (0.8 MB at
#: n 200) stay in a core's cache between the steps (on (1024, 4, 200, 2) batches ~1.5x faster than whole-array steps)
CHUNK_CONTOURS = 512
#: contours of a batch from which :func:`normalise_contours` and :func:`denormalise_contours` run their chunks on
#: ``silpose.model.threads.THREADS`` threads (``map_threads``; each chunk gives the same values on any thread): 2,000
#: frames of 4 views, the benchmark's batch, spent ~17 ms in these two passes on one core (9.0 + 7.4 ms CPU, load ~10),
#: about half of their work outside BLAS. Inside a block of ``Posterior.infer_in_blocks`` (already on a pool thread)
#: the chunks run in place
THREAD_CONTOURS = 4 * CHUNK_CONTOURS


def chunk_threads(n_contours: int) -> int:
    """Threads for the chunks of a pass over ``n_contours`` contours (:data:`THREAD_CONTOURS`)."""
    return THREADS if n_contours >= THREAD_CONTOURS else 1


def normalise_contours(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The normalisation of ``silpose.shared.contours.normalise`` in float64, arranged for batches.

    centroid c = mean of the points, scale s = RMS distance from c, q = (p - c) / s, and q = 0 with
    s = 0 for a degenerate contour. points (..., n, 2) px -> (q (..., n, 2), c (..., 2), s (...,)).
    Same definition as the shared function; its sums run in another order (strided row sums, one
    dot product per contour), which is ~10x faster on (N, K, 200, 2) batches and agrees to ~1e-15
    relative. Every model file was fitted through this arithmetic, so the model keeps it. Contours are
    normalised :data:`CHUNK_CONTOURS` at a time (each on its own: the same values), the chunks of a large batch on
    threads (:func:`chunk_threads`).
    """
    p = np.asarray(points, dtype=np.float64)
    lead, n = p.shape[:-2], p.shape[-2]
    f = p.reshape(-1, n, 2)
    q = np.empty(f.shape)
    c = np.empty((len(f), 2))
    s = np.empty(len(f))

    def chunk(a: int) -> None:
        b = min(a + CHUNK_CONTOURS, len(f))
        _normalise_chunk(f[a:b], q[a:b], c[a:b], s[a:b])

    map_threads(chunk, range(0, len(f), CHUNK_CONTOURS), chunk_threads(len(f)))
    return q.reshape(p.shape), c.reshape(*lead, 2), s.reshape(lead)


def _normalise_chunk(f: np.ndarray, q: np.ndarray, c: np.ndarray, s: np.ndarray) -> None:
    """:func:`normalise_contours` of contours f (m, n, 2) into q (m, n, 2), c (m, 2), s (m,)."""
    n = f.shape[1]
    np.divide(np.stack([f[:, :, 0].sum(axis=1), f[:, :, 1].sum(axis=1)], axis=-1), n, out=c)  # strided sums: fast
    # f - c: each point's (x, y) as one complex number (the same two subtractions; numpy's broadcast over a last axis
    # of 2 runs in inner loops of 2)
    fc = f.view(np.complex128) if f.flags.c_contiguous else None
    if fc is not None:
        np.subtract(fc, c.view(np.complex128)[:, None], out=q.view(np.complex128))
    else:
        np.subtract(f[..., 0], c[:, 0, None], out=q[..., 0])
        np.subtract(f[..., 1], c[:, 1, None], out=q[..., 1])
    flat = q.reshape(q.shape[0], -1)
    np.sqrt(np.einsum("ij,ij->i", flat, flat) / n, out=s)
    q /= np.where(s > 0, s, 1.0)[:, None, None]


def denormalise_contours(q: np.ndarray, centroid: np.ndarray, scale: np.ndarray,
                         out: np.ndarray | None = None) -> np.ndarray:
    """Inverse of :func:`normalise_contours` (``silpose.shared.contours.denormalise``): ``p = s q + c``, float64.

    q (..., n, 2), centroid (..., 2) px, scale (...,) px -> (..., n, 2) px. With matching shapes, about
    :data:`CHUNK_CONTOURS` contours at a time along the first axis (the same values; ``q`` may be a strided view,
    e.g. of the reconstructions' part of the shape vectors, and is not copied), the chunks of a large batch on threads
    (:func:`chunk_threads`). ``out``: a float64 array of ``q``'s shape to write to (and return), with matching shapes
    only; None = a new one.
    """
    q = np.asarray(q, dtype=np.float64)
    c = np.asarray(centroid, dtype=np.float64)
    sc = np.asarray(scale, dtype=np.float64)
    if q.ndim >= 3 and c.shape == q.shape[:-2] + (2,) and sc.shape == q.shape[:-2]:
        per_row = max(1, int(np.prod(q.shape[1:-2])))
        step = max(1, CHUNK_CONTOURS // per_row)
        if out is None:
            out = np.empty(q.shape)
        elif out.shape != q.shape or out.dtype != np.float64:
            raise ValueError(f"denormalise_contours: out must be float64 of shape {q.shape}, got {out.dtype} {out.shape}")

        def chunk(a: int) -> None:
            _denormalise_into(q[a:a + step], c[a:a + step], sc[a:a + step], out[a:a + step])

        map_threads(chunk, range(0, len(q), step), chunk_threads(len(q) * per_row))
        return out
    if out is not None:
        raise ValueError("denormalise_contours: out needs centroid and scale of the contours' leading shape")
    out = q * sc[..., None, None]
    out[..., 0] += c[..., 0, None]
    out[..., 1] += c[..., 1, None]
    return out


def _denormalise_into(q: np.ndarray, c: np.ndarray, s: np.ndarray, out: np.ndarray) -> None:
    """``out = s q + c`` for q (..., n, 2), c (..., 2), s (...,) of one shape (:func:`denormalise_contours`)."""
    np.multiply(q, s[..., None, None], out=out)
    # + c: each point's (x, y) as one complex number (the same two additions; numpy's broadcast over a last axis of 2
    # runs in inner loops of 2)
    out.view(np.complex128)[..., 0] += np.ascontiguousarray(c).view(np.complex128)


def shape_vectors(layout: FeatureLayout, n_rig_views: int, contours_px: np.ndarray, joints: np.ndarray,
                  rig=None) -> np.ndarray:
    """The training vectors (N, d) of the model (paper eq. 4).

    Args:
        layout: the vector layout (modelled views, structure weight, joint frame).
        n_rig_views: K, the views of the rig the contours are indexed by.
        contours_px: (N, K, n, 2) pixel contours; the modelled views are normalised.
        joints: (N, 19, 3) metres (absolute or root-relative); made root-relative, and divided by
            ``stature / REFERENCE_STATURE`` when ``layout.joint_frame == "stature"``.
        rig: the cameras of the K views (``silpose.shared.camera.Rig``); needed by the stature frame
            (to measure each walker's stature, ``silpose.model.stature``).
    Returns:
        (N, d) float64.
    """
    c = check_contours(contours_px, "contours_px")
    if c.shape[1] != n_rig_views:
        raise ValueError(f"contours_px has {c.shape[1]} views, the model's rig has {n_rig_views}")
    views = list(layout.views)
    norm, _, _ = normalise_contours(c[:, views])
    if layout.joint_frame == "stature":
        if rig is None:
            raise ValueError("joint_frame 'stature' needs the camera rig (to measure each walker's stature)")
        factor = estimate_stature(c[:, views], [rig[v] for v in views]) / REFERENCE_STATURE
        joints = root_relative(np.asarray(joints, dtype=np.float64)) / factor[:, None, None]
    return layout.build(norm, joints)


#: rows per block of :func:`shape_vectors_in_blocks`
SHAPE_VECTOR_BLOCK = 4096


def shape_vectors_in_blocks(layout: FeatureLayout, n_rig_views: int, contours_px: np.ndarray, joints: np.ndarray,
                            rig=None) -> np.ndarray:
    """:func:`shape_vectors` (N, d) built :data:`SHAPE_VECTOR_BLOCK` rows at a time (every step is row-wise), so the
    float64 temporaries of the normalisation are bounded by a block whatever N (float32 contours are converted
    block by block)."""
    n = len(contours_px)
    if n <= SHAPE_VECTOR_BLOCK:
        return shape_vectors(layout, n_rig_views, contours_px, joints, rig)
    out = np.empty((n, layout.dim))
    for start in range(0, n, SHAPE_VECTOR_BLOCK):
        sl = slice(start, start + SHAPE_VECTOR_BLOCK)
        out[sl] = shape_vectors(layout, n_rig_views, contours_px[sl], joints[sl], rig)
    return out
