"""Put a person's inferred skeleton in the room: the root position, and the missing views' contours in pixels.

The model gives root-relative joints (metres, world orientation, scaled to the stature it measured from
the silhouettes; ``silpose.model.stature``). The root (pelvis) position T = (x, y, z):

- height: the feet are on the floor, so ``z = -min_j J_j,z`` (the lowest joint on the floor). Measured on
  400 walkers of the lab rig's training set: the true pelvis is 0.2 cm higher on average, std 0.5 cm.
  Unless the views say clearly otherwise: a person on a treadmill, a step or a platform, or in the air
  mid-jump. With two or more views :func:`place_roots` also fits the height freely (the same image errors,
  the floor position prior kept) and takes that fit when it puts the root higher than the feet-on-floor
  height by more than :data:`MIN_RAISE_M` and by :data:`RAISE_SIGMAS` times the fit's standard deviation.
  Measured with the true joints and the rendered silhouettes' centroids (test splits, 4 views): the free
  height minus the feet-on-floor height is -3.6 +- 2.3 cm (walk preset, max 2.6 cm) and -1.6 +- 3.0 cm
  (motions preset, max 8.3 cm), its estimated standard deviation 4.6 cm: no person on the floor is raised.
- floor position: the silhouettes. A view's contour centroid (the mean of its resampled points, the
  model's normalisation centroid) is the image of a body point ``c = mean_j J_j + (0, 0, -CENTRE_DROP_M)``
  (the mean joint, lowered: contour points crowd on the long thin legs). Measured on the same 400 walkers
  x 4 views: horizontal image error 0.0 +- 1.5 px, vertical 0.0 +- 5.7 px (the vertical centroid moves
  with the arms, legs, skirts and hair). :func:`place_roots` minimises, over (x, y), the squared image
  errors of ``T + c`` in every observed view, weighted by those spreads (:data:`SIGMA_U_PX`,
  :data:`SIGMA_V_PX`), plus the floor grid's position as a prior (:data:`SIGMA_FLOOR_M`) -- a few
  Gauss-Newton steps, vectorised over people and frames. With one view the horizontal image position
  fixes a line on the floor and the prior and the vertical position place the person along it. Without a floor
  grid (one person, ``silpose infer --people 1``), :func:`place_without_floor` lets the views place the person
  from the workspace centre under a weak prior, then places them again with that answer as the floor position:
  on a lab walker's 40 frames its root was 0.26 cm from the floor grid's placement on average
  (``tests/app/recordings/test_one_person_room.py``).

Missing views (:func:`place_contours`): the reconstructed normalised contour is mapped to pixels with
centroid ``project(T + c)`` and scale ``rho f / depth``, where ``rho`` (metres) is the person's contour
scale measured in the observed views, ``rho = mean_k s_k depth_k / f_k``. Measured on the 400 walkers,
leave-one-view-out: the scale of a left-out view is predicted within 2.6 % on average.
"""

from __future__ import annotations

import numpy as np

#: metres the contour centroid's body point lies below the mean joint (measured, module docstring)
CENTRE_DROP_M = 0.055
#: pixels: spread of a view's contour centroid about the image of the body point, horizontal / vertical
SIGMA_U_PX, SIGMA_V_PX = 1.5, 6.0
#: metres: spread of the floor grid's position about the root
SIGMA_FLOOR_M = 0.05
#: metres: spread of the prior about the workspace centre where no floor grid found the person
#: (:func:`place_without_floor`): the workspace's scale, so that the views decide
SIGMA_OPEN_FLOOR_M = 2.0
#: Gauss-Newton steps
N_STEPS = 4
#: metres: the least height above the feet-on-floor root a free fit must find to put a person off the floor
#: (treadmills, steps and platforms are 0.1 m and higher; a force plate is flush)
MIN_RAISE_M = 0.10
#: ... and in standard deviations of the free fit's height
RAISE_SIGMAS = 2.5
#: metres: the prior spread of the free fit's height about the feet-on-floor height (weak: the views decide)
SIGMA_FREE_HEIGHT_M = 1.0
_EPS = 1e-4


def body_point(joints: np.ndarray) -> np.ndarray:
    """(N, 3) root-relative point whose image is a view's contour centroid, from joints (N, 19, 3)."""
    c = np.asarray(joints, float).mean(axis=1)
    c[:, 2] -= CENTRE_DROP_M
    return c


def root_height(joints: np.ndarray) -> np.ndarray:
    """(N,) metres: the root's height with the lowest joint on the floor."""
    return -np.asarray(joints, float)[..., 2].min(axis=1)


def place_roots(joints: np.ndarray, centroids: np.ndarray, present: np.ndarray, cameras, floor_xy: np.ndarray,
                floor_sigma: float = SIGMA_FLOOR_M) -> np.ndarray:
    """(N, 3) root positions, metres, silpose's frame (module docstring).

    Args:
        joints: (N, 19, 3) root-relative joints, metres.
        centroids: (N, K, 2) px contour centroids of the K views (anything where absent).
        present: (N, K) bool observed views.
        cameras: K cameras (``Camera``).
        floor_xy: (N, 2) metres, the floor grid's positions (the prior and the start).
        floor_sigma: metres, the prior's spread (:data:`SIGMA_FLOOR_M`, the floor grid's; larger for a prior that
            only keeps a one-view placement bounded, :func:`place_without_floor`).
    """
    joints = np.asarray(joints, float)
    n = len(joints)
    c = body_point(joints)
    z = root_height(joints)
    xy = np.asarray(floor_xy, float).copy()
    prior = xy.copy()
    w = np.array([1 / SIGMA_U_PX, 1 / SIGMA_V_PX])
    for _ in range(N_STEPS):
        A = np.zeros((n, 2, 2)) + np.eye(2) / floor_sigma**2
        b = (prior - xy) / floor_sigma**2
        X = np.concatenate([xy, z[:, None]], axis=1) + c
        for k, cam in enumerate(cameras):
            obs = present[:, k]
            if not obs.any():
                continue
            Xo = X[obs]
            p0 = cam.project(Xo)
            J = np.stack([(cam.project(Xo + _EPS * e) - p0) / _EPS for e in (np.eye(3)[0], np.eye(3)[1])], axis=2)  # (m, 2, 2)
            r = (centroids[obs, k] - p0) * w
            Jw = J * w[None, :, None]
            A[obs] += np.einsum("mij,mik->mjk", Jw, Jw)
            b[obs] += np.einsum("mij,mi->mj", Jw, r)
        xy = xy + np.linalg.solve(A, b[..., None])[..., 0]
    roots = np.concatenate([xy, z[:, None]], axis=1)
    several = np.asarray(present, bool).sum(axis=1) >= 2
    if several.any():
        free, sd = free_height_roots(c[several], roots[several], centroids[several], present[several], cameras,
                                     prior[several])
        raised = free[:, 2] - roots[several, 2] > np.maximum(MIN_RAISE_M, RAISE_SIGMAS * sd)
        roots[np.flatnonzero(several)[raised]] = free[raised]
    return roots


def place_without_floor(joints: np.ndarray, centroids: np.ndarray, present: np.ndarray, cameras,
                        centre_xy) -> np.ndarray:
    """(N, 3) root positions, metres, of people no floor grid found (one person, ``silpose infer --people 1``).

    The views alone place them: :func:`place_roots` from ``centre_xy`` (2,) metres (the workspace centre) with a
    prior of :data:`SIGMA_OPEN_FLOOR_M` (it only bounds a one-view placement along its line on the floor), then
    :func:`place_roots` again with that answer as the floor position, as the floor grid's would be.
    Arguments as :func:`place_roots`'s.
    """
    joints = np.asarray(joints, float)
    prior = np.tile(np.asarray(centre_xy, float).reshape(1, 2), (len(joints), 1))
    first = place_roots(joints, centroids, present, cameras, prior, floor_sigma=SIGMA_OPEN_FLOOR_M)
    return place_roots(joints, centroids, present, cameras, first[:, :2])


def free_height_roots(body: np.ndarray, start: np.ndarray, centroids: np.ndarray, present: np.ndarray, cameras,
                      floor_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Root positions (N, 3) fitted with the height free, and the fit's height standard deviation (N,) metres.

    Gauss-Newton on the same weighted image errors as :func:`place_roots`, the floor grid's position
    ``floor_xy`` (N, 2) as the prior of (x, y), a weak prior (:data:`SIGMA_FREE_HEIGHT_M`) on the height about
    the start's. body: (N, 3) root-relative body points (:func:`body_point`); start: (N, 3) feet-on-floor roots.
    """
    X = np.asarray(start, float).copy()
    z0 = X[:, 2].copy()
    n = len(X)
    w = np.array([1 / SIGMA_U_PX, 1 / SIGMA_V_PX])
    prior_precision = np.diag([1 / SIGMA_FLOOR_M**2, 1 / SIGMA_FLOOR_M**2, 1 / SIGMA_FREE_HEIGHT_M**2])
    for _ in range(2 * N_STEPS):
        A = np.zeros((n, 3, 3)) + prior_precision
        b = np.c_[floor_xy - X[:, :2], z0 - X[:, 2]] * np.diag(prior_precision)
        for k, cam in enumerate(cameras):
            obs = present[:, k]
            if not obs.any():
                continue
            Xo = X[obs] + body[obs]
            p0 = cam.project(Xo)
            J = np.stack([(cam.project(Xo + _EPS * e) - p0) / _EPS for e in np.eye(3)], axis=2)  # (m, 2, 3)
            r = (centroids[obs, k] - p0) * w
            Jw = J * w[None, :, None]
            A[obs] += np.einsum("mij,mik->mjk", Jw, Jw)
            b[obs] += np.einsum("mij,mi->mj", Jw, r)
        X = X + np.linalg.solve(A, b[..., None])[..., 0]
    return X, np.sqrt(np.linalg.inv(A)[:, 2, 2])


def place_contours(result, roots: np.ndarray, cameras) -> np.ndarray:
    """(N, K, n, 2) px contours of every modelled view: observed views' reconstructions as the model placed
    them, missing views' mapped with the projected centroid and the person's metric contour scale.

    result: the model's InferenceResult for N people (``contours_norm``, ``contours_px``, ``scale``,
    ``views_present``, ``joints``); roots (N, 3) metres; cameras: the K modelled views' cameras.
    """
    present = result.views_present
    out = np.array(result.contours_px, float, copy=True)
    X = roots + body_point(result.joints)
    depth = np.stack([cam.to_camera(X)[:, 2] for cam in cameras], axis=1)  # (N, K)
    focal = np.array([cam.K[0, 0] for cam in cameras])
    with np.errstate(invalid="ignore", divide="ignore"):
        seen = present & np.isfinite(result.scale) & (depth > 0)
        total = np.where(seen, result.scale * depth / focal, 0.0).sum(axis=1)
        count = seen.sum(axis=1)
        rho = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    for k, cam in enumerate(cameras):
        miss = ~present[:, k] & np.isfinite(rho) & (depth[:, k] > 0)
        if not miss.any():
            continue
        centre = cam.project(X[miss])
        scale = rho[miss] * focal[k] / depth[miss, k]
        out[miss, k] = result.contours_norm[miss, k] * scale[:, None, None] + centre[:, None, :]
    return out
