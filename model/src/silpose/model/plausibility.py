"""How typical an input is: the log marginal likelihood of the observed views as a calibrated percentile.

Every inference computes ``log p(a)``, the log density of the observed views' contour dims under
the prior (``silpose.model.conditioning``; nats). Its scale depends on which views are observed
(d_a = 400 dims per view) and on the model, so a raw value says little. A
:class:`PlausibilityCalibration`, built at training time from held-out training inputs, turns it
into a percentile: the share (%) of held-out inputs *with the same subset of views* whose log
marginal is lower.

Calibration inputs. The model assumes (docs/conventions.md, "Model") that an observed contour is a
clean shape plus independent Gaussian noise of variance s^2 (the model's ``noise_variance``,
normalised contour units^2) on every coordinate. The held-out inputs are therefore calibrated *as
the model expects to observe them*: each held-out walker's normalised contours get ``n_draws``
draws of that noise (stream ``derive_rng(seed, stream_code("plausibility"))``), so a genuine
noisy input sits inside the calibrated range while a clean one scores near 100. Calibrating on
clean held-out contours instead would put almost every noisy test input below the whole range
(measured on the default preset: 92 % of the evaluation's noisy 4-view test inputs below the
lowest clean held-out value).

Per subset. K modelled views give 2^K - 1 view subsets (15 for 4); each gets its own table of
percentiles 0, 0.5, ..., 100 of the calibration log marginals. A frame whose log marginal is below
the ``flag_percentile`` percentile (default 1 %) of its subset's table is *implausible*
(``silpose infer`` flags it). The calibration holds for the noise variance it was made with; an
inference at another s^2 gets NaN percentiles and no flags.

Convex silhouettes (:func:`convex_in_every_view`). A smooth blob -- a box, a rectangle, a bin bag --
is *more* likely under the prior than any person (it sits near a component mean: percentile 100), so
no likelihood threshold flags it. A person's silhouette is never convex: the neck, the armpits and
the gap between the legs make its area clearly smaller than its convex hull's. Measured on the
default preset's 500 test walkers x 4 views (clothing and builds the model never saw): solidity
(area / convex-hull area) median 0.65, largest 0.93 clean and 0.91 with the evaluation's standard
noise. A frame whose every observed view has solidity >= :data:`CONVEX_SOLIDITY` (0.97) is flagged
too, whatever its likelihood. It needs no calibration, so it applies at any s^2.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import cv2
import numpy as np

from silpose.shared.seeds import derive_rng, stream_code

from .features import denormalise_contours, normalise_contours

__all__ = ["PlausibilityCalibration", "PERCENTILES", "DEFAULT_FLAG_PERCENTILE", "CONVEX_SOLIDITY", "subset_key",
           "view_subsets", "solidity", "convex_in_every_view"]

#: the percentile grid of every table (0, 0.5, ..., 100)
PERCENTILES = np.linspace(0.0, 100.0, 201)
#: frames below this percentile of their subset's calibration are implausible
DEFAULT_FLAG_PERCENTILE = 1.0
#: noise draws per held-out walker and view subset
DEFAULT_DRAWS = 3
#: held-out walkers used at most (the first ones): bounds the cost on large presets
MAX_INPUTS = 400
#: the noise stream of the calibration (silpose.shared.seeds)
PLAUSIBILITY_STREAM = "plausibility"
#: a frame whose every observed view is at least this convex (area / hull area) is not a person
CONVEX_SOLIDITY = 0.97


def solidity(contours_px: np.ndarray) -> np.ndarray:
    """Area over convex-hull area (...,) of closed contours (..., n, 2) px; NaN for non-finite or empty ones."""
    c = np.asarray(contours_px, dtype=np.float64)
    flat = c.reshape(-1, c.shape[-2], 2)
    out = np.full(len(flat), np.nan)
    for i, poly in enumerate(flat):
        if not np.isfinite(poly).all():
            continue
        pts = poly.astype(np.float32)
        hull = cv2.contourArea(cv2.convexHull(pts))
        if hull > 0:
            out[i] = abs(cv2.contourArea(pts)) / hull
    return out.reshape(c.shape[:-2])


def convex_in_every_view(contours_px: np.ndarray, present: np.ndarray, threshold: float = CONVEX_SOLIDITY) -> np.ndarray:
    """(N,) bool: every present view of the frame has solidity >= ``threshold`` (module doc); False for a
    frame without a present view. contours_px (N, K, n, 2) px, present (N, K) bool."""
    p = np.asarray(present, dtype=bool)
    s = np.where(p, solidity(np.where(p[..., None, None], contours_px, np.nan)), np.nan)
    return p.any(axis=1) & np.all(~p | (s >= threshold), axis=1)


def subset_key(present_row) -> str:
    """'0123'-style key of a (K,) bool pattern of present modelled views (positions in the model's view order)."""
    return "".join(str(i) for i in np.flatnonzero(np.asarray(present_row, dtype=bool))) or "-"


def view_subsets(k: int) -> list[tuple[int, ...]]:
    """Every non-empty subset of ``k`` view positions, largest first."""
    return [s for r in range(k, 0, -1) for s in itertools.combinations(range(k), r)]


@dataclass
class PlausibilityCalibration:
    """Percentile tables of held-out log marginals, one per view subset (module doc).

    Attributes:
        noise_variance: the s^2 (normalised units^2) the tables were computed with.
        tables: {subset key: (201,) log marginal at PERCENTILES}, keys from :func:`subset_key`.
        n_inputs: held-out walkers used; n_draws: noise draws per walker; seed: noise seed.
        flag_percentile: frames below this percentile are implausible.
    """

    noise_variance: float
    tables: dict = field(default_factory=dict)
    n_inputs: int = 0
    n_draws: int = DEFAULT_DRAWS
    seed: int = 0
    flag_percentile: float = DEFAULT_FLAG_PERCENTILE

    # ------------------------------------------------------------------ building
    @classmethod
    def fit(cls, model, contours_px: np.ndarray, *, n_draws: int = DEFAULT_DRAWS, seed: int = 0,
            flag_percentile: float = DEFAULT_FLAG_PERCENTILE) -> "PlausibilityCalibration":
        """Calibrate ``model`` (a fitted ShapeStructureModel) on held-out inputs.

        Args:
            contours_px: (N, K_rig, n, 2) clean pixel contours of held-out training walkers (rig order); the
                first :data:`MAX_INPUTS` are used.
            n_draws: noise draws per walker (module doc).
        Cost: 2^K - 1 subsets x min(N, MAX_INPUTS) x n_draws inferences (9,000 for the default preset).
        """
        c = np.asarray(contours_px, dtype=np.float64)[:MAX_INPUTS]
        layout = model.fitted_layout()
        if c.ndim != 4 or c.shape[1] != model.n_rig_views_ or len(c) == 0:
            raise ValueError(f"calibration contours must have shape (N>0, {model.n_rig_views_}, n, 2), got {c.shape}")
        s2 = float(model.noise_variance)
        views = list(layout.views)
        norm, cen, sc = normalise_contours(c[:, views])
        rng = derive_rng(int(seed), stream_code(PLAUSIBILITY_STREAM))
        draws = norm[None] + rng.normal(0.0, np.sqrt(s2), size=(int(n_draws),) + norm.shape)
        noisy = denormalise_contours(draws, cen[None], sc[None]).reshape((-1,) + norm.shape[1:])
        cal = cls(noise_variance=s2, n_inputs=int(len(c)), n_draws=int(n_draws), seed=int(seed),
                  flag_percentile=float(flag_percentile))
        for sub in view_subsets(layout.n_views):
            present = np.zeros((len(noisy), layout.n_views), dtype=bool)
            present[:, list(sub)] = True
            lm = model.infer(noisy, present, input_views=layout.views).log_marginal
            cal.tables[subset_key(present[0])] = np.percentile(lm, PERCENTILES)
        return cal

    # ------------------------------------------------------------------ use
    def applies_to(self, noise_variance: float) -> bool:
        """True when an inference at ``noise_variance`` can use these tables."""
        return bool(np.isclose(float(noise_variance), self.noise_variance, rtol=1e-9, atol=0.0))

    def percentile(self, log_marginal: np.ndarray, present: np.ndarray) -> np.ndarray:
        """(N,) % of calibration inputs with the same view subset whose log marginal is lower.

        log_marginal (N,) nats; present (N, K) bool in the model's view order. Linear interpolation in
        the subset's table; 0 below its lowest value, 100 above its highest; NaN for a NaN log marginal or
        a subset without a table.
        """
        lm = np.asarray(log_marginal, dtype=np.float64)
        p = np.asarray(present, dtype=bool)
        out = np.full(lm.shape, np.nan)
        patterns, inverse = np.unique(p, axis=0, return_inverse=True)
        for g, pattern in enumerate(patterns):
            table = self.tables.get(subset_key(pattern))
            rows = np.flatnonzero(inverse.reshape(-1) == g)
            if table is None:
                continue
            x = lm[rows]
            # np.interp needs increasing x; ties in the table (flat stretches) are fine
            out[rows] = np.where(np.isfinite(x), np.interp(x, table, PERCENTILES, left=0.0, right=100.0), np.nan)
        return out

    def implausible(self, percentile: np.ndarray) -> np.ndarray:
        """(N,) bool: below ``flag_percentile`` (NaN percentiles are not flagged)."""
        pct = np.asarray(percentile, dtype=np.float64)
        return np.where(np.isfinite(pct), pct < self.flag_percentile, False)

    # ------------------------------------------------------------------ serialisation
    def to_dict(self) -> dict:
        return {"noise_variance": self.noise_variance, "n_inputs": self.n_inputs, "n_draws": self.n_draws,
                "seed": self.seed, "flag_percentile": self.flag_percentile,
                "percentiles": "0, 0.5, ..., 100",
                "tables": {k: [float(v) for v in t] for k, t in sorted(self.tables.items())}}

    @classmethod
    def from_dict(cls, d: dict, source: str = "plausibility") -> "PlausibilityCalibration":
        """Inverse of :meth:`to_dict`; ValueError naming ``source`` and the field for a malformed document."""
        if not isinstance(d, dict):
            raise ValueError(f"{source}: must be a JSON object")
        try:
            cal = cls(noise_variance=float(d["noise_variance"]), n_inputs=int(d["n_inputs"]),
                      n_draws=int(d["n_draws"]), seed=int(d["seed"]), flag_percentile=float(d["flag_percentile"]))
            tables = d["tables"]
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{source}: field {exc} is missing or invalid") from None
        if not isinstance(tables, dict):
            raise ValueError(f"{source}: field 'tables' must be an object")
        for key, values in tables.items():
            t = np.asarray(values, dtype=np.float64)
            if t.shape != PERCENTILES.shape or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
                raise ValueError(f"{source}: field 'tables.{key}' must hold {PERCENTILES.size} finite increasing values")
            cal.tables[str(key)] = t
        return cal
