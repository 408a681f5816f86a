"""The posterior mean with calibrated component weights: tempered responsibilities and the view pairs' heading votes.

The posterior mean of the joints is the responsibility-weighted average of the components' conditional means
(``silpose.model.conditioning``): ``E[s | a] = sum_i r_i m_i``, ``r_i = p(i | a)``. The responsibilities of a
model fitted on few, diverse samples are far too sure of themselves: the mixture scores each of the 2 n K contour
coordinates as independent given the component (one isotropic noise variance per component), while neighbouring
points of an outline move together, so a 1,600-dimensional observation counts its evidence many times over and
r_1 is ~0.998 on average (motions preset, 4 views). When the winner faces the wrong way (a *flip*,
``silpose.model.hypotheses``) the answer is off by a half turn of the body, although a component facing the
right way is usually the second or third: on the motions preset's test split the robust posterior mean is flipped
in 22 % of the frames, the best of the top 3 hypotheses in 1.8 %.

:class:`Mixing` replaces the weights by

    w_i  ∝  exp( log r_i / T_k  +  beta * mean_v cos(theta_i - phi_v) )

- ``T_k`` (>= 1) is a *temperature* per number k of present views: the responsibilities are tempered as if the
  observation carried 1 / T_k of its nominal evidence; T = 1 is the mixture's own posterior mean.
- ``theta_i`` is the heading of component i's joints (:func:`silpose.model.hypotheses.heading`) and ``phi_v`` the
  heading of the posterior mean given the v-th pair of present views (``Posterior.pair_headings``; needs >= 3
  present views, otherwise the term is 0): components facing the way most pairs of views see the person gain
  weight -- the soft form of :func:`~silpose.model.hypotheses.consensus_choice`.

Both are calibrated per model on held-out training samples (:func:`calibrate_mixing`: the grid point of least
mean joint error, robust inference, every subset of views), never on test data, and saved in the model file
(``silpose.model.persistence``). A model without a calibration answers with the plain posterior mean.
Measured (robust inference, the evaluation's standard noise, mean joint error cm; validation = the trainer's
held-out rows with another noise seed): docs/mixing.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from silpose.shared.metrics import pose_error_cm

from .checks import model_inputs
from .hypotheses import FLIP_ANGLE, Hypotheses, heading, wrap_angle
from .plausibility import view_subsets
from .robust import RobustSettings, robust_infer

__all__ = ["Mixing", "mixed_joints", "vote_agreement", "agreeing_choice", "mixture_terms", "calibrate_mixing", "TEMPERATURES", "VOTE_WEIGHTS"]

#: temperatures tried by :func:`calibrate_mixing`
TEMPERATURES = (1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 7.0, 10.0, 15.0, 20.0)
#: vote weights beta tried by :func:`calibrate_mixing`
VOTE_WEIGHTS = (0.0, 2.0, 5.0, 10.0)
#: held-out samples used at most (the first ones): bounds the cost on large presets (every view subset is
#: inferred robustly with every component's means)
MAX_INPUTS = 200
#: a grid value is chosen over a smaller one only if it lowers the held-out error by more than this (relative)
MARGIN = 0.005
#: floor of the responsibilities in log r (a responsibility that underflowed to 0)
R_FLOOR = 1e-300


@dataclass
class Mixing:
    """Calibrated component weights of the posterior mean (module doc).

    Attributes:
        temperatures: {k present views: T_k >= 1}; a view count without an entry uses T = 1.
        vote_weight: beta >= 0, weight of the heading votes of the view pairs.
        n_inputs: held-out samples the calibration used; errors_cm: {k: [error cm at T=1, at the chosen T]}
            measured there (for the record).
    """

    temperatures: dict = field(default_factory=dict)
    vote_weight: float = 0.0
    n_inputs: int = 0
    errors_cm: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.temperatures = {int(k): float(t) for k, t in self.temperatures.items()}
        if any(not np.isfinite(t) or t < 1.0 for t in self.temperatures.values()):
            raise ValueError(f"Mixing temperatures must be finite and >= 1, got {self.temperatures}")
        if not np.isfinite(self.vote_weight) or self.vote_weight < 0:
            raise ValueError(f"Mixing vote_weight must be finite and >= 0, got {self.vote_weight}")

    def temperature(self, n_present: np.ndarray) -> np.ndarray:
        """(N,) T per frame from its number of present views (N,) int."""
        k = np.asarray(n_present, dtype=np.int64)
        return np.array([self.temperatures.get(int(v), 1.0) for v in k.reshape(-1)]).reshape(k.shape)

    @property
    def needs_votes(self) -> bool:
        return self.vote_weight > 0

    def to_dict(self) -> dict:
        return {"temperatures": {str(k): v for k, v in sorted(self.temperatures.items())},
                "vote_weight": self.vote_weight, "n_inputs": self.n_inputs,
                "errors_cm": {str(k): [float(x) for x in v] for k, v in sorted(self.errors_cm.items())}}

    @classmethod
    def from_dict(cls, d: dict, source: str = "mixing") -> "Mixing":
        """Inverse of :meth:`to_dict`; ValueError naming ``source`` and the field for a malformed document."""
        if not isinstance(d, dict):
            raise ValueError(f"{source}: must be a JSON object")
        try:
            temps = {int(k): float(v) for k, v in dict(d["temperatures"]).items()}
            beta = float(d["vote_weight"])
            n = int(d.get("n_inputs", 0))
            errs = {int(k): [float(x) for x in v] for k, v in dict(d.get("errors_cm", {})).items()}
        except (KeyError, TypeError, ValueError) as exc:
            raise ValueError(f"{source}: field {exc} is missing or invalid") from None
        try:
            return cls(temperatures=temps, vote_weight=beta, n_inputs=n, errors_cm=errs)
        except ValueError as exc:
            raise ValueError(f"{source}: {exc}") from None


def vote_agreement(component_joints: np.ndarray, votes: np.ndarray) -> np.ndarray:
    """(N, M) mean over the frame's votes of cos(theta_i - phi_v), in [-1, 1]; 0 where a frame has no vote.

    component_joints (N, M, 19, 3) metres; votes (N, V) radians, NaN = no vote."""
    theta = heading(component_joints)  # (N, M)
    v = np.asarray(votes, dtype=np.float64)
    c = np.cos(wrap_angle(theta[:, :, None] - v[:, None, :]))  # (N, M, V)
    have = np.isfinite(c)
    count = have.sum(axis=2)
    return np.where(count > 0, np.where(have, c, 0.0).sum(axis=2) / np.maximum(count, 1), 0.0)


def mixed_joints(component_joints: np.ndarray, responsibilities: np.ndarray, temperature,
                 agreement: np.ndarray | None = None, vote_weight: float = 0.0) -> np.ndarray:
    """(N, 19, 3) metres: the posterior mean with the weights of the module doc.

    Args:
        component_joints: (N, M, 19, 3) each component's conditional mean of the joints (NaN for a component not
            evaluated: weight 0).
        responsibilities: (N, M) p(i | a).
        temperature: T, a float or (N,) one per frame (>= 1).
        agreement: (N, M) :func:`vote_agreement`, or None.
        vote_weight: beta.
    With T = 1 and no votes this is the mixture's posterior mean (up to the NaN components).
    """
    cj = np.asarray(component_joints, dtype=np.float64)
    r = np.asarray(responsibilities, dtype=np.float64)
    t = np.broadcast_to(np.asarray(temperature, dtype=np.float64), (len(r),))
    ok = np.isfinite(cj).all(axis=(2, 3)) & np.isfinite(r)
    score = np.log(np.maximum(np.where(ok, r, 0.0), R_FLOOR)) / t[:, None]
    if agreement is not None and vote_weight > 0:
        score = score + float(vote_weight) * np.asarray(agreement, dtype=np.float64)
    score = np.where(ok, score, -np.inf)
    best = score.max(axis=1, keepdims=True)
    w = np.where(ok, np.exp(score - np.where(np.isfinite(best), best, 0.0)), 0.0)
    total = w.sum(axis=1, keepdims=True)
    w = w / np.where(total > 0, total, 1.0)
    out = np.einsum("nm,nmjc->njc", w, np.where(ok[..., None, None], cj, 0.0))
    out[total[:, 0] <= 0] = np.nan
    return out


def agreeing_choice(hyp: Hypotheses, joints: np.ndarray) -> np.ndarray:
    """(N,) slot of the most probable hypothesis facing within 90 deg of ``joints`` (N, 19, 3) (the mixed posterior
    mean), 0 where none does: the hypotheses' ``chosen`` for a calibrated answer, so that
    :func:`~silpose.model.hypotheses.single_answer` does not turn the answer back to a likelier hypothesis the votes
    overruled."""
    diff = np.abs(wrap_angle(hyp.heading - heading(joints)[:, None]))  # (N, K), NaN in unused slots
    ok = (hyp.component >= 0) & np.where(np.isfinite(diff), diff <= FLIP_ANGLE, False)
    return np.where(ok.any(axis=1), np.argmax(ok, axis=1), 0).astype(np.intp)  # slots are sorted by probability


def mixture_terms(model, contours_px: np.ndarray, present: np.ndarray, *, robust=True,
                  noise_variance: float | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`mixed_joints` needs for frames of a fitted ShapeStructureModel: the components' joint means
    (N, M, 19, 3) metres, the responsibilities (N, M) and the view pairs' heading votes (N, V) radians (NaN = no
    vote), from rig-ordered pixel contours (N, K_rig, n, 2) with present views (N, K_rig) bool; ``robust`` as
    ``infer``'s."""
    settings = RobustSettings() if robust is True else (robust or None)
    s2 = float(model.noise_variance if noise_variance is None else noise_variance)
    inputs = model_inputs(model.fitted_layout(), model.n_rig_views_, contours_px, present, None, None, None)
    posterior = model.posterior()
    if settings is None:
        res, comp = posterior.infer(inputs, s2, components=True)
    else:
        res, comp = robust_infer(posterior, inputs, s2, settings, True)
    return comp, res.responsibilities, posterior.pair_headings(inputs, s2)


def calibrate_mixing(model, contours_px: np.ndarray, joints: np.ndarray, *, robust=True,
                     temperatures: Sequence[float] = TEMPERATURES,
                     vote_weights: Sequence[float] = VOTE_WEIGHTS, margin: float = MARGIN) -> Mixing:
    """Choose the temperatures and the vote weight of a fitted ShapeStructureModel on held-out samples.

    Args:
        model: the fitted model (its own ``mixing_`` is ignored here).
        contours_px: (N, K_rig, n, 2) pixel contours of held-out training samples (rig order), as the model will
            see them (the caller adds the noise it expects).
        joints: (N, 19, 3) their joints, metres. The first :data:`MAX_INPUTS` are used.
        robust: the inference to calibrate (``ShapeStructureModel.infer``'s ``robust``).
    For each number k of present views every sample is inferred once, sample i seeing the (i mod S)-th of the
    S subsets of k views (K inferences per sample, not 2^K - 1). beta is the grid value of least mean error over the frames
    with >= 3 present views (the votes need 3; with T chosen per view count for each beta); then T_k per view
    count k, given beta, the grid value of least mean error over the subsets of k views. Each choice is the
    smallest grid value whose error is within ``margin`` (relative) of the grid's least: a gain smaller than that
    on a few hundred held-out samples is not worth trusting (measured on the default preset: T 1.5 for one view
    gained 0.07 % on its held-out rows and lost 1 % on the test split).
    """
    layout = model.fitted_layout()
    c = np.asarray(contours_px, dtype=np.float64)[:MAX_INPUTS]
    j = np.asarray(joints, dtype=np.float64)[:MAX_INPUTS]
    if c.ndim != 4 or len(c) == 0 or j.shape != (len(c),) + j.shape[1:] or j.ndim != 3:
        raise ValueError(f"calibrate_mixing needs contours (N>0, K, n, 2) and joints (N, 19, 3), got {c.shape}, {j.shape}")
    kmod = layout.n_views
    temps = sorted(float(t) for t in temperatures)
    betas = sorted(float(b) for b in vote_weights)
    # errors[k][b_index, t_index]: summed error over the subsets of k views
    sums: dict[int, np.ndarray] = {}
    counts: dict[int, int] = {}
    for k in range(kmod, 0, -1):
        subsets = [s for s in view_subsets(kmod) if len(s) == k]
        present = np.zeros((len(c), model.n_rig_views_), dtype=bool)  # rig order, as contours_px
        for i in range(len(c)):  # sample i sees the (i mod S)-th of the S subsets of k views
            present[i, [layout.views[p] for p in subsets[i % len(subsets)]]] = True
        comp, resp, votes = mixture_terms(model, c, present, robust=robust)
        agree = vote_agreement(comp, votes)
        grid = np.empty((len(betas), len(temps)))
        for bi, beta in enumerate(betas):
            for ti, t in enumerate(temps):
                grid[bi, ti] = pose_error_cm(mixed_joints(comp, resp, t, agree, beta), j).sum()
        sums[k], counts[k] = grid, len(c)
    voting = [k for k in sums if k >= 3]
    if voting:
        total = sum(sums[k].min(axis=1) for k in voting)  # (B,) each beta with its best T per view count
        bi = _smallest_near_best(total, margin)
    else:
        bi = 0
    out_t, errs = {}, {}
    for k, grid in sums.items():  # fewer than 3 views: no votes, every beta gives the same row
        row = grid[bi]
        ti = _smallest_near_best(row, margin)
        out_t[k] = temps[ti]
        errs[k] = [float(grid[betas.index(0.0), temps.index(1.0)] / counts[k]) if 0.0 in betas and 1.0 in temps
                   else float("nan"), float(row[ti] / counts[k])]
    return Mixing(temperatures=out_t, vote_weight=betas[bi], n_inputs=int(len(c)), errors_cm=errs)


def _smallest_near_best(errors: np.ndarray, margin: float) -> int:
    """Index of the first (smallest grid value) of ``errors`` (G,) within ``margin`` (relative) of their least."""
    e = np.asarray(errors, dtype=np.float64)
    return int(np.flatnonzero(e <= e.min() * (1.0 + float(margin)))[0])
