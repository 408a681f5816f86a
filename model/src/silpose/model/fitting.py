"""What the fit entry points of :class:`~silpose.model.shape_model.ShapeStructureModel` share.

``fit``, ``fit_stream`` and ``fit_shards`` validate the hyperparameters (:func:`check_hyperparameters`), lay out
the shape vector of the modelled views in the joint frame they resolve (:func:`model_layout`,
:func:`resolve_joint_frame`) and fit the mixture :func:`new_mixture` makes; ``fit`` and ``score`` read joints with
:func:`joints_array`, ``fit`` its arrays with :func:`training_arrays`, ``fit_shards`` its rows with
:func:`selected_shards`. :func:`hyperparameter_record` is what model files and reports record. The checks raise
ValueError naming the argument.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.skeleton import N_JOINTS

from .checks import check_contours, check_views
from .features import FeatureLayout
from .mppca import MPPCA
from .shards import split_global_rows

__all__ = ["check_hyperparameters", "hyperparameter_record", "resolve_joint_frame", "model_layout", "new_mixture",
           "joints_array", "training_arrays", "selected_shards"]


def check_hyperparameters(model) -> None:
    """ValueError for a hyperparameter of ``model`` (a ShapeStructureModel) out of its range."""
    if int(model.n_components) < 1:
        raise ValueError(f"n_components must be >= 1, got {model.n_components}")
    if int(model.n_latent) < 1:
        raise ValueError(f"n_latent must be >= 1, got {model.n_latent}")
    if int(model.n_fits) < 1:
        raise ValueError(f"n_fits must be >= 1, got {model.n_fits}")
    if not np.isfinite(model.noise_variance) or model.noise_variance < 0:
        raise ValueError(f"noise_variance must be finite and >= 0, got {model.noise_variance}")
    if model.joint_frame not in (None, "metres", "stature"):
        raise ValueError(f"joint_frame must be 'metres', 'stature' or None, got {model.joint_frame!r}")


def hyperparameter_record(model) -> dict:
    """The hyperparameters of ``model`` as a JSON-friendly dict (no callback, verbose or rig)."""
    return {
        "n_components": int(model.n_components),
        "n_latent": int(model.n_latent),
        "structure_weight": float(model.structure_weight),
        "views": None if model.views is None else [int(v) for v in model.views],
        "noise_variance": float(model.noise_variance),
        "joint_frame": model.joint_frame,
        "noise_dof": bool(model.noise_dof),
        "tol": float(model.tol),
        "max_iter": int(model.max_iter),
        "n_init": int(model.n_init),
        "n_fits": int(model.n_fits),
        "random_state": None if model.random_state is None else int(model.random_state),
    }


def resolve_joint_frame(joint_frame: str | None, rig) -> str:
    """The joint frame a fit with ``rig`` uses (None -> 'stature' with a rig, else 'metres')."""
    frame = joint_frame or ("stature" if rig is not None else "metres")
    if frame == "stature" and rig is None:
        raise ValueError("joint_frame 'stature' needs the camera rig: pass rig= to fit (or joint_frame='metres')")
    return frame


def model_layout(model, n_rig_views: int, n_points: int, rig) -> FeatureLayout:
    """The shape-vector layout ``model`` fits on: its modelled views of a rig of ``n_rig_views`` views (``rig``, or
    None), ``n_points`` per contour, its structure weight, the joint frame :func:`resolve_joint_frame` chooses."""
    views = check_views(model.views, n_rig_views)
    return FeatureLayout(views, n_points, N_JOINTS, float(model.structure_weight),
                         resolve_joint_frame(model.joint_frame, rig))


def new_mixture(model, init_params: dict | None = None, fit_index: int = 0) -> MPPCA:
    """The unfitted :class:`~silpose.model.mppca.MPPCA` of ``model``'s hyperparameters; fit ``fit_index`` of its
    ``n_fits`` starts from seed ``random_state + fit_index``."""
    seed = model.random_state
    if fit_index and seed is not None:
        seed = int(seed) + int(fit_index)
    return MPPCA(n_components=int(model.n_components), n_latent=int(model.n_latent), tol=float(model.tol),
                 max_iter=int(model.max_iter), n_init=int(model.n_init), init_params=init_params,
                 noise_dof=bool(model.noise_dof), random_state=seed, callback=model.callback, verbose=model.verbose)


def joints_array(y, name: str) -> np.ndarray:
    """Joints as float64 (N, 19, 3) from (N, 19, 3) or flattened (N, 57); ValueError naming ``name`` otherwise."""
    j = np.asarray(y, dtype=np.float64)
    if j.ndim == 2 and j.shape[1] == 3 * N_JOINTS:
        j = j.reshape(len(j), N_JOINTS, 3)
    if j.ndim != 3 or j.shape[1:] != (N_JOINTS, 3):
        raise ValueError(f"{name} must have shape (N, {N_JOINTS}, 3) or (N, {3 * N_JOINTS}), got {j.shape}")
    return j


def training_arrays(X, y, rig) -> tuple[np.ndarray, np.ndarray]:
    """The checked training contours (N, K, n, 2) px and joints (N, 19, 3) metres of ``fit(X, y, rig)``: float32
    contours are checked as they are (converted block by block later, never as a whole), every value finite, one
    joint set per sample, one camera per view of ``rig`` (or None)."""
    raw = np.asarray(X)
    c = raw if raw.dtype == np.float32 and raw.ndim == 4 else check_contours(raw, "contours_px")
    j = joints_array(y, "joints")
    if j.shape[0] != c.shape[0]:
        raise ValueError(f"contours_px has {c.shape[0]} samples but joints has {j.shape[0]}")
    if not np.all(np.isfinite(c)):
        raise ValueError("contours_px contains NaN or inf")
    if not np.all(np.isfinite(j)):
        raise ValueError("joints contains NaN or inf")
    if rig is not None and len(rig) != c.shape[1]:
        raise ValueError(f"rig has {len(rig)} cameras but contours_px has {c.shape[1]} views")
    return c, j


def selected_shards(source, rows, where: str):
    """``source`` (a :class:`~silpose.model.streaming.DatasetShards`) restricted to the global row indices ``rows``
    (None = every row; sorted, duplicates dropped); ValueError naming ``where`` for an empty or out-of-range set."""
    if rows is None:
        return source
    idx = np.unique(np.asarray(rows, dtype=np.int64))
    total = sum(source.shard_rows())
    if idx.size == 0 or idx[0] < 0 or idx[-1] >= total:
        raise ValueError(f"rows must be non-empty indices in 0..{total - 1} ({where})")
    return source.select(split_global_rows(idx, source.shard_rows()))
