"""Top-K pose hypotheses from the mixture's components, facing direction and flips, and the choice
among hypotheses: a vote of the view pairs for one frame, a Viterbi path for a sequence.

The posterior of the shape+structure model is a mixture (``silpose.model.conditioning``): given
the observed views, component i proposes the conditional mean ``E[s | a, i]`` of the joints with
weight ``r_i = p(i | a)``. Those component means are the hypotheses; the posterior mean is their
weighted average. Silhouettes are nearly mirror-symmetric under a half turn of the body (a walker
facing theta and one facing theta + 180 deg with the other leg forward cast almost the same
silhouette in every view), so a wrong-facing component can win -- a *flip*.

Facing direction (:func:`heading`). With z up, the body's left axis is the sum of the
hip and shoulder axes, ``a = (l_hip - r_hip) + (l_shoulder - r_shoulder)``; the forward direction
is ``a x z = (a_y, -a_x)`` in the floor plane and the heading is its angle, radians
counter-clockwise from world +x (the datagen walk's ``heading``). A hypothesis is a *flip* when
its heading differs from the truth by more than 90 deg (:data:`FLIP_ANGLE`).

Top-K (:func:`top_hypotheses`). Components are sorted by posterior weight; a component whose
joints lie within ``merge_cm`` (mean joint distance) of a more probable kept hypothesis is merged
into it (its weight added), so the K hypotheses are distinct poses. Their probabilities are the
(merged) posterior weights; they sum to <= 1 over the K kept.

One frame (:func:`consensus_choice`). The mixture weights of a 1,600-dimensional observation are
nearly 0/1 and a single corrupted view can decide the facing. Each pair of the present views (6
for 4 views) gives its own posterior-mean heading -- a vote; the chosen hypothesis is the most
probable one whose heading agrees (within 90 deg) with the most votes (a tie keeps the more
probable). With fewer than 3 present views there is nothing to vote on and the most probable
hypothesis is kept. Measured on the default preset (500 test walkers, 4 views, top 3; flips with
the posterior mean -> with the consensus): clean contours 1.8 -> 0.4 %, the evaluation's standard
noise before issue 12 1.4 -> 0.2 %, the current standard noise 3.2 -> 0.8 %, "mask mild" 10.2 ->
7.6 %. Pairs vote better than every subset of >= 2 views (0.4 / 1.4 / 8.0 % on the last three):
the larger subsets share the corrupted view with the full set.

A sequence (:func:`temporal_choice`). Over T frames of one person, a Viterbi path picks one
hypothesis per frame maximising

    sum_t log p_t(h_t) / T_temp - sum_t [ (dtheta_t / sigma)^2 + (dj_t / sigma_j)^2 ] / 2,

where ``dtheta_t`` is the heading change between consecutive chosen hypotheses, ``dj_t`` the mean
distance of their 19 joints (root-relative), ``sigma`` and ``sigma_j`` the expected turn and joint
motion per frame (``turn_sigma_deg`` and ``pose_sigma_m``, :data:`TEMPORAL_TURN_SIGMA_DEG` and
:data:`TEMPORAL_POSE_SIGMA_M`, times the frame gap) and ``T_temp`` a temperature. A flipped frame costs a
180 deg turn twice, so a path through the right-facing hypotheses wins unless the evidence for the flip is
overwhelming. Cost O(T K^2).

The temperature divides the frames' evidence against the motion terms; only the ratio sigma^2 / T_temp matters. The
responsibilities are overconfident (a frame's top hypothesis often holds 0.998 of the weight,
``silpose.model.mixing``), and on the motions preset a high temperature helped: T_temp 100 with 20 deg and 0.15 m
(ratio 4) was the earlier setting. It failed smaller models: with few, broad components the steadiest sequence of
component means wins whatever the frames say, a whole track facing the wrong way (a lab-rig model of 5 components on
400 walkers, the benchmark's recording of two walkers: 7.67 cm at ratio 81, 13.01 cm at ratio 8, 16.80 cm with
the earlier setting; every frame's posterior mean 8.02). Calibrating a temperature per model on the trainer's
held-out frames (temperature scaling of the hypotheses' probabilities) did not predict it: that calibration gave 10
for both lab-rig models of the tests and benchmark, and 15 for the motions preset, while their paths wanted ratios
from 4 to 81 and more. So the choice is
untempered (:data:`TEMPORAL_TEMPERATURE` 1) with 9 deg and 0.067 m (ratio 81), never far from the best of the
ratios tried on ten sets of sequences (below).

The answer along a sequence (:func:`sequence_answer`): the chosen hypothesis itself. Chosen along the
frames, the hypothesis carries evidence the posterior mean does not have, and the mean of the frame's
components (what :func:`single_answer` keeps unless the choice faces the other way) mixes in the very
hypotheses the path rejected.

Measured (``silpose.eval.sequences``: 1 s sequences at 30 fps, standard noise, robust inference, 4
views, cm, 2026-12-06). The earlier settings were chosen on sequences of the train split's held-out part (the
samples ``silpose train`` leaves out: motions preset, 32 sequences of 6 held-out clips and 8 procedural
walkers; default preset, 40 walkers); the test sequences (held-out subjects' clips; test walkers) were
scored afterwards:

| | motions, held-out train clips | motions, test clips | default, held-out | default, test |
|---|---|---|---|---|
| each frame alone (:func:`single_answer`) | 13.87 | 12.30 | 3.75 | 3.21 |
| before: 3 hypotheses, untempered, no joint term, :func:`single_answer` | 13.33 | 12.60 | 3.66 | 3.19 |
| 8 hypotheses, T_temp 100, no joint term, the chosen hypothesis | 11.12 | 10.57 | 3.58 | 3.24 |
| 8 hypotheses, T_temp 100, 20 deg, 0.15 m, the chosen hypothesis (before) | 10.62 | 10.54 | 3.57 | 3.22 |
| the same, untempered (T_temp 1, 20 deg, 0.15 m) | 12.81 | 12.43 | 3.61 | 3.27 |
| **untempered, 9 deg, 0.067 m (now)** | **11.92** | **11.02** | **3.61** | **3.26** |
| best of the 8 (an oracle) | 8.08 | 8.53 | 3.32 | 2.98 |

Held-out choices of the earlier setting: T_temp 10 / 30 / 100 gave 11.36 / 11.28 / 11.12 (no joint term); sigma_j
0.05 / 0.1 / 0.15 / 0.2 / 0.3 m gave 11.63 / 10.61 / 10.62 / 10.65 / 10.90 (T_temp 100); :func:`single_answer` after
the same choice 11.47. Flips (facing more than 90 deg from the truth), motions test clips: 9.7 % each frame alone,
3.0 % with the earlier setting. The ratio sigma^2 / T_temp on more sets (untempered; 6 / 9 / 12 deg with 0.045 /
0.067 / 0.09 m; the sequences cut into chunks of 16, each decided with the next ahead, "A stream"; held-out / test;
"small": models of the default preset's data with M 3, q 12 and M 10, q 30, one fit each; the lab models: the
tests' lab recording with its M 3 model and the benchmark's with its M 5 model, the root-relative error of the
rows the pipeline inferred, their hypotheses chosen again; cm):

| | every frame's posterior mean | 6 deg | **9 deg (now)** | 12 deg | the earlier T_temp 100, 20 deg, 0.15 m |
|---|---|---|---|---|---|
| motions | 13.87 / 12.30 | 11.30 / 11.23 | **11.92 / 11.02** | 12.44 / 11.60 | 10.62 / 10.54 (whole sequences) |
| default | 3.75 / 3.21 | 3.60 / 3.25 | **3.61 / 3.26** | 3.61 / 3.27 | 3.57 / 3.22 (whole sequences) |
| small M 3 | 10.39 / 9.60 | 9.45 / 9.08 | **9.47 / 9.13** | 9.60 / 9.12 | 9.56 / 9.90 (whole sequences) |
| small M 10 | 5.23 / 4.02 | 4.39 / 3.86 | **4.42 / 3.87** | 4.45 / 3.88 | 4.31 / 3.87 (whole sequences) |
| lab, tests' recording (50 frames) | 15.10 | 14.02 | **14.00** | 15.65 | – |
| lab, benchmark's recording (150 frames) | 8.02 | 8.23 | **7.67** | 7.50 | 16.80 (whole sequences) |

A stream (:func:`continue_choice`). When frames arrive a chunk at a time (a recording of several people,
``silpose infer --videos``: 16 steps per chunk), each track keeps where its path ended (:class:`PathEnd`: the
accumulated cost of the best path into each hypothesis of its latest decided frame) and the next frames continue
the same Viterbi recursion from it, with the same settings as a whole sequence. A frame is decided by the path that
is best at the end of the frames known by then, and never revised once written. How far that look-ahead reaches
matters: without it, a track is locked into the facing its first frames favour. In the lab recording of the tests
(``silpose.datagen.lab``, a small model), one walker's first 31 frames favour the wrong facing; decided each chunk
alone, the path kept it for all of them (the recording's world-frame error 17.32 cm, 13.30 with the next chunk
ahead). So the pipeline decides
a chunk only once the next one is inferred (``silpose.app.recordings.chunk_rows.choose_along_tracks``): every frame
sees 16 to 31 frames ahead, and its rows wait about that long anyway for their tracks to be decided (0.9 s,
``silpose.app.recordings.tracking``). Measured on the sequences above, cut into chunks of 16 as a recording is
(cm, held-out / test; the lab recordings: world-frame error through the pipeline itself, the tests' with its M 3
model, the benchmark's with its M 5 model, clean per-person masks' posterior mean 13.77 and 8.22):

| | motions | default | small M 3 | small M 10 | lab, tests' | lab, benchmark's |
|---|---|---|---|---|---|---|
| before: the previous frame's heading only (3 hypotheses, :func:`single_answer`) | 13.87 / 12.52 | 3.75 / 3.21 | 10.38 / 9.60 | 5.23 / 4.02 | 14.22 | 7.84 |
| each chunk decided alone | 11.77 / 11.12 | 3.61 / 3.26 | 9.47 / 9.12 | 4.42 / 3.87 | 17.32 | – |
| **each chunk decided with the next one ahead (now)** | **11.92 / 11.02** | **3.61 / 3.26** | **9.47 / 9.13** | **4.42 / 3.87** | **13.30** | **7.57** |

On these 1 s sequences (two chunks) the last row is the whole sequence at once; the lab recordings are 50 and 150
frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from silpose.shared.skeleton import JOINT_INDEX, N_JOINTS

__all__ = [
    "FLIP_ANGLE",
    "Hypotheses",
    "heading",
    "heading_error",
    "is_flip",
    "top_hypotheses",
    "consensus_choice",
    "temporal_choice",
    "PathEnd",
    "continue_choice",
    "single_answer",
    "sequence_answer",
    "TEMPORAL_TEMPERATURE",
    "TEMPORAL_POSE_SIGMA_M",
    "TEMPORAL_TURN_SIGMA_DEG",
    "TEMPORAL_HYPOTHESES",
]

#: radians: a hypothesis whose heading is further than this from the truth is a flip.
FLIP_ANGLE = np.pi / 2
#: smallest probability used in log p (keeps -log p finite for hypotheses with weight ~0).
PROB_FLOOR = 1e-12
#: temperature of the frames' log-probabilities in :func:`temporal_choice` (module doc, "A sequence": untempered)
TEMPORAL_TEMPERATURE = 1.0
#: expected heading change per frame in :func:`temporal_choice` (degrees, standard deviation)
TEMPORAL_TURN_SIGMA_DEG = 9.0
#: expected motion of the joints per frame in :func:`temporal_choice` (mean over the 19 joints, metres)
TEMPORAL_POSE_SIGMA_M = 0.067
#: hypotheses a choice along a sequence needs per frame (module doc: 3 left the right-facing pose out too often)
TEMPORAL_HYPOTHESES = 8

_LH, _RH = JOINT_INDEX["l_hip"], JOINT_INDEX["r_hip"]
_LS, _RS = JOINT_INDEX["l_shoulder"], JOINT_INDEX["r_shoulder"]


def heading(joints: np.ndarray) -> np.ndarray:
    """Facing direction (...,) in radians, counter-clockwise from world +x (module doc).

    joints (..., 19, 3) metres, z up (world orientation; absolute or root-relative). NaN joints give NaN.
    """
    j = np.asarray(joints, dtype=np.float64)
    if j.shape[-2:] != (N_JOINTS, 3):
        raise ValueError(f"joints must have shape (..., {N_JOINTS}, 3), got {j.shape}")
    left = (j[..., _LH, :] - j[..., _RH, :]) + (j[..., _LS, :] - j[..., _RS, :])
    return np.arctan2(-left[..., 0], left[..., 1])


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a, dtype=np.float64) + np.pi) % (2.0 * np.pi) - np.pi


def heading_error(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Absolute heading difference (...,) in [0, pi] radians between joints pred and true (..., 19, 3)."""
    return np.abs(wrap_angle(heading(pred) - heading(true)))


def is_flip(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """(...,) bool: pred faces more than :data:`FLIP_ANGLE` away from true."""
    return heading_error(pred, true) > FLIP_ANGLE


@dataclass
class Hypotheses:
    """K pose hypotheses of N frames, most probable first.

    Attributes:
        joints: (N, K, 19, 3) metres, root-relative; NaN in unused slots (fewer distinct components than K).
        probability: (N, K) posterior weight of each hypothesis (merged duplicates added); 0 in unused slots.
        component: (N, K) int, the mixture component of each hypothesis; -1 in unused slots.
        heading: (N, K) radians (:func:`heading`); NaN in unused slots.
        chosen: (N,) int, the slot of the single answer (0 = most probable unless a consensus or a
            temporal choice picked another).
    """

    joints: np.ndarray
    probability: np.ndarray = field(metadata={"fill": 0.0})  # fills: frames without a view (silpose.model.result)
    component: np.ndarray
    heading: np.ndarray
    chosen: np.ndarray = field(metadata={"fill": 0})

    @property
    def k(self) -> int:
        return int(self.probability.shape[1])

    @property
    def best_joints(self) -> np.ndarray:
        """(N, 19, 3) the chosen hypothesis of every frame."""
        return self.joints[np.arange(len(self.chosen)), self.chosen]

    def best_of(self, true: np.ndarray, k: int | None = None) -> np.ndarray:
        """(N,) slot of the hypothesis among the first ``k`` closest to ``true`` (N, 19, 3) (an oracle,
        for evaluation only): mean joint distance, root-relative."""
        k = self.k if k is None else min(int(k), self.k)
        t = np.asarray(true, dtype=np.float64)
        t = t - t[:, :1]
        h = self.joints[:, :k] - self.joints[:, :k, :1]
        d = np.linalg.norm(h - t[:, None], axis=-1).mean(axis=-1)
        return np.argmin(np.where(np.isfinite(d), d, np.inf), axis=1)

    def take(self, rows: np.ndarray) -> "Hypotheses":
        """The hypotheses of frames ``rows``."""
        return Hypotheses(self.joints[rows], self.probability[rows], self.component[rows], self.heading[rows],
                          self.chosen[rows])

    @classmethod
    def concat(cls, parts: "list[Hypotheses]") -> "Hypotheses":
        """The frames of ``parts`` (each with the same K) one after the other."""
        return cls(*(np.concatenate([getattr(p, name) for p in parts])
                     for name in ("joints", "probability", "component", "heading", "chosen")))


def top_hypotheses(component_joints: np.ndarray, responsibilities: np.ndarray, k: int = 3,
                   merge_cm: float = 3.0) -> Hypotheses:
    """The ``k`` most probable distinct component hypotheses of each frame (module doc).

    Args:
        component_joints: (N, M, 19, 3) metres, each component's conditional mean of the joints.
        responsibilities: (N, M) p(i | observed views).
        k: hypotheses kept (>= 1).
        merge_cm: components whose joints are within this mean joint distance (cm, root-relative) of a
            more probable kept hypothesis are merged into it.
    Returns:
        :class:`Hypotheses` with ``chosen`` = 0.
    """
    cj = np.asarray(component_joints, dtype=np.float64)
    r = np.asarray(responsibilities, dtype=np.float64)
    if cj.ndim != 4 or cj.shape[2:] != (N_JOINTS, 3) or r.shape != cj.shape[:2]:
        raise ValueError(f"component_joints (N, M, {N_JOINTS}, 3) and responsibilities (N, M) disagree: "
                         f"{cj.shape}, {r.shape}")
    k = int(k)
    if k < 1:
        raise ValueError(f"k must be >= 1, got {k}")
    n, m = r.shape
    order = np.argsort(-r, axis=1, kind="stable")
    rel = cj - cj[:, :, :1]  # root-relative
    joints = np.full((n, k, N_JOINTS, 3), np.nan)
    prob = np.zeros((n, k))
    comp = np.full((n, k), -1, dtype=np.intp)
    count = np.zeros(n, dtype=np.intp)
    rows = np.arange(n)
    limit = merge_cm / 100.0
    kept_rel = np.full((n, k, N_JOINTS, 3), np.nan)  # the kept hypotheses, root-relative (NaN: empty slot)
    slots = np.arange(k)[None, :]
    for step in range(m):
        cand = order[:, step]
        cand_rel = rel[rows, cand]  # (N, 19, 3)
        dist = np.linalg.norm(kept_rel - cand_rel[:, None], axis=-1).mean(axis=-1)  # (N, k), NaN in empty slots
        dist = np.where(slots < count[:, None], dist, np.inf)
        near = np.argmin(np.where(np.isfinite(dist), dist, np.inf), axis=1)  # no NaN left: argmin = nanargmin
        merge = dist[rows, near] < limit
        p = r[rows, cand]
        prob[rows[merge], near[merge]] += p[merge]
        new = ~merge & (count < k)
        slot = count[new]
        kept_rel[rows[new], slot] = cand_rel[new]
        joints[rows[new], slot] = cj[rows[new], cand[new]]
        prob[rows[new], slot] = p[new]
        comp[rows[new], slot] = cand[new]
        count[new] += 1
    # merged weights can reorder the kept hypotheses: sort again by probability (unused slots last)
    resort = np.argsort(-np.where(comp >= 0, prob, -1.0), axis=1, kind="stable")
    joints = np.take_along_axis(joints, resort[:, :, None, None], axis=1)
    prob = np.take_along_axis(prob, resort, axis=1)
    comp = np.take_along_axis(comp, resort, axis=1)
    return Hypotheses(joints, prob, comp, heading(joints), np.zeros(n, dtype=np.intp))


def consensus_choice(hyp: Hypotheses, vote_headings: np.ndarray) -> np.ndarray:
    """(N,) slot of the most probable hypothesis that agrees with the majority of ``vote_headings``.

    Args:
        hyp: the hypotheses of N frames.
        vote_headings: (N, V) radians, one heading per posterior given a subset of the views (silpose infer: each pair) (NaN = no vote).
    A hypothesis agrees with a vote when their headings differ by at most 90 deg. Per frame, the
    hypotheses with the most agreeing votes are candidates and the most probable of them is chosen;
    frames without votes keep slot 0.
    """
    v = np.asarray(vote_headings, dtype=np.float64)
    if v.ndim != 2 or v.shape[0] != hyp.probability.shape[0]:
        raise ValueError(f"vote_headings must have shape (N, V) with N = {hyp.probability.shape[0]}, got {v.shape}")
    valid = hyp.component >= 0  # (N, K)
    diff = np.abs(wrap_angle(hyp.heading[:, :, None] - v[:, None, :]))  # (N, K, V)
    agree = np.where(np.isfinite(diff), diff <= FLIP_ANGLE, False).sum(axis=2)  # (N, K)
    agree = np.where(valid, agree, -1)
    best = agree.max(axis=1, keepdims=True)
    cand = (agree == best) & valid
    # hypotheses are sorted by probability: the first candidate is the most probable one
    chosen = np.argmax(cand, axis=1)
    no_votes = ~np.isfinite(v).any(axis=1)
    chosen[no_votes] = 0
    return chosen.astype(np.intp)


def temporal_choice(hyp: Hypotheses, *, valid: np.ndarray | None = None, frame_gap: np.ndarray | None = None,
                    turn_sigma_deg: float = TEMPORAL_TURN_SIGMA_DEG, temperature: float = TEMPORAL_TEMPERATURE,
                    pose_sigma_m: float | None = TEMPORAL_POSE_SIGMA_M) -> np.ndarray:
    """(T,) slot per frame of the Viterbi path over the hypotheses of one person's T frames (module doc).

    Args:
        hyp: hypotheses of T consecutive frames of one track, in time order.
        valid: (T,) bool, frames to use (False: no observation; such a frame keeps slot 0 and the path
            bridges it); None = every frame with at least one hypothesis.
        frame_gap: (T,) frames elapsed since the previous frame (first entry ignored); None = 1 each.
            The expected turn grows with the gap: sigma = turn_sigma_deg * gap.
        turn_sigma_deg: expected heading change between consecutive frames (degrees, standard deviation).
        temperature: the frames' log-probabilities are divided by it (> 0; 1 = untempered).
        pose_sigma_m: expected mean joint motion between consecutive frames (metres, standard deviation; grows
            with the gap like the turn's); None = no joint term.
    Returns:
        (T,) int slots; ``hyp.chosen`` is not modified.
    """
    t_len = hyp.probability.shape[0]
    ok = _frames_used(hyp, valid)
    gap = np.ones(t_len) if frame_gap is None else np.asarray(frame_gap, dtype=np.float64)
    if gap.shape != (t_len,):
        raise ValueError(f"valid and frame_gap must have shape ({t_len},)")
    chosen, _ = _viterbi(hyp, ok, gap, None, turn_sigma_deg, temperature, pose_sigma_m)
    return chosen


@dataclass(frozen=True)
class PathEnd:
    """Where the Viterbi path of a track stood after its latest frame (module doc, "A stream"): what
    :func:`continue_choice` goes on from.

    Attributes:
        cost: (K,) accumulated cost of the best path ending in each hypothesis of that frame, the least 0 (inf:
            an unused slot).
        heading: (K,) radians, the frame's hypotheses' headings (NaN in unused slots).
        joints: (K, 19, 3) metres, root-relative, the frame's hypotheses (NaN in unused slots).
        step: the frame's time step.
    """

    cost: np.ndarray
    heading: np.ndarray
    joints: np.ndarray
    step: int


def continue_choice(hyp: Hypotheses, steps: np.ndarray, start: PathEnd | None = None, *,
                    turn_sigma_deg: float = TEMPORAL_TURN_SIGMA_DEG, temperature: float = TEMPORAL_TEMPERATURE,
                    pose_sigma_m: float | None = TEMPORAL_POSE_SIGMA_M) -> tuple[np.ndarray, PathEnd | None]:
    """The next frames of one track along the path of :func:`temporal_choice` (module doc, "A stream").

    Args:
        hyp: hypotheses of the track's next T frames, in time order.
        steps: (T,) int, their time steps (increasing; the gap between two is the ``frame_gap``).
        start: the path's end after the track's earlier frames (None: these are its first).
        turn_sigma_deg, temperature, pose_sigma_m: as for :func:`temporal_choice`.
    Returns:
        (T,) int slots -- the path over all the track's frames so far that is best at the last of these, on these
        frames (a frame without a usable hypothesis keeps slot 0 and is bridged) -- and the path's new end (``start``
        when no frame had a hypothesis). Earlier frames' slots are never revised: with ``start`` None this is
        :func:`temporal_choice` of these frames.
    """
    st = np.asarray(steps)
    t_len = hyp.probability.shape[0]
    if st.shape != (t_len,) or (t_len and not np.issubdtype(st.dtype, np.integer)):
        raise ValueError(f"steps must be ({t_len},) integers, got {st.shape} {st.dtype}")
    prev = st[:1] if start is None else np.array([start.step])
    gap = np.diff(st, prepend=prev).astype(np.float64)
    if np.any(gap[(start is None):] < 1):
        raise ValueError("steps must increase, and follow the start's step")
    if start is not None and start.cost.shape != (hyp.k,):
        raise ValueError(f"start holds {start.cost.shape[0]} hypotheses, the frames {hyp.k}")
    ok = _frames_used(hyp, None)
    chosen, cost = _viterbi(hyp, ok, gap, start, turn_sigma_deg, temperature, pose_sigma_m)
    if cost is None:
        return chosen, start
    last = int(np.flatnonzero(ok)[-1])
    return chosen, PathEnd(cost=cost, heading=hyp.heading[last].copy(), joints=hyp.joints[last].copy(),
                           step=int(st[last]))


def _frames_used(hyp: Hypotheses, valid: np.ndarray | None) -> np.ndarray:
    """(T,) bool: frames with at least one hypothesis (and ``valid``, when given)."""
    has = (hyp.component >= 0).any(axis=1)
    if valid is None:
        return has
    v = np.asarray(valid, dtype=bool)
    if v.shape != has.shape:
        raise ValueError(f"valid and frame_gap must have shape ({has.shape[0]},)")
    return v & has


def _viterbi(hyp: Hypotheses, ok: np.ndarray, gap: np.ndarray, start: PathEnd | None, turn_sigma_deg: float,
             temperature: float, pose_sigma_m: float | None) -> tuple[np.ndarray, np.ndarray | None]:
    """The Viterbi path of the module doc over the frames ``ok`` (T,) bool, ``gap`` (T,) frames since the previous
    frame (the first: since ``start``'s frame; ignored without a start). Returns the (T,) slots and the (K,) costs
    of the paths ending at the last frame used, the least 0 (None: no frame used)."""
    t_len, k = hyp.probability.shape
    if not temperature > 0:
        raise ValueError(f"temperature must be > 0, got {temperature}")
    if pose_sigma_m is not None and not pose_sigma_m > 0:
        raise ValueError(f"pose_sigma_m must be > 0 or None, got {pose_sigma_m}")
    if turn_sigma_deg <= 0:
        raise ValueError(f"turn_sigma_deg must be > 0, got {turn_sigma_deg}")
    sigma = np.radians(float(turn_sigma_deg))
    usable = hyp.component >= 0
    unary = np.where(usable, -np.log(np.maximum(hyp.probability, PROB_FLOOR)) / float(temperature), np.inf)  # (T, K)
    chosen = np.zeros(t_len, dtype=np.intp)
    frames = np.flatnonzero(ok)
    if frames.size == 0:
        return chosen, None

    def pair(prev_heading, prev_joints, t, g):  # (K_prev, K_now) cost of moving from the previous hypotheses to t's
        d = wrap_angle(hyp.heading[t][None, :] - prev_heading[:, None])
        c = 0.5 * (np.nan_to_num(d, nan=np.pi) / (sigma * g)) ** 2
        if pose_sigma_m is not None:  # mean joint distance, metres; unused slots are inf anyway
            dj = np.linalg.norm(prev_joints[:, None] - hyp.joints[t][None, :], axis=-1).mean(axis=-1)
            c = c + 0.5 * (np.nan_to_num(dj, nan=0.0) / (pose_sigma_m * g)) ** 2
        return c

    # accumulated gaps between consecutive valid frames (a bridged invalid frame adds its gap)
    cum = np.cumsum(gap)
    first = frames[0]
    if start is None:
        cost = unary[first].copy()
    else:  # the first frame used is cum[first] frames after the start's (bridged frames included)
        cost = np.min(start.cost[:, None] + pair(start.heading, start.joints, first, max(cum[first], 1e-9)),
                      axis=0) + unary[first]
    back = np.zeros((frames.size, k), dtype=np.intp)
    for s in range(1, frames.size):
        t, prev = frames[s], frames[s - 1]
        total = cost[:, None] + pair(hyp.heading[prev], hyp.joints[prev], t, max(cum[t] - cum[prev], 1e-9))
        back[s] = np.argmin(total, axis=0)
        cost = total[back[s], np.arange(k)] + unary[t]
    slot = int(np.argmin(cost))
    for s in range(frames.size - 1, -1, -1):
        chosen[frames[s]] = slot
        slot = int(back[s, slot])
    return chosen, cost - cost[np.isfinite(cost)].min()


def _chosen(hyp: Hypotheses, chosen: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(slots (N,), the chosen hypotheses' joints (N, 19, 3), whether each is usable (N,) bool)."""
    slots = hyp.chosen if chosen is None else np.asarray(chosen, dtype=np.intp)
    rows = np.arange(len(slots))
    pick = hyp.joints[rows, slots]
    usable = (hyp.component[rows, slots] >= 0) & np.isfinite(pick).all(axis=(1, 2))
    return slots, pick, usable


def single_answer(posterior_mean: np.ndarray, hyp: Hypotheses | None, chosen: np.ndarray | None = None) -> np.ndarray:
    """(N, 19, 3) the single answer per frame (module doc): ``posterior_mean`` (N, 19, 3), replaced by the
    chosen hypothesis (``chosen`` (N,) slots, default ``hyp.chosen``) in the frames where that hypothesis's
    heading is more than 90 deg from the posterior mean's. Without hypotheses, the posterior mean."""
    mean = np.asarray(posterior_mean, dtype=np.float64)
    if hyp is None:
        return mean
    slots, pick, usable = _chosen(hyp, chosen)
    turned = np.abs(wrap_angle(hyp.heading[np.arange(len(slots)), slots] - heading(mean))) > FLIP_ANGLE
    return np.where((turned & usable)[:, None, None], pick, mean)


def sequence_answer(posterior_mean: np.ndarray, hyp: Hypotheses | None, chosen: np.ndarray | None = None) -> np.ndarray:
    """(N, 19, 3) the answer along a sequence (module doc): the chosen hypothesis (``chosen`` (N,) slots, default
    ``hyp.chosen``) of every frame that has one, the posterior mean (N, 19, 3) elsewhere. Without hypotheses, the
    posterior mean."""
    mean = np.asarray(posterior_mean, dtype=np.float64)
    if hyp is None:
        return mean
    _, pick, usable = _chosen(hyp, chosen)
    return np.where(usable[:, None, None], pick, mean)
