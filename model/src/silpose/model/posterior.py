"""The posterior of a fitted shape+structure model given observed views: the conditioning orchestration.

Inference (paper section 4): the observed dimensions are the *present views'* contour coordinates; the
missing dimensions are the absent views' contours and the whole structure block. Missing dimensions are
marginalised by dropping their rows, never zero-filled; rows with different missing-view patterns (and, in
robust inference, different noise levels) are grouped and conditioned separately. Every modelled view gets a
reconstruction: missing views from the conditional mean, present views from their Bayesian reconstruction
``mu_a + W_a E[x | a]`` (the shape model of [8]). The numerics are the exact Gaussian conditioning of
:mod:`silpose.model.conditioning` (the tests check it against dense conditioning).

:class:`Posterior` holds what one fitted mixture needs to answer: its layout, its rig (the 'stature' joint
frame) and a cache of :class:`~silpose.model.conditioning.Conditioner` objects, one per present-view pattern
and noise level. ``ShapeStructureModel.infer`` calls :meth:`Posterior.infer` once, robust inference
(``silpose.model.robust``) once per pass. A large batch of one view pattern and one noise level is inferred in
blocks on threads (:meth:`Posterior.infer_in_blocks`), each block normalised, conditioned and denormalised in turn.
"""

from __future__ import annotations

import threading

import numpy as np

from .checks import Inputs
from .conditioning import THREAD_BLOCK_ROWS, Conditioner
from .gated import condition_gated, rows_where
from .screen import Screen, ScreenMatrices
from .features import FeatureLayout, denormalise_contours, normalise_contours
from .hypotheses import heading
from .plausibility import view_subsets
from .result import InferenceResult
from .stature import REFERENCE_STATURE, estimate_stature
from .threads import MIN_THREAD_FRAMES, block_bounds, map_blocks, prepare

__all__ = ["Posterior"]

#: bytes of the cached Conditioners of one Posterior (their shared output matrix aside): four of a 200-component,
#: q 40 mixture on 4 views (robust inference alternates between the model's s^2 and a frame's noise level)
CACHE_BYTES = 512 << 20
#: bytes of the cached screen matrices (silpose.model.screen): float32, 52 MB per view pattern at M 200, q 40
SCREEN_BYTES = 256 << 20


class Posterior:
    """Conditioning of one fitted mixture on observed views (module doc).

    Args:
        mixture: the fitted :class:`~silpose.model.mppca.MPPCA` (or its parameters).
        layout: the shape-vector layout it was fitted on.
        rig: the ``silpose.shared.camera.Rig`` (needed for the 'stature' joint frame), or None.
    """

    def __init__(self, mixture, layout: FeatureLayout, rig=None) -> None:
        self.mixture = mixture
        self.layout = layout
        self.rig = rig
        self.n_components = int(mixture.weights_.shape[0])
        self._cache: dict = {}
        self._screens: dict = {}  # present-view pattern -> ScreenMatrices
        self._output = None  # the output matrix every reconstructing conditioner shares (Conditioner.output_matrix)
        self._lock = threading.Lock()  # the caches are shared by the threads of a batch (silpose.model.threads)
        prepare()  # the BLAS controller those threads use, now rather than in a first large batch

    def __getstate__(self) -> dict:
        """For copies: the state without the lock (a copy gets a new one)."""
        state = self.__dict__.copy()
        del state["_lock"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()

    def infer(self, inputs: Inputs, s2, components: bool = False, only=None,
              screen: dict | None = None, stature: bool = True) -> tuple[InferenceResult, np.ndarray | None]:
        """Normalise, condition (one Conditioner per present-view pattern and noise) and assemble the result.

        ``s2`` a float or (N,) one noise variance per frame (robust inference). With ``components`` also
        returns each component's conditional mean of the joints (N, M, 19, 3) metres, else None. ``only``:
        indices of the only mixture components to evaluate, the others being known to be negligible
        (``Conditioner.__call__``'s ``components``), or an (N, M) bool mask of each frame's own
        (:func:`~silpose.model.gated.condition_gated`; not with ``components``); None = all. ``screen``: a dict
        the caller keeps for these ``inputs`` (empty at first): the components are chosen by a float32 first
        pass (:mod:`silpose.model.screen`), kept there and reused by later calls on the same inputs at other
        noise levels, and only those conditioned exactly (not with ``components`` or ``only``). ``stature``
        False: in the "stature" joint frame, the joints stay those of a 1.75 m person, for a caller that scales them
        once at the end (:meth:`scale_to_stature`; robust inference, whose passes but the last are discarded).
        """
        layout = self.layout
        c_mod, present = inputs.contours, inputs.present
        n, kmod = present.shape
        all_present = bool(present.all())
        if (only is None and screen is None and np.ndim(s2) == 0 and n >= 2 * MIN_THREAD_FRAMES
                and (all_present or bool((present == present[:1]).all()))):
            return self.infer_in_blocks(inputs, float(s2), components, stature)
        # absent views may hold NaN (never read); absurd values (~1e300 px) overflow, caught below
        with np.errstate(invalid="ignore", over="ignore"):
            norm, cen, sc = normalise_contours(c_mod)
        overflow = present & ~(np.isfinite(sc) & np.isfinite(cen).all(axis=-1))  # (N, K): O(N K) check
        if overflow.any():
            r, p = np.argwhere(overflow)[0]
            raise ValueError(
                f"contours_px values too large to normalise (overflow) in an observed view: frame {r}, view "
                f"{layout.views[p]}; pixel coordinates must be finite and of image size"
            )
        if not all_present:  # keep the known factors for absent views
            cen = np.where(present[..., None], cen, inputs.centroid)
            sc = np.where(present, sc, inputs.scale)

        d = layout.dim
        M = self.n_components
        flat = norm.reshape(n, -1)
        per_row = np.ndim(s2) > 0
        if per_row and (all_present or n == 1):
            s2_rows = np.asarray(s2, dtype=np.float64).reshape(-1)
            if (s2_rows == s2_rows[0]).all():  # one group: grouping by noise would find just this one
                s2, per_row = float(s2_rows[0]), False
        if per_row:  # group by (pattern, noise): one integer per row, the pattern's bits then the noise level index
            levels, level_of = np.unique(np.asarray(s2, dtype=np.float64), return_inverse=True)
            code = present.astype(np.int64) @ (np.int64(1) << np.arange(kmod, dtype=np.int64))
            keys, inverse = np.unique(code + (level_of.reshape(-1).astype(np.int64) << kmod), return_inverse=True)
            patterns = ((keys[:, None] >> np.arange(kmod)) & 1).astype(bool)
            group_s2 = levels[keys >> kmod]
            inverse = inverse.reshape(-1)
        elif all_present or n == 1:
            patterns, inverse = present[:1], np.zeros(n, dtype=np.intp)
        else:
            patterns, inverse = np.unique(present, axis=0, return_inverse=True)
            inverse = inverse.reshape(-1)
        if not per_row:
            group_s2 = np.full(len(patterns), float(s2))
        cmeans = None
        per_frame = only is not None and np.ndim(only) == 2
        if per_frame and components:
            raise ValueError("a per-frame component mask gives no component means (components=False)")

        screened = screen is not None and not components and only is None

        def condition(pattern, s2_group, x_obs, rows=None):
            cond = self.conditioner(pattern, s2_group)
            if per_frame:
                return condition_gated(cond, x_obs, only if rows is None else only[rows])
            if screened:
                return condition_gated(cond, x_obs, self.screened(screen, pattern, present, flat, rows, cond))
            return cond(x_obs, return_components=components, components=only)

        if len(patterns) == 1:  # the common case: no fancy-index copies
            x_obs = flat if patterns[0].all() else flat[:, layout.observed_mask(patterns[0])[: layout.contour_dim]]
            post = condition(patterns[0], float(group_s2[0]), x_obs)
            mean, best, var, resp, logm = (post.reconstruction, post.best_mean, post.variance,
                                           post.responsibilities, post.log_marginal)
            cmeans = post.component_means
        else:
            mean = np.empty((n, d))
            best = np.empty((n, layout.structure_dim))
            var = np.empty((n, layout.structure_dim))
            resp = np.empty((n, M))
            logm = np.empty(n)
            if components:
                cmeans = np.empty((n, M, layout.structure_dim))
            for g, pattern in enumerate(patterns):
                rows = rows_where(inverse == g)  # a slice when consecutive (robust passes sort their frames so)
                x_obs = flat[rows]  # every view observed: no column gather
                if not pattern.all():
                    x_obs = x_obs[:, layout.observed_mask(pattern)[: layout.contour_dim]]
                post = condition(pattern, float(group_s2[g]), x_obs, rows)
                mean[rows], best[rows], var[rows] = post.reconstruction, post.best_mean, post.variance
                resp[rows], logm[rows] = post.responsibilities, post.log_marginal
                if components:
                    cmeans[rows] = post.component_means

        return self.assemble(inputs, mean, best, var, resp, logm, cmeans, cen, sc, stature=stature)

    def assemble(self, inputs: Inputs, mean, best, var, resp, logm, cmeans, cen, sc,
                 px: np.ndarray | None = None, stature: bool = True) -> tuple[InferenceResult, np.ndarray | None]:
        """The :meth:`infer` result from the conditioning's arrays of every frame (module doc): mixture mean (N, d),
        best component's joints block, its variance (N, 57), responsibilities (N, M), log marginal (N,), component
        means of the joints (N, M, 57) or None, the normalisation factors cen (N, K, 2) and sc (N, K) px, and the
        reconstructions in pixels (N, K, n, 2) when already made (None: made here); ``stature``: as in :meth:`infer`."""
        layout = self.layout
        c_mod, present = inputs.contours, inputs.present
        n = len(present)
        M = self.n_components
        rec, joints = layout.split(mean)
        w = layout.structure_weight
        joints_best = best.reshape(n, layout.n_joints, 3) / w
        # Var[w s] = w^2 Var[s]  ->  std(s) = sqrt(Var[w s]) / w
        joint_std = np.sqrt(np.maximum(var, 0.0)).reshape(n, layout.n_joints, 3) / w
        comp_joints = None if cmeans is None else cmeans.reshape(n, M, layout.n_joints, 3) / w
        if px is None:
            px = denormalise_contours(rec, cen, sc)
        res = InferenceResult(joints=joints, joints_best=joints_best, joint_std=joint_std, contours_norm=rec,
                              contours_px=px, centroid=cen, scale=sc, views_present=present, responsibilities=resp,
                              log_marginal=logm, views=layout.views)
        if stature:
            comp_joints = self.scale_to_stature(res, comp_joints, c_mod, present)
        return res, comp_joints

    def scale_to_stature(self, res: InferenceResult, comp_joints: np.ndarray | None, contours_mod: np.ndarray,
                         present: np.ndarray) -> np.ndarray | None:
        """In the "stature" joint frame, from "a 1.75 m walker" to each frame's own metres: ``res``'s joints,
        best-component joints and joint std (in place, new arrays) and ``comp_joints`` (N, M, 19, 3) or None
        (returned) times the stature measured from ``contours_mod`` (N, K, n, 2) px in the ``present`` (N, K)
        views over :data:`~silpose.model.stature.REFERENCE_STATURE`. Other joint frames: unchanged."""
        if self.layout.joint_frame != "stature":
            return comp_joints
        factor = self.stature(contours_mod, present) / REFERENCE_STATURE
        res.joints, res.joints_best, res.joint_std = (a * factor[:, None, None]
                                                      for a in (res.joints, res.joints_best, res.joint_std))
        return None if comp_joints is None else comp_joints * factor[:, None, None, None]

    def infer_in_blocks(self, inputs: Inputs, s2: float, components: bool,
                        stature: bool = True) -> tuple[InferenceResult, np.ndarray | None]:
        """:meth:`infer` of a large batch whose frames all have one present-view pattern, at one noise ``s2``: blocks of
        :data:`~silpose.model.conditioning.THREAD_BLOCK_ROWS` frames on the pool's threads
        (:func:`~silpose.model.threads.map_blocks`, BLAS on one thread each), each block normalised, conditioned
        and denormalised in turn while its arrays are in the cache, into the batch's arrays. The same arithmetic as
        the whole-batch steps, row by row (the normalised contours are never a whole-batch array). Only the present
        views are normalised: with 1 of 4 views the normalisation of the absent three was a quarter of the call
        (benchmark frames, 20,000, M 5 q 30: best of 3 0.39-0.45 s -> 0.33-0.34 s; floor 0.18 s); each contour is
        normalised on its own, so the values are those of the whole-batch steps (log marginals to ~1e-12 relative:
        the observed part is now its own array, summed at another alignment)."""
        layout = self.layout
        c_mod, present = inputs.contours, inputs.present
        n, kmod = present.shape
        pattern = present[0]
        every = bool(pattern.all())
        cond = self.conditioner(pattern, s2)
        sd, M = layout.structure_dim, self.n_components
        mean = np.empty((n, layout.dim))
        best, var = np.empty((n, sd)), np.empty((n, sd))
        resp, logm = np.empty((n, M)), np.empty(n)
        cmeans = np.empty((n, M, sd)) if components else None
        cen, sc = np.empty((n, kmod, 2)), np.empty((n, kmod))
        px = np.empty(c_mod.shape)

        seen = np.flatnonzero(pattern)  # the present views: only they are normalised (each contour on its own)

        def block(bounds: tuple[int, int]) -> None:
            sl = slice(*bounds)
            with np.errstate(invalid="ignore", over="ignore"):  # as in infer
                norm, c_seen, s_seen = normalise_contours(c_mod[sl] if every else c_mod[sl][:, seen])
            overflow = ~(np.isfinite(s_seen) & np.isfinite(c_seen).all(axis=-1))
            if overflow.any():
                r, p = np.argwhere(overflow)[0]
                raise ValueError(
                    f"contours_px values too large to normalise (overflow) in an observed view: frame {sl.start + r}, "
                    f"view {layout.views[seen[p]]}; pixel coordinates must be finite and of image size")
            if every:
                cen[sl], sc[sl] = c_seen, s_seen
            else:  # the known factors for absent views
                cen[sl], sc[sl] = inputs.centroid[sl], inputs.scale[sl]
                cen[sl, seen], sc[sl, seen] = c_seen, s_seen
            # the present views' normalised contours in view order: the observed part of the shape vector
            post = cond(norm.reshape(len(norm), -1), return_components=components, out=mean[sl])
            best[sl], var[sl], resp[sl], logm[sl] = post.best_mean, post.variance, post.responsibilities, post.log_marginal
            if components:
                cmeans[sl] = post.component_means
            rec = mean[sl, : layout.contour_dim].reshape(px[sl].shape)
            denormalise_contours(rec, cen[sl], sc[sl], out=px[sl])

        blocks, threads = block_bounds(n, THREAD_BLOCK_ROWS)
        map_blocks(block, blocks, threads)
        return self.assemble(inputs, mean, best, var, resp, logm, cmeans, cen, sc, px, stature=stature)

    def screened(self, screen: dict, pattern: np.ndarray, present: np.ndarray, flat: np.ndarray, rows,
                 cond: Conditioner) -> np.ndarray:
        """(n, M) bool: the components of frames ``rows`` (None = every frame) that the float32 screen keeps under
        ``cond`` (:meth:`~silpose.model.screen.Screen.candidates`). The screen of the frames with this ``pattern``
        of ``present`` (N, K) views (their normalised contours ``flat`` (N, d_contour)) is made at the first call
        and kept in ``screen``."""
        key = np.asarray(pattern, dtype=bool).tobytes()
        hit = screen.get(key)
        if hit is None:
            rows_p = np.flatnonzero((present == pattern[None, :]).all(axis=1))
            obs = self.layout.observed_mask(pattern)[: self.layout.contour_dim]
            x = flat if rows_p.size == len(flat) else flat[rows_p]
            hit = screen[key] = (rows_p, Screen(self.screen_matrices(pattern), x if obs.all() else x[:, obs]))
        rows_p, sc = hit
        if isinstance(rows, slice):
            rows = np.arange(len(flat))[rows]
        if rows is None and rows_p.size == len(flat):
            return sc.candidates(cond)
        return sc.candidates(cond, np.searchsorted(rows_p, np.arange(len(flat)) if rows is None else rows))

    def screen_matrices(self, pattern: np.ndarray) -> ScreenMatrices:
        """Cached :class:`~silpose.model.screen.ScreenMatrices` of one present-view pattern (every noise level)."""
        key = np.asarray(pattern, dtype=bool).tobytes()
        with self._lock:
            return self._screen_matrices(key, pattern)

    def _screen_matrices(self, key: bytes, pattern: np.ndarray) -> ScreenMatrices:
        """:meth:`screen_matrices` under the lock."""
        mats = self._screens.pop(key, None)
        self._screens[key] = mats  # most recently used last
        if mats is None:
            obs = np.flatnonzero(self.layout.observed_mask(pattern))
            mats = self._screens[key] = ScreenMatrices(self.mixture.components_, self.mixture.means_, obs)
            while sum(v.nbytes for v in self._screens.values()) > SCREEN_BYTES and len(self._screens) > 1:
                self._screens.pop(next(iter(self._screens)))
        return mats

    def pair_headings(self, inputs: Inputs, s2: float) -> np.ndarray:
        """(N, V) headings (radians) of the posterior mean joints given each pair of present views (V = K (K - 1) / 2
        columns, NaN where a view of the pair is absent); frames with fewer than 3 present views get no votes
        (all NaN). See :func:`~silpose.model.hypotheses.consensus_choice`."""
        layout = self.layout
        present = inputs.present
        n, kmod = present.shape
        pairs = [s for s in view_subsets(kmod) if len(s) == 2]
        votes = np.full((n, len(pairs)), np.nan)
        voting = present.sum(axis=1) >= 3
        if not voting.any():
            return votes
        with np.errstate(invalid="ignore", over="ignore"):
            norm, _, _ = normalise_contours(inputs.contours)
        flat = norm.reshape(n, -1)
        for j, pair in enumerate(pairs):
            pattern = np.zeros(kmod, dtype=bool)
            pattern[list(pair)] = True
            rows = np.flatnonzero(voting & present[:, pattern].all(axis=1))
            if rows.size == 0:
                continue
            x_obs = flat[rows][:, layout.observed_mask(pattern)[: layout.contour_dim]]
            post = self.conditioner(pattern, s2, structure_only=True)(x_obs)
            votes[rows, j] = heading(post.missing_mean.reshape(rows.size, layout.n_joints, 3))
        return votes

    def stature(self, contours_mod: np.ndarray, present: np.ndarray) -> np.ndarray:
        """(N,) metres: stature measured from the present modelled views (``silpose.model.stature``)."""
        if self.rig is None:
            raise ValueError("this model's joints are in the 'stature' frame but it has no camera rig")
        cams = [self.rig[v] for v in self.layout.views]
        return estimate_stature(contours_mod, cams, present)

    def conditioner(self, pattern: np.ndarray, s2: float, structure_only: bool = False) -> Conditioner:
        """Cached :class:`~silpose.model.conditioning.Conditioner` for one present-view pattern and s^2.

        Its q x q factorisations depend only on the pattern and s^2, so they are computed once per
        (pattern, s^2); repeated single-frame calls then cost O((d_obs + d) q M). ``structure_only``: a
        conditioner whose mean covers the joints only (``BatchPosterior.missing_mean``, (N, 57)), for the
        consensus votes.
        """
        key = (np.asarray(pattern, dtype=bool).tobytes(), s2, bool(structure_only))
        with self._lock:
            return self._conditioner(key, pattern, s2, structure_only)

    def _conditioner(self, key: tuple, pattern: np.ndarray, s2: float, structure_only: bool) -> Conditioner:
        """:meth:`conditioner` under the lock."""
        cache = self._cache
        post = cache.pop(key, None)
        if post is None:
            layout = self.layout
            det = np.arange(layout.structure_slice.start, layout.structure_slice.stop)
            if self._output is None and not structure_only:
                self._output = Conditioner.output_matrix(self.mixture)
            post = Conditioner(
                self.mixture, layout.observed_mask(pattern), s2, detail=det,
                reconstruct=not structure_only, detail_only=structure_only,
                output=None if structure_only else self._output,
            )
            cache[key] = post
            # bounded by bytes, least recently used first out: one conditioner holds O(d_a M q) floats (about 30 MB
            # for M 60, q 40 on 4 views, 105 MB for M 200), and a run may visit 2 (2^K - 1) view patterns per s^2
            total = sum(c.nbytes for c in cache.values())
            while total > CACHE_BYTES and len(cache) > 1:
                total -= cache.pop(next(iter(cache))).nbytes
        else:
            cache[key] = post  # most recently used last
        return post
