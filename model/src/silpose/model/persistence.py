"""One-file persistence of a fitted :class:`ShapeStructureModel`: ``.npz`` + JSON header, no pickle.

File layout (``numpy.savez``, written crash-safely through :func:`silpose.shared.atomic.atomic_open`:
a temporary name, fsync, then ``os.replace``; docs/conventions.md, "Crash safety"):

=====================  ===============  ==============================================
key                    dtype / shape    meaning
=====================  ===============  ==============================================
``header``             uint8 (B,)       UTF-8 JSON document (below)
``weights``            float64 (M,)     mixing proportions pi_i
``means``              float64 (M, d)   component means mu_i
``components``         float64 (M,d,q)  principal axes W_i
``noise_variance``     float64 (M,)     isotropic variances sigma_i^2
``lower_bounds``       float64 (T,)     EM log-likelihood curve of the kept run
=====================  ===============  ==============================================

Header: ``format`` (= "silpose-model"), ``format_version``, ``feature_layout``
(FeatureLayout.to_dict), ``views``, ``joint_names``, ``n_rig_views``, ``rig`` (Rig.to_dict or
null), ``hyperparameters`` (ShapeStructureModel.hyperparameters), ``training`` (n_iter, converged,
lower_bound, initial_bound, fit time, n_train), ``dataset`` (root, manifest sha256 when known, the generator
config, ...), ``training_config`` (how ``silpose train`` was run: held-out fraction, seed, selection),
``plausibility`` (the :class:`~silpose.model.plausibility.PlausibilityCalibration` as a dict, or
null: files written before it have none), ``mixing`` (the :class:`~silpose.model.mixing.Mixing` calibration of the
posterior mean's weights as a dict, or null: files written before it have none), ``arrays`` (name -> [dtype, shape]) and ``arrays_sha256`` (sha256 over every array's name,
dtype, shape and bytes, in sorted key order) which :func:`load_model` verifies.
"""

from __future__ import annotations

import hashlib
import json
import zipfile
from pathlib import Path

import numpy as np

from silpose.shared.atomic import atomic_open
from silpose.shared.camera import Rig
from silpose.shared.skeleton import JOINT_NAMES

from .features import FeatureLayout
from .mppca import MPPCA
from .mixing import Mixing
from .plausibility import PlausibilityCalibration
from .shape_model import ShapeStructureModel

FORMAT_NAME = "silpose-model"
FORMAT_VERSION = 1
ARRAY_KEYS = ("weights", "means", "components", "noise_variance", "lower_bounds")


class ModelFileError(ValueError):
    """A model file cannot be read; the message names the file and the field."""


def arrays_sha256(arrays: dict[str, np.ndarray]) -> str:
    """sha256 over (name, dtype, shape, C-order bytes) of each array, keys sorted."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(name.encode())
        h.update(a.dtype.str.encode())
        h.update(repr(tuple(a.shape)).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def save_model(path: str | Path, model: ShapeStructureModel) -> Path:
    """Write a fitted ShapeStructureModel to ``path`` (``.npz``); returns the path."""
    path = Path(path)
    layout = model.fitted_layout()
    mix = model.mixture_
    arrays = {
        "weights": np.asarray(mix.weights_, dtype=np.float64),
        "means": np.asarray(mix.means_, dtype=np.float64),
        "components": np.asarray(mix.components_, dtype=np.float64),
        "noise_variance": np.asarray(mix.noise_variance_, dtype=np.float64),
        "lower_bounds": np.asarray(getattr(mix, "lower_bounds_", []), dtype=np.float64).reshape(-1),
    }
    rig = getattr(model, "rig_", None)
    header = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "feature_layout": layout.to_dict(),
        "views": list(layout.views),
        "joint_names": list(JOINT_NAMES),
        "n_rig_views": int(model.n_rig_views_),
        "rig": None if rig is None else rig.to_dict(),
        "hyperparameters": model.hyperparameters(),
        "training": {
            "n_iter": int(getattr(mix, "n_iter_", -1)),
            "converged": bool(getattr(mix, "converged_", False)),
            "lower_bound": float(getattr(mix, "lower_bound_", float("nan"))),
            "initial_bound": float(getattr(mix, "initial_bound_", float("nan"))),
            "fit_time_s": float(getattr(model, "fit_time_", float("nan"))),
            "n_train": int(getattr(model, "n_train_", -1)),
        },
        "dataset": dict(getattr(model, "dataset_info_", {}) or {}),
        "training_config": dict(getattr(model, "training_config_", {}) or {}),
        "plausibility": None if getattr(model, "plausibility_", None) is None else model.plausibility_.to_dict(),
        "mixing": None if getattr(model, "mixing_", None) is None else model.mixing_.to_dict(),
        "arrays": {k: [v.dtype.str, list(v.shape)] for k, v in arrays.items()},
        "arrays_sha256": arrays_sha256(arrays),
    }
    blob = np.frombuffer(json.dumps(header, sort_keys=True).encode("utf-8"), dtype=np.uint8)
    with atomic_open(path, "wb") as f:  # a file object keeps numpy from appending another ".npz"
        np.savez(f, header=blob, **arrays)
    return path


def read_header(path: str | Path) -> dict:
    """The validated JSON header of a model file (without loading the parameters into a model)."""
    header, _ = _read(path)
    return header


def _read(path: str | Path) -> tuple[dict, dict[str, np.ndarray]]:
    path = Path(path)
    if not path.is_file():
        raise ModelFileError(f"{path}: no such model file")
    if not zipfile.is_zipfile(path):  # else numpy's refusal to unpickle would be the message
        raise ModelFileError(f"{path}: not a silpose model file (not an .npz archive: a model is what silpose train "
                             "writes)")
    try:
        z = np.load(path, allow_pickle=False)
        if not isinstance(z, np.lib.npyio.NpzFile):
            raise ModelFileError(f"{path}: not a silpose model file (a bare .npy array, not an .npz archive)")
        with z:
            data = {k: z[k] for k in z.files}
    except ModelFileError:
        raise
    except (zipfile.BadZipFile, OSError, ValueError, EOFError) as exc:
        raise ModelFileError(f"{path}: not a silpose model file (cannot read it as .npz: {exc})") from None
    if "header" not in data:
        raise ModelFileError(f"{path}: not a silpose model file (field 'header' is missing)")
    raw = data.pop("header")
    if raw.dtype != np.uint8 or raw.ndim != 1:
        raise ModelFileError(f"{path}: field 'header' must be a uint8 vector, got {raw.dtype} {raw.shape}")
    try:
        header = json.loads(bytes(raw).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{path}: field 'header' is not valid UTF-8 JSON: {exc}") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT_NAME:
        got = header.get("format") if isinstance(header, dict) else type(header).__name__
        raise ModelFileError(f"{path}: field 'header.format' is {got!r}, expected {FORMAT_NAME!r}: not a silpose model file")
    version = header.get("format_version")
    if version != FORMAT_VERSION:
        raise ModelFileError(
            f"{path}: field 'header.format_version' is {version!r}; this silpose reads version {FORMAT_VERSION} only"
        )
    for key in ("feature_layout", "n_rig_views", "hyperparameters", "arrays_sha256", "joint_names"):
        if key not in header:
            raise ModelFileError(f"{path}: field 'header.{key}' is missing")
    for key in ARRAY_KEYS:
        if key not in data:
            raise ModelFileError(f"{path}: field {key!r} (array) is missing")
    extra = sorted(set(data) - set(ARRAY_KEYS))
    if extra:
        raise ModelFileError(f"{path}: unexpected fields {extra}")
    digest = arrays_sha256(data)
    if digest != header["arrays_sha256"]:
        raise ModelFileError(
            f"{path}: field 'header.arrays_sha256' does not match the stored arrays: the file was modified or corrupted"
        )
    return header, data


def _check_shapes(path: Path, header: dict, data: dict[str, np.ndarray], layout: FeatureLayout) -> None:
    hp = header["hyperparameters"]
    w, mu, W, s2 = data["weights"], data["means"], data["components"], data["noise_variance"]
    if w.ndim != 1 or w.size < 1:
        raise ModelFileError(f"{path}: field 'weights' must be a non-empty vector, got shape {w.shape}")
    m = w.shape[0]
    fits = int(hp.get("n_fits", 1))
    if m != int(hp.get("n_components", m)) * fits:
        raise ModelFileError(f"{path}: field 'weights' has {m} components, header.hyperparameters.n_components "
                             f"x n_fits says {hp['n_components']} x {fits}")
    if mu.shape != (m, layout.dim):
        raise ModelFileError(f"{path}: field 'means' has shape {mu.shape}, expected ({m}, {layout.dim}) from the feature layout")
    q = int(hp.get("n_latent", W.shape[-1] if W.ndim == 3 else -1))
    if W.shape != (m, layout.dim, q):
        raise ModelFileError(f"{path}: field 'components' has shape {W.shape}, expected ({m}, {layout.dim}, {q})")
    if s2.shape != (m,):
        raise ModelFileError(f"{path}: field 'noise_variance' has shape {s2.shape}, expected ({m},)")
    for name in ("weights", "means", "components", "noise_variance"):
        if not np.all(np.isfinite(data[name])):
            raise ModelFileError(f"{path}: field {name!r} contains NaN or inf")
    if np.any(s2 <= 0):
        raise ModelFileError(f"{path}: field 'noise_variance' must be > 0")
    if np.any(w < 0) or abs(float(w.sum()) - 1.0) > 1e-6:
        raise ModelFileError(f"{path}: field 'weights' must be non-negative and sum to 1 (sum {w.sum():.8g})")
    if list(header["joint_names"]) != list(JOINT_NAMES):
        raise ModelFileError(f"{path}: field 'header.joint_names' differs from this silpose's skeleton")
    if max(layout.views) >= int(header["n_rig_views"]):
        raise ModelFileError(f"{path}: field 'header.feature_layout.views' {layout.views} exceeds n_rig_views {header['n_rig_views']}")


def load_model(path: str | Path) -> ShapeStructureModel:
    """Read a model written by :func:`save_model`; raises :class:`ModelFileError` naming the file and field."""
    path = Path(path)
    header, data = _read(path)
    try:
        layout = FeatureLayout.from_dict(header["feature_layout"], source=f"{path}: field 'header.feature_layout'")
    except ValueError as exc:
        raise ModelFileError(str(exc)) from None
    _check_shapes(path, header, data, layout)
    hp = dict(header["hyperparameters"])
    try:
        model = ShapeStructureModel(
            n_components=int(hp["n_components"]),
            n_latent=int(hp["n_latent"]),
            structure_weight=float(hp["structure_weight"]),
            views=None if hp.get("views") is None else tuple(hp["views"]),
            noise_variance=float(hp["noise_variance"]),
            joint_frame=hp.get("joint_frame"),
            noise_dof=bool(hp.get("noise_dof", False)),
            tol=float(hp.get("tol", 1e-4)),
            max_iter=int(hp.get("max_iter", 200)),
            n_init=int(hp.get("n_init", 3)),
            n_fits=int(hp.get("n_fits", 1)),
            random_state=hp.get("random_state"),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ModelFileError(f"{path}: field 'header.hyperparameters' is invalid: {exc!r}") from None
    rig = None
    if header.get("rig") is not None:
        try:
            rig = Rig.from_dict(header["rig"], source=f"{path}: header.rig")
        except Exception as exc:  # RigError and malformed dicts alike
            raise ModelFileError(f"{path}: field 'header.rig' is invalid: {exc}") from None
        if len(rig) != int(header["n_rig_views"]):
            raise ModelFileError(f"{path}: field 'header.rig' has {len(rig)} cameras, n_rig_views is {header['n_rig_views']}")
    if layout.joint_frame == "stature" and rig is None:
        raise ModelFileError(f"{path}: field 'header.rig' is missing, but the feature layout's joints are in the "
                             "'stature' frame, which needs the cameras")
    mix = MPPCA(n_components=int(data["weights"].shape[0]), n_latent=model.n_latent, tol=model.tol,
                max_iter=model.max_iter, n_init=model.n_init, random_state=model.random_state)
    mix.weights_ = data["weights"]
    mix.means_ = data["means"]
    mix.components_ = data["components"]
    mix.n_latent_ = int(data["components"].shape[-1])
    mix.noise_variance_ = data["noise_variance"]
    mix.lower_bounds_ = data["lower_bounds"]
    training = header.get("training", {})
    mix.n_iter_ = int(training.get("n_iter", -1))
    mix.converged_ = bool(training.get("converged", False))
    mix.lower_bound_ = float(training.get("lower_bound", float("nan")))
    mix.initial_bound_ = float(training.get("initial_bound", float("nan")))
    mix.n_features_in_ = layout.dim
    model.layout_ = layout
    model.mixture_ = mix
    model.n_rig_views_ = int(header["n_rig_views"])
    model.rig_ = rig
    model.fit_time_ = float(training.get("fit_time_s", float("nan")))
    model.n_train_ = int(training.get("n_train", -1))
    model.dataset_info_ = dict(header.get("dataset", {}) or {})
    model.training_config_ = dict(header.get("training_config", {}) or {})
    model.plausibility_ = None
    if header.get("plausibility") is not None:
        try:
            model.plausibility_ = PlausibilityCalibration.from_dict(header["plausibility"],
                                                                    source=f"{path}: field 'header.plausibility'")
        except ValueError as exc:
            raise ModelFileError(str(exc)) from None
    model.mixing_ = None
    if header.get("mixing") is not None:
        try:
            model.mixing_ = Mixing.from_dict(header["mixing"], source=f"{path}: field 'header.mixing'")
        except ValueError as exc:
            raise ModelFileError(str(exc)) from None
    model.header_ = header
    return model


def is_model_file(path: str | Path) -> bool:
    """True if ``path`` is an .npz archive whose header names the silpose model format (any format
    version): a file ``silpose train`` may replace (``silpose.shared.output_dir.claim_files``)."""
    try:
        z = np.load(path, allow_pickle=False)
    except (zipfile.BadZipFile, OSError, ValueError, EOFError):
        return False
    if not isinstance(z, np.lib.npyio.NpzFile):
        return False
    with z:
        try:
            header = json.loads(bytes(z["header"]).decode("utf-8")) if "header" in z.files else None
        except (zipfile.BadZipFile, OSError, ValueError, EOFError):
            return False
    return isinstance(header, dict) and header.get("format") == FORMAT_NAME
