"""Training augmentation: ragged contours like those of real segmentation, and mirrored people (issue 12).

**Mirrored people.** When the rig is mirror-symmetric (``silpose.shared.rig_symmetry``: a vertical plane
maps every camera a onto a camera ``view_map[a]`` with its image flipped), every training sample gives a
second, exact one: the person reflected in the plane. :func:`mirror_samples` builds it without rendering:

    contour_a' = reverse(flip(contour_{view_map[a]}))      flip(x, y) = (W - 1 - x, y)
    joints'    = swap_left_right(S joints)                  S X = X - 2 (n . X - c) n

``reverse`` keeps point 0 and reverses the others, so the contour stays clockwise and starts where it
did (the start point's rule, docs/conventions.md "Contours", commutes with the flip); ``swap_left_right``
relabels the reflected left arm as the right one (``silpose.shared.skeleton.mirror_indices``).
Measured on the default preset (200 held-out training walkers, 4 views, robust inference, M 15 q 40
with the mirrored copies against M 10 q 30 without, cm, three EM seeds): clean 3.68 -> 2.77-3.12,
standard noise 4.55 -> 3.82-4.32, mild mask noise 6.59 -> 5.95-6.41.

Real background subtraction (the paper's section 5, ``silpose.segment``) leaves ragged outlines:
the boundary wanders by a pixel or two over a few pixels of its length (camera noise, shadow
tests, the median and open/close filters), with an occasional deeper dent or bump. Rendered
training silhouettes have none of that, so a model fitted on them sees every real outline as
unusual. :func:`roughen_contours` moves each contour point along its outward normal by

    delta_i = amplitude * (g * e)_i / std(g * e)  +  sum over notches of  depth * sin(pi (j + 1/2) / L)

where ``e`` is white noise over the n points of the closed contour, ``g`` a cyclic Gaussian of
``correlation`` points standard deviation (so neighbouring points move together, as pixel blobs
do), and a Poisson number (mean ``notches``) of dents/bumps of ``L = notch_length`` points and
depth ``+-notch_depth`` (sign 50/50) are added at uniform positions. All values are pixels,
applied before normalisation, so the augmented contours go through the same shape-vector path as
clean ones. Points stay in order (no resampling); a displacement larger than half a limb's width
can fold a contour, so amplitudes of about 1 px (the jitter of the standard test noise) are meant.

Deterministic: the draws of sample ``i`` come from ``derive_rng(seed, stream_code("roughness"),
i)`` (``silpose.shared.seeds``), whatever the batch.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.contours import outward_normals
from silpose.shared.rig_symmetry import RigMirror
from silpose.shared.seeds import derive_rng, stream_code
from silpose.shared.skeleton import mirror_indices

__all__ = ["Roughness", "roughen_contours", "augment_rows", "mirror_samples", "training_rows",
           "ROUGHNESS_STREAM", "MIRROR_ID_STRIDE"]

#: Second key of the roughness stream (``derive_rng(seed, ROUGHNESS_STREAM, sample)``).
ROUGHNESS_STREAM = stream_code("roughness")
#: Sample id of the k-th mirror (k = 1, 2, ...) of sample i in the roughness streams: ``i + k * MIRROR_ID_STRIDE``.
MIRROR_ID_STRIDE = 1 << 32


@dataclass(frozen=True)
class Roughness:
    """Settings of :func:`roughen_contours` (pixels and contour points).

    Attributes:
        amplitude_px: standard deviation of the smooth normal displacement (0 = no wander).
        correlation: standard deviation of the smoothing kernel, in contour points (> 0).
        notches: mean number of dents/bumps per contour (Poisson).
        notch_depth_px: peak displacement of a dent (inward) or bump (outward).
        notch_length: points per dent/bump.
        copies: augmented copies of every training sample added to the clean ones (0 = replace
            each clean sample by one augmented copy).
    """

    amplitude_px: float = 1.0
    correlation: float = 1.5
    notches: float = 1.0
    notch_depth_px: float = 2.5
    notch_length: int = 6
    copies: int = 1

    def __post_init__(self) -> None:
        for name in ("amplitude_px", "notches", "notch_depth_px"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"roughness {name} must be finite and >= 0, got {v!r}")
        if not (np.isfinite(self.correlation) and self.correlation > 0):
            raise ValueError(f"roughness correlation must be finite and > 0, got {self.correlation!r}")
        if int(self.notch_length) < 1:
            raise ValueError(f"roughness notch_length must be >= 1, got {self.notch_length!r}")
        if int(self.copies) < 0:
            raise ValueError(f"roughness copies must be >= 0, got {self.copies!r}")

    def to_dict(self) -> dict:
        return asdict(self)


def _smooth_cyclic(e: np.ndarray, sigma: float) -> np.ndarray:
    """Cyclic Gaussian smoothing along the last axis of ``e`` (..., n), kernel std ``sigma`` points."""
    n = e.shape[-1]
    k = np.fft.fftfreq(n)
    kernel = np.exp(-2.0 * (np.pi * sigma * k) ** 2)  # Fourier transform of a unit-mass Gaussian
    return np.fft.ifft(np.fft.fft(e, axis=-1) * kernel, axis=-1).real


def _displacements(rng: np.random.Generator, k: int, n: int, spec: Roughness) -> np.ndarray:
    """(k, n) normal displacements (px) of one sample's k contours (module docstring)."""
    s = _smooth_cyclic(rng.standard_normal((k, n)), float(spec.correlation))
    s *= float(spec.amplitude_px) / np.maximum(s.std(axis=-1, keepdims=True), 1e-12)
    counts = rng.poisson(float(spec.notches), size=k)
    length = int(min(spec.notch_length, n))
    profile = np.sin(np.pi * (np.arange(length) + 0.5) / length)
    for v in range(k):
        for _ in range(int(counts[v])):
            start = int(rng.integers(n))
            sign = 1.0 if rng.uniform() < 0.5 else -1.0
            s[v, (start + np.arange(length)) % n] += sign * float(spec.notch_depth_px) * profile
    return s


def roughen_contours(contours_px: np.ndarray, spec: Roughness, seed: int, sample_ids=None) -> np.ndarray:
    """Ragged copies of pixel contours (module docstring).

    Args:
        contours_px: (N, K, n, 2) contours in pixels (closed, ordered).
        spec: the :class:`Roughness` settings.
        seed: key of the stream; ``sample_ids`` (N,) non-negative integers name each row's stream
            (None = 0..N-1), so a sample's draws do not depend on the batch.
    Returns:
        (N, K, n, 2) float64 px.
    """
    c = np.asarray(contours_px, dtype=np.float64)
    if c.ndim != 4 or c.shape[-1] != 2:
        raise ValueError(f"contours_px must have shape (N, K, n, 2), got {c.shape}")
    n_rows, k, n = c.shape[:3]
    ids = np.arange(n_rows) if sample_ids is None else np.asarray(sample_ids, dtype=np.int64)
    if ids.shape != (n_rows,):
        raise ValueError(f"sample_ids must have shape ({n_rows},), got {ids.shape}")
    normals = outward_normals(c)
    out = c.copy()
    for r in range(n_rows):
        d = _displacements(derive_rng(int(seed), ROUGHNESS_STREAM, int(ids[r])), k, n, spec)
        out[r] += d[..., None] * normals[r]
    return out


def augment_rows(contours_px: np.ndarray, joints: np.ndarray, spec: Roughness, seed: int,
                 sample_ids=None) -> tuple[np.ndarray, np.ndarray]:
    """Training rows with the roughness augmentation: ``spec.copies`` ragged copies appended to the clean
    rows (copy c of sample i draws from stream ``seed + c``), or every row replaced by one ragged copy
    when ``copies`` is 0. contours_px (N, K, n, 2) px, joints (N, 19, 3); ``sample_ids`` as in
    :func:`roughen_contours`. Returns (contours (N', K, n, 2) float64, joints (N', 19, 3))."""
    ids = np.arange(len(joints)) if sample_ids is None else np.asarray(sample_ids)
    if int(spec.copies) == 0:
        return roughen_contours(contours_px, spec, seed, ids), np.asarray(joints)
    parts = [np.asarray(contours_px, dtype=np.float64)]
    parts += [roughen_contours(contours_px, spec, seed + c, ids) for c in range(int(spec.copies))]
    return np.concatenate(parts), np.concatenate([np.asarray(joints)] * (1 + int(spec.copies)))


def mirror_samples(contours_px: np.ndarray, joints: np.ndarray, mirror: RigMirror, rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """The mirrored people of a batch of samples (module docstring, "Mirrored people").

    Args:
        contours_px: (N, V, n, 2) pixel contours of all V rig views (x right, y down), clockwise from the start point.
        joints: (N, 19, 3) world joints, metres (absolute or root-relative: the plane's offset only moves the root).
        mirror: a symmetry of ``rig`` (``silpose.shared.rig_symmetry.rig_mirrors``).
        rig: the rig the contours were seen by (its image widths).
    Returns:
        (contours (N, V, n, 2) float64 px, joints (N, 19, 3) float64 metres) of the mirrored people.
    """
    c = np.asarray(contours_px, dtype=np.float64)
    if c.ndim != 4 or c.shape[-1] != 2 or c.shape[1] != len(rig):
        raise ValueError(f"contours_px must have shape (N, {len(rig)}, n, 2) for this rig, got {c.shape}")
    if len(mirror.view_map) != len(rig):
        raise ValueError(f"the mirror maps {len(mirror.view_map)} views, the rig has {len(rig)}")
    source = np.asarray(mirror.view_map)
    widths = np.array([rig[int(b)].width for b in source], dtype=np.float64)
    out = c[:, source].copy()
    out[..., 0] = (widths[None, :, None] - 1.0) - out[..., 0]
    out = np.concatenate([out[:, :, :1], out[:, :, :0:-1]], axis=2)  # clockwise again, same start point
    mirrored_joints = mirror.reflect(np.asarray(joints, dtype=np.float64))[:, mirror_indices()]
    return out, mirrored_joints


def training_rows(contours_px: np.ndarray, joints: np.ndarray, sample_ids, *, rig: Rig | None = None,
                  mirrors: tuple[RigMirror, ...] = (), roughness: Roughness | None = None,
                  seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """The rows a model is fitted on: the samples, then their mirrored people (one block per mirror,
    :func:`mirror_samples`), then the roughness copies of all of those (:func:`augment_rows`; the k-th
    mirror of sample i draws as sample ``i + k * MIRROR_ID_STRIDE``). ``silpose train``, model selection
    and the eval's baselines all build their training rows here, so they fit the same rows.

    contours_px (N, V, n, 2) px, joints (N, 19, 3) metres, sample_ids (N,) non-negative ints.
    Returns (contours (N', V, n, 2) float64, joints (N', 19, 3)), N' = N (1 + len(mirrors)) (1 + copies).
    """
    ids = np.asarray(sample_ids, dtype=np.int64)
    c_parts, j_parts, id_parts = [np.asarray(contours_px, dtype=np.float64)], [np.asarray(joints)], [ids]
    if mirrors and rig is None:
        raise ValueError("mirrored training rows need the rig the contours were seen by")
    for k, mirror in enumerate(mirrors, start=1):
        c_m, j_m = mirror_samples(contours_px, joints, mirror, rig)
        c_parts.append(c_m)
        j_parts.append(j_m.astype(j_parts[0].dtype, copy=False))
        id_parts.append(ids + k * MIRROR_ID_STRIDE)
    c, j, i = (np.concatenate(p) if len(p) > 1 else p[0] for p in (c_parts, j_parts, id_parts))
    if roughness is not None:
        c, j = augment_rows(c, j, roughness, seed, i)
    return c, j
