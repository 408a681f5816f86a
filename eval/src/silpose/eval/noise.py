"""Segmentation-like noise for test contours (paper §6, Fig. 4; docs/conventions.md, "Evaluation protocol").

All noise acts in PIXELS, before normalisation, on the clean resampled contours of the test
split. Three families, each deterministic per ``(seed, sample_id)``:

(a) **Jitter** (:func:`jitter_points`) — every contour point moves in a uniformly random
    direction ``theta ~ U[0, 2 pi)``. Magnitude: ``"fixed"`` moves every point by exactly
    ``magnitude`` px; ``"gaussian"`` draws the displacement from ``N(0, magnitude^2 I_2)``
    (isotropic, per-axis standard deviation ``magnitude`` px, so the direction is still uniform
    and the length is Rayleigh distributed).
(b) **Normal patches** (:func:`normal_patches`) — ``n_patches`` contiguous runs of
    ``patch_length`` consecutive points (cyclic) move along the contour's outward unit normal
    by ``sign * depth * w_j``, with the bump profile ``w_j = sin(pi (j + 1/2) / L)``
    (``j = 0..L-1``; every point of the run moves, the middle ones by ~``depth``). ``sign`` is
    -1 for a hole (inward) and +1 for a false extension (outward); ``mode="both"`` draws it
    with probability 1/2. Overlapping patches add up. Normals come from the clean contour
    (central differences, oriented outward with the sign of the shoelace area, so they do not
    depend on the contour's orientation).
(c) **Mask corruption** (:func:`corrupt_mask`) — on the binary silhouette: discs removed near
    the outline (holes biting into it), discs added just outside it (spurious blobs, attached
    or detached) and a flat ellipse added sideways at the feet (a shadow-like extension).
    The contour is then re-extracted with :func:`silpose.shared.contours.extract_contour`,
    which keeps only the largest blob's outer boundary — the closest of the three to real
    background-subtraction errors.

Defaults (:data:`STANDARD_NOISE`, the test noise of E1, E2 and E4) are scaled to our silhouettes,
measured on the smoke dataset (default rig, 320x240): a person ~116 px tall, ~380 px of contour,
~2,600 px of area, 200 points ~1.8 px apart, limbs ~6-10 px wide (the paper's: ~850 px of contour,
~30,000 px of area). Standard noise (issue 12): 1 px fixed jitter plus 6 patches per view of 30
points (~59 px of outline each; together they touch most of the outline, overlapping ones add
up) with an 8 px peak depth, holes or extensions at random. The paper gives no magnitudes but
calls its noise "large"; ours is chosen so that the noisy input is clearly further from the true
contour than the model's reconstruction of it: on the default preset (200 test walkers, 4 views)
the input's own Chamfer D(true -> input) is 2.55 px against 2.10 px for the reconstruction (the
earlier standard, 1 px jitter and 3 patches of 16 points at 4 px, gave 0.83 px against 1.51 px, so
the E1 contour comparison measured fidelity, not denoising). E3 sweeps the magnitudes (jitter
0.5-4 px, patch depth 2-16 px, two mask-corruption levels).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import cv2
import numpy as np

from silpose.shared.contours import EmptyMaskError, extract_contour, outward_normals
from silpose.shared.seeds import derive_rng, stream_code

__all__ = [
    "NoiseSpec",
    "STANDARD_NOISE",
    "sample_rng",
    "jitter_points",
    "outward_normals",
    "normal_patches",
    "corrupt_mask",
    "apply_noise",
]


@dataclass(frozen=True)
class NoiseSpec:
    """One noise setting; a family is off when its size parameter is 0.

    Attributes:
        label: short name used in tables.
        jitter_px: (a) displacement magnitude in px (0 = off).
        jitter_distribution: "fixed" (every point moves exactly ``jitter_px``) or "gaussian"
            (``N(0, jitter_px^2 I_2)``).
        n_patches: (b) patches per view (0 = off).
        patch_length: points per patch (of the n resampled points).
        patch_depth_px: peak displacement along the normal, px.
        patch_mode: "both" (hole or extension, p = 1/2 each), "holes" or "extensions".
        mask_holes, mask_hole_radius_px: (c) discs removed near the outline.
        mask_blobs, mask_blob_radius_px: (c) discs added next to the outline.
        mask_shadow_px: (c) half-length of the shadow ellipse at the feet (0 = off);
            ``mask_shadow_height_px`` its half-height.
    """

    label: str = "clean"
    jitter_px: float = 0.0
    jitter_distribution: str = "fixed"
    n_patches: int = 0
    patch_length: int = 16
    patch_depth_px: float = 0.0
    patch_mode: str = "both"
    mask_holes: int = 0
    mask_hole_radius_px: float = 5.0
    mask_blobs: int = 0
    mask_blob_radius_px: float = 5.0
    mask_shadow_px: float = 0.0
    mask_shadow_height_px: float = 3.0

    def __post_init__(self) -> None:
        if self.jitter_distribution not in ("fixed", "gaussian"):
            raise ValueError(f"NoiseSpec {self.label!r} field jitter_distribution: "
                             f"expected 'fixed' or 'gaussian', got {self.jitter_distribution!r}")
        if self.patch_mode not in ("both", "holes", "extensions"):
            raise ValueError(f"NoiseSpec {self.label!r} field patch_mode: "
                             f"expected 'both', 'holes' or 'extensions', got {self.patch_mode!r}")
        for name in ("jitter_px", "patch_depth_px", "mask_hole_radius_px", "mask_blob_radius_px",
                     "mask_shadow_px", "mask_shadow_height_px"):
            if not (np.isfinite(getattr(self, name)) and getattr(self, name) >= 0):
                raise ValueError(f"NoiseSpec {self.label!r} field {name}: must be finite and >= 0")
        for name in ("n_patches", "patch_length", "mask_holes", "mask_blobs"):
            if int(getattr(self, name)) < 0:
                raise ValueError(f"NoiseSpec {self.label!r} field {name}: must be >= 0")
        if self.n_patches > 0 and self.patch_length < 1:
            raise ValueError(f"NoiseSpec {self.label!r} field patch_length: must be >= 1")

    @property
    def needs_masks(self) -> bool:
        """True when the mask-level family is on (the test masks must be loaded)."""
        return self.mask_holes > 0 or self.mask_blobs > 0 or self.mask_shadow_px > 0

    def to_dict(self) -> dict:
        return asdict(self)

    def with_(self, **changes) -> "NoiseSpec":
        return replace(self, **changes)


#: The test noise of E1, E2 and E4 (see the module docstring for the reasoning).
STANDARD_NOISE = NoiseSpec(label="standard", jitter_px=1.0, n_patches=6, patch_length=30,
                           patch_depth_px=8.0)


def sample_rng(seed: int, sample_id: int, stream: str) -> np.random.Generator:
    """The Generator for one sample and one noise stream.

    ``derive_rng(seed, stream_code(stream), sample_id)``, i.e. ``SeedSequence([seed, crc32(stream),
    sample_id])`` (:mod:`silpose.shared.seeds`; streams "mask", "patches", "jitter"): the draws of a
    sample do not depend on which other samples are evaluated, on their order or on batching.
    """
    return derive_rng(seed, stream_code(stream), sample_id)


def jitter_points(points: np.ndarray, magnitude: float, rng: np.random.Generator,
                  distribution: str = "fixed") -> np.ndarray:
    """(a) Move every point in a uniformly random direction.

    Args:
        points: (..., n, 2) px.
        magnitude: px; the exact displacement ("fixed") or the per-axis std ("gaussian").
        rng: the Generator to draw from.
        distribution: "fixed" or "gaussian".
    Returns:
        (..., n, 2) float64 px.
    """
    p = np.asarray(points, dtype=np.float64)
    if distribution == "fixed":
        theta = rng.uniform(0.0, 2.0 * np.pi, size=p.shape[:-1])
        d = magnitude * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    elif distribution == "gaussian":
        d = rng.normal(0.0, magnitude, size=p.shape)
    else:
        raise ValueError(f"distribution must be 'fixed' or 'gaussian', got {distribution!r}")
    return p + d


def normal_patches(points: np.ndarray, n_patches: int, patch_length: int, depth: float,
                   rng: np.random.Generator, mode: str = "both") -> np.ndarray:
    """(b) Move contiguous runs of points along the outward normal (holes / false extensions).

    Args:
        points: (n, 2) px, one closed contour.
        n_patches: number of patches; each starts at a uniformly random index.
        patch_length: points per patch L (clipped to n).
        depth: peak displacement in px.
        rng: the Generator to draw from.
        mode: "both" (sign +-1 with p = 1/2), "holes" (inward) or "extensions" (outward).
    Returns:
        (n, 2) float64 px; point ``start + j`` (mod n) of a patch moves by
        ``sign * depth * sin(pi (j + 1/2) / L) * normal``.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got {p.shape}")
    n = len(p)
    length = int(min(patch_length, n))
    if n_patches <= 0 or length <= 0 or depth == 0:
        return p.copy()
    normals = outward_normals(p)
    profile = np.sin(np.pi * (np.arange(length) + 0.5) / length)
    offset = np.zeros(n)
    for _ in range(int(n_patches)):
        start = int(rng.integers(n))
        if mode == "both":
            sign = 1.0 if rng.random() < 0.5 else -1.0
        elif mode == "holes":
            sign = -1.0
        elif mode == "extensions":
            sign = 1.0
        else:
            raise ValueError(f"mode must be 'both', 'holes' or 'extensions', got {mode!r}")
        idx = (start + np.arange(length)) % n
        offset[idx] += sign * depth * profile
    return p + offset[:, None] * normals


def _disc(img: np.ndarray, cx: float, cy: float, r: float, value: int) -> None:
    """Fill a disc of radius ``r`` px centred on (cx, cy) in place (cv2.circle, 1/16 px precision)."""
    cv2.circle(img, (int(round(cx * 16)), int(round(cy * 16))), max(int(round(r * 16)), 1), int(value), -1,
               lineType=cv2.LINE_8, shift=4)


def corrupt_mask(mask: np.ndarray, rng: np.random.Generator, *, n_holes: int = 0, hole_radius: float = 5.0,
                 n_blobs: int = 0, blob_radius: float = 5.0, shadow_px: float = 0.0,
                 shadow_height_px: float = 3.0) -> np.ndarray:
    """(c) Segmentation-like corruption of one binary silhouette.

    - holes: ``n_holes`` discs of radius ``hole_radius`` removed, centred on foreground pixels
      at most ``hole_radius`` inside the outline (so they bite into it);
    - blobs: ``n_blobs`` discs of radius ``blob_radius`` added, centred on background pixels at
      most ``blob_radius`` outside the outline (attached or nearly attached);
    - shadow: a filled ellipse of half-axes (``shadow_px``, ``shadow_height_px``) centred on the
      silhouette's lowest row, shifted sideways by ``shadow_px`` to a random side, so it
      extends the feet along the floor.

    Args:
        mask: (H, W) 0/1 or bool silhouette.
    Returns:
        (H, W) uint8 0/1 corrupted mask (may have several blobs).
    """
    m = (np.asarray(mask) > 0).astype(np.uint8)
    if m.ndim != 2:
        raise ValueError(f"mask must have shape (H, W), got {m.shape}")
    out = m.copy()
    if not m.any():
        return out
    if n_holes > 0:
        # Distance of each foreground pixel to the background (inside depth).
        inside = cv2.distanceTransform(m, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        cand = np.argwhere((m > 0) & (inside <= max(hole_radius, 1.0)))
        for _ in range(int(n_holes)):
            y, x = cand[rng.integers(len(cand))]
            _disc(out, x, y, hole_radius, 0)
    if n_blobs > 0:
        outside = cv2.distanceTransform(1 - m, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
        cand = np.argwhere((m == 0) & (outside <= max(blob_radius, 1.0)))
        if len(cand):
            for _ in range(int(n_blobs)):
                y, x = cand[rng.integers(len(cand))]
                _disc(out, x, y, blob_radius, 1)
    if shadow_px > 0:
        ys, xs = np.nonzero(m)
        bottom = ys.max()
        foot_x = xs[ys == bottom].mean()
        side = 1.0 if rng.random() < 0.5 else -1.0
        cx = foot_x + side * shadow_px
        axes = (max(int(round(shadow_px * 16)), 1), max(int(round(shadow_height_px * 16)), 8))
        cv2.ellipse(out, (int(round(cx * 16)), int(round(bottom * 16))), axes, 0, 0, 360, 1, -1,
                    lineType=cv2.LINE_8, shift=4)
    return out


def apply_noise(spec: NoiseSpec, contours: np.ndarray, sample_ids: np.ndarray, seed: int,
                masks: np.ndarray | None = None, n_points: int | None = None) -> np.ndarray:
    """Apply one noise setting to a batch of clean multi-view contours.

    Order: mask corruption and re-extraction (c) if on, then normal patches (b), then jitter
    (a). Each sample uses :func:`sample_rng` ``(seed, sample_id, ...)``, one stream per family.
    If corruption empties a mask (never seen in practice) the clean contour is kept.

    Args:
        spec: the setting.
        contours: (N, K, n, 2) clean contours, px.
        sample_ids: (N,) ints identifying the samples.
        seed: the experiment's noise seed.
        masks: (N, K, H, W) clean silhouettes; required when ``spec.needs_masks``.
        n_points: points per re-extracted contour (default: n of ``contours``).
    Returns:
        (N, K, n, 2) float32 noisy contours, px.
    """
    c = np.asarray(contours, dtype=np.float64)
    if c.ndim != 4 or c.shape[-1] != 2:
        raise ValueError(f"contours must have shape (N, K, n, 2), got {c.shape}")
    ids = np.asarray(sample_ids).reshape(-1)
    if len(ids) != len(c):
        raise ValueError(f"sample_ids has {len(ids)} entries for {len(c)} contours")
    n_points = c.shape[2] if n_points is None else int(n_points)
    out = c.copy()
    if spec.needs_masks:
        if masks is None:
            raise ValueError(f"noise {spec.label!r} corrupts masks: pass the test masks (load_split(..., with_masks=True))")
        if masks.shape[:2] != c.shape[:2]:
            raise ValueError(f"masks shape {masks.shape} does not match contours {c.shape}")
        for i, sid in enumerate(ids):
            rng = sample_rng(seed, sid, "mask")
            for k in range(c.shape[1]):
                bad = corrupt_mask(masks[i, k], rng, n_holes=spec.mask_holes, hole_radius=spec.mask_hole_radius_px,
                                   n_blobs=spec.mask_blobs, blob_radius=spec.mask_blob_radius_px,
                                   shadow_px=spec.mask_shadow_px, shadow_height_px=spec.mask_shadow_height_px)
                try:
                    out[i, k] = extract_contour(bad, n_points).points
                except EmptyMaskError:
                    pass
    if spec.n_patches > 0 and spec.patch_depth_px > 0:
        for i, sid in enumerate(ids):
            rng = sample_rng(seed, sid, "patches")
            for k in range(c.shape[1]):
                out[i, k] = normal_patches(out[i, k], spec.n_patches, spec.patch_length, spec.patch_depth_px,
                                           rng, spec.patch_mode)
    if spec.jitter_px > 0:
        for i, sid in enumerate(ids):
            rng = sample_rng(seed, sid, "jitter")
            out[i] = jitter_points(out[i], spec.jitter_px, rng, spec.jitter_distribution)
    return out.astype(np.float32)
