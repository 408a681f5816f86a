"""silpose.model: the shape+structure prior (mixture of PPCA over multi-view contours + 3D joints).

A library: estimators, their numerics and their model file; no command line, no image or video
I/O (those live in ``silpose.app``). Modules, lowest first::

    threads           BLAS held to one thread; the blocks of a batch on threads of their own (map_blocks)
    _ppca, _em        private numerics of the mixture of PPCA (densities, E/M-step sums)
    shards            row blocks EM maps over (ShardSource, ArrayShards)
    mppca             MPPCA, the scikit-learn style estimator (paper eq. 3)
    conditioning      Gaussian conditioning of an MPPCA: condition, Conditioner (the one inference path)
    stature           metric stature from calibrated silhouettes
    features          FeatureLayout, contour normalisation, shape_vectors (paper eq. 4)
    hypotheses        top-K pose hypotheses and the choice among them
    mixing            calibrated weights of the posterior mean (tempered responsibilities, heading votes)
    result            InferenceResult: what infer returns, its row operations (take, put, merge, nan_like)
    posterior         Posterior: conditioning on the present views, its cache of Conditioners
    checks            input checks of the shape model
    defaults          the shape model's default hyperparameters and how they were chosen
    fitting           what the shape model's fit entry points share: checks, layout, the mixture to fit
    inference_options what infer adds to a posterior: plausibility, mixing, hypotheses, untangling
    robust            robust inference: per-point weights, excursions, re-indexing, the loop
    streaming         DatasetShards: a dataset's Parquet shards as EM row blocks (locally or on Ray)
    shape_model       ShapeStructureModel: fit, fit_stream, infer (paper sections 3-4)
    persistence       save_model / load_model: the one-file .npz model, no pickle
    selection         validation grid search over q, M, structure weight and noise
    synthetic         synthetic shapes with a known linear joints -> contours link (tests)
"""

from __future__ import annotations

from .conditioning import BatchPosterior, Conditioner, MixtureParams, RowsPosterior, condition, condition_rows
from .features import FeatureLayout
from .mppca import MPPCA
from .persistence import ModelFileError, load_model, read_header, save_model
from .selection import SelectionResult, select
from .posterior import Posterior
from .result import InferenceResult
from .shape_model import ShapeStructureModel

__all__ = [
    "MPPCA",
    "Conditioner",
    "MixtureParams",
    "BatchPosterior",
    "Posterior",
    "RowsPosterior",
    "condition",
    "condition_rows",
    "FeatureLayout",
    "ShapeStructureModel",
    "InferenceResult",
    "save_model",
    "load_model",
    "read_header",
    "ModelFileError",
    "select",
    "SelectionResult",
]
