"""Synthetic shape+structure data with a known linear link between joints and contours.

Used by the tests and benchmarks of ``silpose.model`` where no rendered dataset is needed:
joints come from a low-dimensional walk-like latent space, and each view's pixel contour is a
fixed linear function of the root-relative joints (a crude affine camera on a deformable
template) plus isotropic pixel noise, then placed at a per-sample image position and size.
Because the link is linear, a PPCA mixture can recover joints from contours almost exactly,
which gives the tests a strong, independent expectation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from silpose.shared.seeds import derive_rng
from silpose.shared.skeleton import N_JOINTS, root_relative


@dataclass
class SyntheticShapes:
    """contours (N, K, n, 2) px float32, joints (N, 19, 3) metres float32 (absolute), latent (N, r)."""

    contours: np.ndarray
    joints: np.ndarray
    latent: np.ndarray
    centroid: np.ndarray
    scale: np.ndarray


def make_linear_shapes(
    n_samples: int,
    n_views: int = 4,
    n_points: int = 32,
    *,
    n_factors: int = 4,
    pixel_noise: float = 0.3,
    seed: int = 0,
    n_clusters: int = 2,
) -> SyntheticShapes:
    """Draw a synthetic data set.

    Joints: ``s = mean_c + B_c z`` with ``z ~ N(0, I_r)`` (r = n_factors) and cluster c uniform
    over ``n_clusters`` (different means and bases, like walking directions). Contours: per view,
    ``t_k + G_k vec(s - s_root)`` in template units (a circle template of radius 1 deformed by a
    fixed random linear map ``G_k`` shared by all samples), then scaled by a per-sample size in
    ``[40, 60]`` px and shifted to a per-sample position, plus ``N(0, pixel_noise^2)`` px noise.
    The maps and bases come from ``derive_rng(seed, 0)``, the samples from ``derive_rng(seed, 1)``
    (``silpose.shared.seeds``), so data sets of different sizes share the maps.
    """
    # fixed model structure from a separate stream, so data sets of different sizes share it
    fixed = derive_rng(seed, 0)
    rng = derive_rng(seed, 1)
    base = fixed.normal(0.0, 0.3, size=(n_clusters, N_JOINTS, 3))
    bases = fixed.normal(0.0, 0.08, size=(n_clusters, N_JOINTS * 3, n_factors))
    angle = np.linspace(0.0, 2.0 * np.pi, n_points, endpoint=False)
    template = np.stack([np.cos(angle), np.sin(angle)], axis=-1)  # (n, 2)
    gains = fixed.normal(0.0, 0.6 / np.sqrt(N_JOINTS * 3), size=(n_views, n_points * 2, N_JOINTS * 3))

    cluster = rng.integers(n_clusters, size=n_samples)
    z = rng.normal(size=(n_samples, n_factors))
    joints = base[cluster] + np.einsum("nij,nj->ni", bases[cluster], z).reshape(n_samples, N_JOINTS, 3)
    rel = root_relative(joints).reshape(n_samples, -1)
    joints = joints + np.array([0.0, 0.0, 1.0]) + rng.uniform(-1, 1, size=(n_samples, 1, 3)) * [1, 1, 0]

    shape = template[None, None] + np.einsum("kpj,nj->nkp", gains, rel).reshape(n_samples, n_views, n_points, 2)
    size = rng.uniform(40.0, 60.0, size=(n_samples, n_views))
    centre = rng.uniform([100.0, 80.0], [220.0, 160.0], size=(n_samples, n_views, 2))
    contours = shape * size[..., None, None] + centre[:, :, None, :]
    contours = contours + rng.normal(0.0, pixel_noise, size=contours.shape)
    return SyntheticShapes(
        contours=contours.astype(np.float32),
        joints=joints.astype(np.float32),
        latent=z,
        centroid=centre,
        scale=size,
    )
