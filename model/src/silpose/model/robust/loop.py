"""The robust inference loop (``silpose.model.robust``): reweighted passes, then the repairs of the input.

:func:`robust_passes` runs the Gaussian pass, the adaptive noise and ``settings.iterations`` reweighted passes
of one batch (:mod:`silpose.model.robust.weights`), each pass on the frames whose reconstruction still moved
more than :data:`SETTLED_PX` in the pass before; :func:`robust_infer` then trims the observed contours'
excursions (:mod:`silpose.model.robust.excursions`) and undoes their slides along the outline
(:mod:`silpose.model.robust.reindex`) against the robust reconstruction, inferring the changed frames again.

Cost: the two Gaussian passes share one float32 screen of every component (:mod:`silpose.model.screen`) and
condition exactly only the components it keeps; each reweighting pass conditions a frame on its own components of
the pass before (:mod:`silpose.model.gated`), so it costs O(d q) per frame and component that matters rather than
O(d q M).

The repairs look at every observed view once; a later pass of the same repair looks only at the frames inferred
again since (a view's answer depends on its own input and reconstruction, so the others would come out unchanged).
Their array arithmetic, and the passes', avoids numpy's broadcasts and reductions over a last axis of 2 (inner
loops of two elements) and (views, n, 2w + 1) gathers on large batches, with the same results bit for bit
(``tests/model/test_robust_arithmetic.py``). Measured at the benchmark's size (``benchmarks/inference.py``: 20,000
frames, M 5, q 30, 4 views; 2 shared cores): robust batched inference 70.0 s before these changes and 45.9 s after
in one run at load 3 (48x and 30x the plain batched time), 34 s at load 1.5; 58-133x the BLAS floor (the floor
itself moved 2x within one run). Its outputs on the benchmark's frames and on 3,000 corrupted frames with missing
views are bit-identical to before. Where the rest went (CPU profile, 5,000 frames): the passes' conditioning,
gathers and scatters ~45 %, re-indexing ~20 % (the per-view 7 x 7 solves and medians of its fits), excursion
trimming ~20 %.

Since (issue "A prior that holds every motion"): a batch runs in blocks of :data:`BLOCK_FRAMES` frames whose
(frames, d) arrays stay in cache (robust time per frame had grown ~1.5x from 1,000 to 20,000 frames); the slide
fits solve their 7 x 7 systems by one batched Cholesky factorisation (``reindex.solve_spd``: ``np.linalg.solve``
took 14 us a system under OpenBLAS's threading, 0.3 us here); the slide matching reads shifted slices of a padded
copy instead of ``np.roll`` copies and compares squared distances; the far-point search of the excursions widens in
stages (4, 12, n / 4 edges), settling a point by a vertex first. Outputs equal the previous code's to rounding (300
test rows of the default preset, clean, standard noise and "mask strong", every view and missing views: joints
within 4e-11 mm, contours within 4e-12 px, the same views trimmed and re-indexed). Same-run figures
(``benchmarks.run --only inference``, 2 shared cores): full size (20,000 frames), load 8-10, robust 97.3 s -> 44.6 s
(75x -> 47x the BLAS floor); ``--quick`` (2,000 frames), two alternating pairs at load 7, 6.9 -> 3.6 s (66x -> 37x)
and 3.1 -> 2.3 s (50x -> 42x). Where the rest goes (2,000 frames): the passes' conditioning ~30 %, excursion
trimming ~25 % (the far-point search of outlines the random benchmark model draws wiggly), re-indexing ~20 %, the
weights' medians ~8 %.

Since (issue "A prior that holds every motion", second round): the point-wise steps of a reweighting pass (matching,
weights, pseudo-observation, the largest move) run :data:`CHUNK_FRAMES` frames at a time so that their arrays stay
in a core's cache (1,024 frames x 4 views: 66 -> 41 CPU ms for the chain), as do the (de)normalisations
(``silpose.model.features``, which also add the centroid as one complex number per point); the reweighting passes
run on the frames sorted by group (:func:`pass_order`), so that ``Posterior.infer``'s noise groups and the gated
conditioning's component groups are slices, not gathered copies; the gated conditioning gets ``a P_i`` and
``a . mu_a,i`` from one product and, when every frame has one component, writes ``mu_i + x_hat_i W_i^T`` directly;
medians sort instead of partitioning (numpy's partition took 28 ms for 4,096 rows of 200, its sort 9.6 ms; on
a CPU without AVX-512 it is the other way round, and ``robust.median`` partitions there). Outputs
equal the previous code's to rounding (300 default-preset test rows, clean, standard noise and "mask strong", every
view and missing views: joints within 1.7e-9 mm, the same views trimmed and re-indexed; the benchmark's frames within
1.5e-13 mm). Where the rest goes (2,000 frames, CPU profile at load 11-13): the passes ~45 % (conditioning ~25 %, the
two Gaussian passes ~12 %), excursion trimming ~21 % (the far-point search ~13 %), re-indexing ~23 % (slide fits
~12 %, matching ~9 %; on the benchmark's frames it changes no view -- the slide fits' chi^2 has its 99th percentile
at 49 against a gate of 120 -- but we found no cheap bound that proves a view unchanged before its fit).


Since (issue "A prior that holds every motion", third round): the blocks of a batch of at least 2
``MIN_THREAD_FRAMES`` frames run on up to ``THREADS`` threads (``silpose.model.threads.map_blocks``: the process's
pool, BLAS on one thread meanwhile), in equal shares (``threads.block_bounds``): the BLAS floor the benchmark compares
with uses every core, and most of robust inference is numpy's array loops, which release the GIL. Answers equal the
blocks' one after the other (1,200 default test rows, standard noise: bit-identical joints; benchmark frames within
2e-16 m). The excursions' far-point search leaves out the runs that cannot be excursions
(``excursions.excursion_candidates``) and the repairs keep each view's normalisation scale until one changes the view
(both bit-identical: 500 default test rows, standard noise and "mask mild"). What the threads give depends on the
other jobs on the 2 shared cores: 2,000 benchmark frames, THREADS 1 vs 2 alternating in one process, median wall
4.93 -> 3.89 s at load 10-11 (5 pairs), 3.94 -> 3.90 s at load 6 (6 pairs, the process got ~0.5 core either way);
``benchmarks.run --only inference --quick``, three alternating pairs with main at load 5-6: 511 / 433 / 668 frames/s
(56x / 39x / 36x the floor) on main, 514 / 487 / 653 frames/s (40x / 28x / 30x) here -- the same throughput, the
ratios moved with the floor (0.07-0.15 s in these runs). Not shown on an idle machine.

Since (issue "A prior that holds every motion", fourth round): three loops are compiled
(:mod:`silpose.model.robust.kernels`, numba): the re-indexing's shift search, the excursions' far-point search
(from a point's own index outwards, stopping at the first edge within the limit, instead of the stages) and a
reweighting pass's weights and pseudo-observation with index correspondences (the median by selection, view by view,
without the GIL, so both threads work). Answers are bit-identical (the benchmark's 2,000 frames; 500 default-preset
test rows clean, standard noise and strong patches, with missing views: joints, contours, views trimmed and
re-indexed). 2,000 benchmark frames, best of 3, the previous code and this alternating in their own processes at load
1.3: 0.90 / 0.88 / 0.95 s -> 0.73 / 0.73 / 0.74 s with the two searches, 0.87 / 0.87 -> 0.66 / 0.64 s with the
pass's kernel too. Where the rest goes (2,000 frames, one thread, CPU profile): the passes' conditioning ~15 %, the
slide fits ~16 % (their medians half of it), the pass kernel ~12 % (its medians ~70 % of it), excursion trimming's
per-view work ~15 %.

Fresh memory: on the project's machine the first write to memory the process has not used lately costs ~100 MB/s
(docs/conventions.md, "Benchmarks"). A batch of 20,000 frames held every block's result (~600 MB in all) until one
merge copied them into a new ~600 MB result: that merge took 2.0-7.0 s of a 15-17 s call, and the time per frame
doubled from 5,000 to 10,000 frames. Each block is now written into the batch's result as soon as it is done and
its own arrays freed, so the next block reuses their memory: 20,000 benchmark frames (idle, two alternating pairs)
17.2 / 15.2 s -> 12.5 / 12.8 s; 2,000 and 5,000 frames within the noise. Answers are bit-identical (10,000 frames).

What only a frame's last pass gives is computed once, at the end of :func:`robust_passes`, from the contours that
pass was given: the stature of the "stature" joint frame (``Posterior.scale_to_stature``; every pass measured its
own, ~0.8 ms a call, bit-identical answers), and, for hypotheses and the calibrated mixing (``want``), every
component's weight and mean: the passes are gated then too, where each conditioned every component. Measured on the
idle machine, alternating with the previous code: a model of the lab rig (M 5), robust batches of 16 frames 8.2-9.9
-> 6.1-6.5 ms a frame (the stature); robust with top-3 hypotheses, 500 frames of the benchmark's M 60 / M 200 q 40
mixtures 1.59 -> 0.93 s and 3.13 -> 1.99 s (the gate; joints within 2e-16 m, the lab model's within 2e-11 m).
"""

from __future__ import annotations

import dataclasses
import threading

import numpy as np

from ..features import normalise_contours
from ..checks import Inputs
from ..conditioning import GATE_NATS
from ..posterior import Posterior
from ..result import InferenceResult
from ..threads import block_bounds, map_blocks
from .excursions import trim_excursions
from .observed_views import view_scales
from .reindex import reindex_contours
from .weights import RobustSettings, frame_noise_variance, point_weights, snap_correspondences

__all__ = ["SETTLED_PX", "BLOCK_FRAMES", "CHUNK_FRAMES", "largest_move", "pass_order", "pseudo_observation",
           "reweighted_observation", "reweighted_passes", "robust_passes", "robust_infer", "robust_block"]

#: px: a frame whose reconstruction moved less than this in a reweighting pass has settled; later passes leave
#: it alone (each would move it less again: the passes converge to the weighted conditioning's fixed point). The
#: moves shrink by a factor rho ~0.15-0.2 a pass (benchmark frames: median 1.17, 0.18, 0.03, 0.007 px), so a frame
#: that stops after a move m lies about m rho / (1 - rho) ~0.25 m from the fixed point: 0.025 px at 0.1 px, a tenth
#: of the evaluation's 1 px jitter and below what a rasterised outline resolves. Was 0.01 px; 0.1 px left the default
#: preset's robust pose errors within 0.013 cm (500 test rows, standard noise and "mask mild", 4 views and view 0
#: alone: 3.6125 -> 3.6117, 11.4582 -> 11.4638, 5.8309 -> 5.8308, 15.5296 -> 15.5424 cm) and cut 2,000 benchmark
#: frames from 0.904-0.928 s to 0.785 s in the same process (idle machine; docs/conventions.md "Benchmarks")
SETTLED_PX = 0.1
#: a reweighting pass evaluates for each frame only the components whose posterior weight exceeded this (GATE_NATS
#: below the best) for it in the pass before; the others count as 0 (their means and weights < e^-30)
GATE_WEIGHT = float(np.exp(-GATE_NATS))
#: frames per block of :func:`robust_infer`: a block's (frames, d) float64 arrays (13 MB at d 1657) fit the shared
#: 32 MB cache of the benchmark machine, and its Python overhead (~30 ms a block) stays small
BLOCK_FRAMES = 1024
#: frames per chunk of a pass's point-wise steps (:func:`reweighted_observation`, :func:`largest_move`): a chunk's
#: (frames, K, n, 2) arrays (0.8 MB for 4 views of 200 points) stay in a core's 2 MB cache between the steps
CHUNK_FRAMES = 128


def robust_passes(posterior: Posterior, inputs: Inputs, s2: float, settings: RobustSettings,
                  want: bool) -> tuple[InferenceResult, np.ndarray | None]:
    """The Gaussian pass, the adaptive noise, then ``settings.iterations`` reweighted passes; returns the last
    pass's result (with ``log_marginal`` that of the input, ``log_marginal_robust``, ``robust_weights``,
    ``noise_variance``) and, with ``want``, its component means (``Posterior.infer``). The passes condition only the
    components that matter for a frame (:mod:`silpose.model.gated`); with ``want`` the contours each frame's last
    pass was given are conditioned once more at the end on every component, whose weights and means the
    hypotheses and the calibrated mixing read (a tempered mixing lifts weights the gate would have left at 0)."""
    c_mod, present = inputs.contours, inputs.present
    # the two Gaussian passes share one float32 screen of every component (silpose.model.screen)
    screen: dict = {}
    # the joints of a pass are kept only where it is a frame's last: each frame's stature is measured once, at the
    # end, from the contours its last pass was given (the same values as every pass measuring its own)
    res, _ = posterior.infer(inputs, s2, components=False, screen=screen, stature=False)
    observed_lm = res.log_marginal
    if settings.noise_scale is not None:  # adaptive observation noise per frame (silpose.model.robust)
        with np.errstate(invalid="ignore", over="ignore"):
            norm_obs = normalise_contours(c_mod)[0]
        s2_rows = frame_noise_variance(norm_obs, res.contours_norm, present, s2, settings.noise_scale)
        res, _ = posterior.infer(inputs, s2_rows, components=False, screen=screen, stature=False)
    else:
        s2_rows = s2
    s2_arr = np.broadcast_to(np.asarray(s2_rows, dtype=np.float64), (len(present),))
    order = pass_order(res.responsibilities, present, s2_arr)
    if order is None:
        res, u, last = reweighted_passes(posterior, inputs, res, s2_rows, settings)
    else:  # the passes on the frames sorted by group, then back in the caller's order
        res, u, last = reweighted_passes(posterior, inputs.take(order), res.take(order),
                                         s2_rows if np.ndim(s2_rows) == 0 else s2_arr[order], settings)
        back = np.empty_like(order)
        back[order] = np.arange(order.size)
        res, u, last = res.take(back), u[back], last[back]
    comp = None
    if want:  # every component's weight and mean, as each frame's last pass gives them ungated (module doc)
        res, comp = posterior.infer(inputs.with_contours(last), s2_rows, components=True, stature=False)
    comp = posterior.scale_to_stature(res, comp, last, present)
    if settings.noise_scale is not None:
        res.noise_variance = s2_rows
    res.log_marginal_robust = res.log_marginal
    res.log_marginal = observed_lm
    res.robust_weights = u
    return res, comp


def pass_order(responsibilities: np.ndarray, present: np.ndarray, s2: np.ndarray) -> np.ndarray | None:
    """The order (N,) of the frames that makes each group of a reweighting pass consecutive -- frames conditioned
    together (one present-view pattern and noise level s2 (N,): ``Posterior.infer``) and within a group those of one
    best component (N, M) ``responsibilities`` (``silpose.model.gated``) -- so that their rows are read as slices, not
    gathered; None when they already are in that order. A frame's result does not depend on the others'."""
    n = len(present)
    if n < 2:
        return None
    code = np.asarray(present, dtype=np.int64) @ (np.int64(1) << np.arange(present.shape[1], dtype=np.int64))
    order = np.lexsort((np.argmax(responsibilities, axis=1), code, s2))
    return None if (order[1:] > order[:-1]).all() else order


def reweighted_passes(posterior: Posterior, inputs: Inputs, res: InferenceResult, s2_rows,
                      settings: RobustSettings) -> tuple[InferenceResult, np.ndarray, np.ndarray]:
    """``settings.iterations`` reweighted passes from the Gaussian pass ``res`` of ``inputs`` at noise ``s2_rows``
    (a float or (N,)); each pass on the frames whose reconstruction still moved :data:`SETTLED_PX` in the pass
    before. Returns the last pass's result, point weights (N, K, n) and the contours (N, K, n, 2) px each frame's
    last pass was given (``inputs.contours`` without a pass). The passes' joints are those of a 1.75 m person
    (``Posterior.infer``'s ``stature`` False)."""
    c_mod, present = inputs.contours, inputs.present
    s2_arr = np.broadcast_to(np.asarray(s2_rows, dtype=np.float64), (len(present),))
    u = np.zeros(present.shape + (c_mod.shape[2],))
    last = c_mod if int(settings.iterations) <= 0 else np.empty(c_mod.shape)  # every frame has a first pass
    active = np.arange(len(present))  # frames whose reconstruction still moves
    for it in range(int(settings.iterations)):
        every = active.size == len(present)  # all frames: the arrays themselves, no gathered copies
        rec = res.contours_px if every else res.contours_px[active]
        c_act = c_mod if every else c_mod[active]
        p_act = present if every else present[active]
        u_act, pseudo = reweighted_observation(c_act, rec, p_act, settings)
        u[active] = u_act
        last[active] = pseudo
        # the components that matter for each frame: within GATE_NATS of its best in the pass before, each
        # component's frames in one product (silpose.model.gated)
        only = (res.responsibilities if every else res.responsibilities[active]) > GATE_WEIGHT
        step_inputs = (inputs.with_contours(pseudo) if every else  # the active frames' factors, not their contours
                       Inputs(p_act, pseudo, inputs.centroid[active], inputs.scale[active]))
        part, _ = posterior.infer(step_inputs, s2_rows if np.ndim(s2_rows) == 0 else s2_arr[active], only=only,
                                  stature=False)
        moved = largest_move(part.contours_px, rec)  # px
        if every:
            res = part
        else:
            res.put(active, part)
        active = active[moved >= SETTLED_PX]  # settled frames keep this pass's answer (module doc)
        if active.size == 0:
            break
    return res, u, last


def reweighted_observation(observed: np.ndarray, rec: np.ndarray, present: np.ndarray,
                           settings: RobustSettings) -> tuple[np.ndarray, np.ndarray]:
    """The point weights (N, K, n) and pseudo-observation (N, K, n, 2) px of a reweighting pass: observed contours
    (N, K, n, 2) px matched to their reconstruction ``rec`` (``snap_correspondences``), Tukey's weights of the
    distances (``point_weights``; 0 in absent views), ``pseudo_observation`` (the observed contour in absent views).

    Every step is per frame; they run :data:`CHUNK_FRAMES` frames at a time, so that a chunk's arrays stay in cache
    from one step to the next (the same values as whole-array steps, ~1.5x faster on blocks of 1,024 frames). With
    index correspondences (``settings.window`` 0, the default) the compiled
    :func:`~silpose.model.robust.kernels.biweight_pseudo` does all three view by view, with the same values."""
    if int(settings.window) == 0:
        from .kernels import biweight_pseudo  # numba: imported on first use (module doc of .kernels)

        return biweight_pseudo(np.ascontiguousarray(observed, dtype=np.float64),
                               np.ascontiguousarray(rec, dtype=np.float64), np.ascontiguousarray(present, dtype=bool),
                               float(settings.threshold), float(settings.scale_floor_px))
    n = len(observed)
    u = np.empty(observed.shape[:3])
    pseudo = np.empty(observed.shape)
    for a in range(0, n, CHUNK_FRAMES):
        sl = slice(a, min(a + CHUNK_FRAMES, n))
        c, r, p = observed[sl], rec[sl], present[sl]
        matched, dist = snap_correspondences(c, r, int(settings.window))
        w = point_weights(dist, settings.threshold, settings.scale_floor_px)
        if p.all():
            u[sl] = w
            pseudo_observation(r, matched, w, out=pseudo[sl])
        else:
            u[sl] = np.where(p[..., None], w, 0.0)
            pseudo[sl] = np.where(p[..., None, None], pseudo_observation(r, matched, u[sl]), c)
    return u, pseudo


def pseudo_observation(rec: np.ndarray, matched: np.ndarray, weights: np.ndarray,
                       out: np.ndarray | None = None) -> np.ndarray:
    """``rec + weights[..., None] * (matched - rec)`` (..., n, 2) px: the pseudo-observation of a reweighting pass
    (``silpose.model.robust.weights``), the same arithmetic per coordinate (no broadcasting over an axis of 2);
    written into ``out`` when given."""
    out = np.subtract(matched, rec, out=out)
    out[..., 0] *= weights
    out[..., 1] *= weights
    out += rec
    return out


def largest_move(new: np.ndarray, old: np.ndarray) -> np.ndarray:
    """(N,) px: the largest coordinate change of each frame's (N, K, n, 2) reconstruction, NaN changes counted as 0
    (``np.abs(np.nan_to_num(new - old)).max(axis=(1, 2, 3))`` for the test ``>= SETTLED_PX``: an infinite change
    stays infinite)."""
    out = np.empty(len(new))
    for a in range(0, len(new), CHUNK_FRAMES):  # per frame: in chunks that stay in cache
        sl = slice(a, a + CHUNK_FRAMES)
        diff = np.subtract(new[sl], old[sl]).reshape(len(out[sl]), -1)
        np.abs(diff, out=diff)
        out[sl] = np.fmax.reduce(diff, axis=1, initial=0.0)
    return out


def robust_infer(posterior: Posterior, inputs: Inputs, s2: float, settings: RobustSettings,
                 want: bool) -> tuple[InferenceResult, np.ndarray | None]:
    """Robust inference of a batch (module doc): :func:`robust_passes`, then the excursions trimmed and the
    slides undone, each changed frame inferred again. Sets ``excursions_trimmed``, ``reindexed`` and
    ``robust_input_px``; ``log_marginal`` stays that of the input as observed.

    A batch of more than :data:`BLOCK_FRAMES` frames is inferred in consecutive blocks of at most that many (a frame's
    answer depends on its own input only), so that the passes' (frames, d) arrays stay in the processor's cache; the
    blocks of a large batch run on threads of their own (``silpose.model.threads``: ``block_bounds``, ``map_blocks``)."""
    n = len(inputs.present)
    bounds, threads = block_bounds(n, BLOCK_FRAMES)
    if len(bounds) == 1:
        return robust_block(posterior, inputs, s2, settings, want)
    out: list[InferenceResult] = []
    lock = threading.Lock()

    def block(b: tuple[int, int]) -> np.ndarray | None:
        # each block is written into the batch's result as soon as it is done, and its own arrays freed: the next
        # block's reuse their memory (module doc, "fresh memory"), where holding every block for a merge at the end
        # needed the whole result twice
        res, comp = robust_block(posterior, inputs.take(slice(*b)), s2, settings, want)
        with lock:
            if not out:
                out.append(res.nan_like(n))
        if _fields(res) != _fields(out[0]):
            raise RuntimeError(f"robust blocks gave different fields: {_fields(res)} vs {_fields(out[0])}")
        out[0].put(slice(*b), res)
        return comp

    comps = map_blocks(block, bounds, threads)
    return out[0], (np.concatenate(comps) if want else None)


def _fields(res: InferenceResult) -> tuple[str, ...]:
    """The names of the fields ``res`` holds (not None)."""
    return tuple(f.name for f in dataclasses.fields(res) if getattr(res, f.name) is not None)


def robust_block(posterior: Posterior, inputs: Inputs, s2: float, settings: RobustSettings,
                 want: bool) -> tuple[InferenceResult, np.ndarray | None]:
    """:func:`robust_infer` of one block of frames, at once."""
    res, comp = robust_passes(posterior, inputs, s2, settings, want)
    observed_lm = res.log_marginal.copy()  # put() below writes into res's arrays
    present = inputs.present
    trimmed = np.zeros(present.shape, dtype=bool)
    reindexed = np.zeros(present.shape, dtype=bool)
    work = inputs.contours
    # each observed view's normalisation scale, for every repair (they depend on the observed points only): computed
    # once, and again for the views a repair changes
    with np.errstate(invalid="ignore", over="ignore"):
        scales = view_scales(np.asarray(work, dtype=np.float64).reshape(-1, *work.shape[2:])).reshape(present.shape)
    # shadows, blobs, holes (silpose.model.robust.excursions), then slides along the outline (.reindex)
    steps = ([(trim_excursions, settings.excursions, trimmed)] * int(settings.excursion_passes)
             + [(reindex_contours, settings.reindex, reindexed)] * int(settings.reindex_passes))
    settled = set()  # a step that changed nothing would change nothing on its next pass either
    # the frames each step has not seen as they are now (None: all of them); a step's answer for a view depends on
    # that view's input and reconstruction only, so the frames it left alone need no second look
    unseen: dict = {step: None for step, _, _ in steps}
    for step, step_settings, done in steps:
        if step in settled:
            continue
        look = unseen[step]
        unseen[step] = np.zeros(0, dtype=np.intp)
        if look is None:
            new, changed = step(work, res.contours_px, present, step_settings, scales)
        else:
            new_l, changed_l = step(work[look], res.contours_px[look], present[look], step_settings, scales[look])
            new, changed = work.copy(), np.zeros(present.shape, dtype=bool)
            new[look], changed[look] = new_l, changed_l
        rows = np.flatnonzero(changed.any(axis=1))
        if rows.size == 0:
            settled.add(step)
            continue
        work = np.where(changed[..., None, None], new, work)
        with np.errstate(invalid="ignore", over="ignore"):
            scales[changed] = view_scales(work[changed])
        done |= changed
        again, again_comp = robust_passes(posterior, inputs.with_contours(work).take(rows), s2, settings, want)
        res.put(rows, again)
        if comp is not None:
            comp[rows] = again_comp
        for other in unseen:
            if unseen[other] is not None:
                unseen[other] = np.union1d(unseen[other], rows)
    res.log_marginal = observed_lm  # of the input as observed, excursions and all
    res.excursions_trimmed = trimmed
    res.reindexed = reindexed
    res.robust_input_px = np.asarray(work, dtype=np.float64)
    return res, comp
