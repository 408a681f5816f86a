"""silpose.model: the shape+structure prior (mixture of PPCA over multi-view contours + 3D joints).

Public API (imported lazily, so ``import silpose.model.cli`` and ``silpose --help`` stay light)::

    MPPCA                     mixture of probabilistic PCA, scikit-learn style (mppca.py)
    condition, Conditioner    exact Gaussian conditioning of an MPPCA (conditional.py)
    FeatureLayout             the shape vector layout, paper eq. 4 (features.py)
    ShapeStructureModel       fit on contours + joints, infer joints and contours (shape_model.py)
    InferenceResult           what ``ShapeStructureModel.infer`` returns
    save_model, load_model    one-file .npz persistence, no pickle (persistence.py)
    ModelFileError            a model file cannot be read
    select, SelectionResult   validation grid search over q, M, structure weight, noise (selection.py)
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "MPPCA": "mppca",
    "condition": "conditional",
    "condition_rows": "conditional",
    "Conditioner": "conditional",
    "ConditionalResult": "conditional",
    "FeatureLayout": "features",
    "ShapeStructureModel": "shape_model",
    "InferenceResult": "shape_model",
    "save_model": "persistence",
    "load_model": "persistence",
    "read_header": "persistence",
    "ModelFileError": "persistence",
    "select": "selection",
    "SelectionResult": "selection",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'silpose.model' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
