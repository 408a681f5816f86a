"""The shortcuts of robust inference's repairs and blocks give the straightforward computation's results.

Each fast path is compared with an independent, plain form of the same computation: the batched Cholesky solve of
the slide fits with ``np.linalg.solve``, the compiled search for far contour points with every point's distance to
every edge in its index window (and, when only the runs that may be excursions are wanted, with the runs of that
search filtered one by one), robust inference of a batch in blocks with the same batch at once, and its blocks on
threads with the blocks one after the other.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from silpose.model.robust import RobustSettings
from silpose.model import threads
from silpose.model.robust import loop
from silpose.model.robust import excursions
from silpose.model.robust.excursions import excursion_runs, far_points, trim_excursions
from silpose.model.robust.observed_views import view_scales
from silpose.model.robust.reindex import reindex_contours, solve_spd
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes


def test_batched_cholesky_solve_is_the_lapack_solve():
    rng = np.random.default_rng(0)
    for v, p in ((300, 7), (5, 1), (40, 3)):
        x = rng.normal(size=(v, p, 3 * p))
        G = x @ x.transpose(0, 2, 1) + 1e-3 * np.eye(p)  # symmetric positive definite, some poorly conditioned
        b = rng.normal(size=(v, p))
        want = np.linalg.solve(G, b[..., None])[..., 0]
        np.testing.assert_allclose(solve_spd(G, b), want, rtol=1e-9, atol=1e-12)


def _brute_far(points, polygon, limit):
    """(V, n) far flags by the definition: farther than the limit from the index-corresponding vertex, and from
    every edge j -> j + 1 with j within n // 4 of the point's index (each distance computed on its own)."""
    v, n = points.shape[:2]
    w = max(n // 4, 1)
    far = np.zeros((v, n), bool)
    for a in range(v):
        for i in range(n):
            p = points[a, i]
            if np.linalg.norm(p - polygon[a, i]) <= limit[a]:
                continue
            best = np.inf
            for j in range(i - w, i + w + 1):
                s, e = polygon[a, j % n], polygon[a, (j + 1) % n]
                t = np.clip(np.dot(p - s, e - s) / max(np.dot(e - s, e - s), 1e-12), 0.0, 1.0)
                best = min(best, np.linalg.norm(p - (s + t * (e - s))))
            far[a, i] = best > limit[a]
    return far


def test_far_point_search_is_the_definition():
    rng = np.random.default_rng(1)
    v, n = 8, 80
    t = 2 * np.pi * np.arange(n) / n
    outline = np.stack([30 * np.cos(t), 50 * np.sin(t)], -1) + 100
    polygon = outline + rng.normal(0, 0.5, size=(v, n, 2))
    # observed points slid along the outline by 0 .. 15 points (within n // 4 = 20 edges), jittered,
    # and a stretch pushed out (points far from every edge)
    slides = (0, 2, 5, 9, 13, 15, 3, 14)
    points = np.stack([np.roll(outline, s, axis=0) for s in slides]) + rng.normal(0, 1.0, (v, n, 2))
    points[::3, 10:25] += np.array([14.0, -9.0])
    points[1, 40] = polygon[1, 40]  # on its own vertex
    points[2, 5:7] = polygon[2, 30:32]  # on vertices beyond the window
    limit = rng.uniform(2.0, 6.0, v)
    want = _brute_far(points, polygon, limit)
    got = far_points(points, polygon, limit)
    assert 0 < want.sum() < want.size and np.array_equal(got, want)


def _wiggly_outlines(rng, v, n):
    """(points, polygon) (v, n, 2) px: jagged ellipses against their smooth reconstruction, slid a little, some with
    loops that add points to the outline (spikes out and back: excursions) and bumps that move points in place (runs
    of far points of every length, some wrapping past index 0)."""
    t = 2 * np.pi * np.arange(n) / n
    polygon = np.stack([30 * np.cos(t), 50 * np.sin(t)], -1) + 100 + rng.normal(0, 0.5, size=(v, n, 2))
    points = np.empty((v, n, 2))
    for a in range(v):
        loops = [(int(rng.integers(0, n)), int(rng.integers(4, 20))) for _ in range(rng.integers(0, 3))]
        m = n - sum(length for _, length in loops)  # points on the ellipse; the loops add the rest
        u = 2 * np.pi * (np.arange(m) + rng.integers(0, 4)) / m
        base = np.stack([30 * np.cos(u), 50 * np.sin(u)], -1) + 100
        pieces, at = [], 0
        for start, length in sorted(loops):
            start = min(start * m // n, m - 1)
            tip = base[start] + (base[start] - 100) / 40 * rng.uniform(8, 25)
            up = np.linspace(0, 1, length // 2 + 2)[1:-1, None]
            down = np.linspace(1, 0, length - length // 2 + 2)[1:-1, None]
            pieces += [base[at:start + 1], base[start] + np.r_[up, down] * (tip - base[start])]
            at = start + 1
        points[a] = np.concatenate(pieces + [base[at:]])[:n] + rng.normal(0, rng.uniform(0.3, 2.0), (n, 2))
        for _ in range(rng.integers(0, 3)):  # bumps in place: 1 to 40 points pushed out 3 to 25 px
            start, length = rng.integers(0, n), rng.integers(1, 40)
            idx = (start + np.arange(length)) % n
            bump = np.sin(np.pi * (np.arange(length) + 1) / (length + 1))[:, None]
            points[a, idx] += bump * rng.uniform(3, 25) * (points[a, idx] - 100) / 40
    return points, polygon


def test_far_points_of_possible_excursions_are_the_far_runs_that_pass_the_arc_test():
    """With ``extra``, the far runs reported are exactly the far runs of the full search whose arc - chord exceeds
    it (each run's arc summed on its own), and views that are far all round are kept whole."""
    rng = np.random.default_rng(4)
    v, n = 60, 100
    points, polygon = _wiggly_outlines(rng, v, n)
    points[0] = polygon[0] + 200.0  # far all round
    limit = rng.uniform(2.0, 5.0, v)
    extra = rng.uniform(4.0, 14.0, v)
    full = far_points(points, polygon, limit)
    got = far_points(points, polygon, limit, extra)
    want = np.zeros_like(full)
    kept = dropped = 0
    for a in range(v):
        for run in excursion_runs(full[a]):
            if len(run) == n:
                want[a] = True
                continue
            path = points[a, np.r_[(run[0] - 1) % n, run, (run[-1] + 1) % n]]
            arc = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
            if arc - np.linalg.norm(path[-1] - path[0]) > extra[a]:
                want[a, run] = True
                kept += 1
            else:
                dropped += 1
    assert kept > 20 and dropped > 20 and want[0].all()  # both kinds of run, many of them
    assert np.array_equal(got, want)


def test_trimming_with_the_pruned_search_equals_the_full_search(monkeypatch):
    rng = np.random.default_rng(5)
    points, polygon = _wiggly_outlines(rng, 80, 100)
    present = np.ones((20, 4), bool)
    present[::3, 1] = False
    c, rec = points.reshape(20, 4, 100, 2), polygon.reshape(20, 4, 100, 2)
    pruned, changed = trim_excursions(c, rec, present)
    full_search = excursions.far_points
    monkeypatch.setattr(excursions, "far_points", lambda p, q, limit, extra=None: full_search(p, q, limit))
    full, full_changed = trim_excursions(c, rec, present)
    assert 5 < changed.sum() < changed.size - 20
    assert np.array_equal(changed, full_changed) and np.array_equal(pruned, full)


def test_repairs_with_known_view_scales_equal_the_repairs_that_compute_them():
    """Robust inference keeps the observed views' scales from one repair to the next (they depend on the observed
    points only): given them, trimming and re-indexing give what they give computing them (absent views: NaN)."""
    rng = np.random.default_rng(6)
    points, polygon = _wiggly_outlines(rng, 80, 100)
    present = np.ones((20, 4), bool)
    present[::3, 1] = False
    c, rec = points.reshape(20, 4, 100, 2), polygon.reshape(20, 4, 100, 2)
    c[~present] = np.nan
    with np.errstate(invalid="ignore"):
        scales = view_scales(c.reshape(-1, 100, 2)).reshape(20, 4)
    assert np.isnan(scales[~present]).all() and np.isfinite(scales[present]).all()
    for step in (trim_excursions, reindex_contours):
        out, changed = step(c, rec, present)
        known, known_changed = step(c, rec, present, scales=scales)
        assert changed.any() and np.array_equal(changed, known_changed)
        assert np.array_equal(out, known, equal_nan=True)


@pytest.fixture(scope="module")
def small_model():
    train = make_linear_shapes(300, n_views=3, n_points=24, seed=5)
    test = make_linear_shapes(330, n_views=3, n_points=24, seed=5)
    model = ShapeStructureModel(n_components=3, n_latent=5, structure_weight=2.0, noise_variance=1e-3, n_init=1,
                                random_state=0, joint_frame="metres").fit(train.contours, train.joints)
    return model, test.contours[300:].astype(np.float64)


def _corrupted(contours):
    """(contours with a stretch of view 1 pushed out in every 4th frame, view 2 absent (NaN) in every 5th; present)."""
    bad = contours.copy()
    bad[::4, 1, 3:8] += np.array([25.0, -15.0])
    present = np.ones(bad.shape[:2], bool)
    present[::5, 2] = False
    bad[::5, 2] = np.nan
    return bad, present


def test_robust_inference_in_blocks_equals_the_batch_at_once(small_model, monkeypatch):
    model, contours = small_model
    bad, present = _corrupted(contours)
    settings = RobustSettings(window=2)
    whole = model.infer(bad, present, robust=settings, hypotheses=2)
    monkeypatch.setattr(loop, "BLOCK_FRAMES", 7)  # 30 frames: 5 blocks of 6
    blocks = model.infer(bad, present, robust=settings, hypotheses=2)
    for name in ("joints", "joints_best", "contours_px", "robust_weights", "responsibilities", "log_marginal",
                 "log_marginal_robust", "noise_variance", "robust_input_px"):
        # equal to rounding: BLAS may block a product's rows differently for another batch size (seen: 5e-12)
        np.testing.assert_allclose(getattr(blocks, name), getattr(whole, name), rtol=1e-9, atol=1e-10,
                                   err_msg=name)
    for name in ("excursions_trimmed", "reindexed", "views_present"):
        assert np.array_equal(getattr(blocks, name), getattr(whole, name)), name
    np.testing.assert_allclose(blocks.hypotheses.joints, whole.hypotheses.joints, rtol=1e-9, atol=1e-10)
    assert np.array_equal(blocks.hypotheses.component, whole.hypotheses.component)


def test_blocks_on_threads_equal_the_blocks_one_after_the_other(small_model, monkeypatch):
    """A batch's blocks inferred on threads (silpose.model.threads.map_blocks, BLAS on one thread) give the answers of
    the same blocks on the caller's thread, and more than one thread did run them."""
    model, contours = small_model
    bad, present = _corrupted(contours)
    monkeypatch.setattr(loop, "BLOCK_FRAMES", 4)
    monkeypatch.setattr(threads, "MIN_THREAD_FRAMES", 6)
    monkeypatch.setattr(threads, "THREADS", 1)
    one = model.infer(bad, present, robust=True)
    seen = set()
    block = loop.robust_block

    def on_thread(*args):
        seen.add(threading.get_ident())
        time.sleep(0.01)  # each thread takes a block before the first is done
        return block(*args)

    monkeypatch.setattr(loop, "robust_block", on_thread)
    monkeypatch.setattr(threads, "THREADS", 3)
    bounds, count = threads.block_bounds(30, loop.BLOCK_FRAMES)  # 8 blocks of <= 4 frames: 9 for 3 threads
    assert count == 3 and len(bounds) == 9 and {b - a for a, b in bounds} == {3, 4}
    threaded = model.infer(bad, present, robust=True)
    assert len(seen) > 1
    for name in ("joints", "joints_best", "contours_px", "robust_weights", "responsibilities", "log_marginal",
                 "log_marginal_robust", "noise_variance", "robust_input_px"):
        # BLAS on one thread may round a product differently (seen: 2e-16)
        np.testing.assert_allclose(getattr(threaded, name), getattr(one, name), rtol=1e-9, atol=1e-10, err_msg=name)
    for name in ("excursions_trimmed", "reindexed"):
        assert np.array_equal(getattr(threaded, name), getattr(one, name)), name


def test_map_blocks_reuses_its_pool_and_maps_nested_blocks_in_place():
    """Blocks run on the pool's threads (the same ones from call to call); a block that maps blocks again runs them
    on its own thread (no waiting for a pool thread that is busy with it), and the answers keep the blocks' order."""
    def inner(c):
        time.sleep(0.005)
        return c, threading.current_thread().name

    def outer(b):
        return b, threading.current_thread().name, threads.map_blocks(inner, [0, 1, 2], 2)

    names, pools = set(), []
    for _ in range(2):
        got = threads.map_blocks(outer, list(range(6)), 2)
        assert [b for b, _, _ in got] == list(range(6))
        for _, name, nested in got:
            assert name.startswith("silpose-block") and [c for c, _ in nested] == [0, 1, 2]
            assert {n for _, n in nested} == {name}  # in place, on the block's own thread
            names.add(name)
        pools.append({t.name for t in threading.enumerate() if t.name.startswith("silpose-block")})
    assert len(names) > 1 and names <= pools[0] == pools[1]  # the second call started no thread
    assert threads.map_blocks(inner, [0, 1], 1) == [(0, threading.current_thread().name),
                                                     (1, threading.current_thread().name)]


def test_block_bounds_cover_the_batch_in_equal_shares(monkeypatch):
    monkeypatch.setattr(threads, "THREADS", 2)
    for n in (0, 1, 511, 512, 1000, 1025, 2500, 20000):
        for most in (loop.BLOCK_FRAMES, None):
            bounds, count = threads.block_bounds(n, most)
            sizes = [b - a for a, b in bounds]
            assert bounds[0][0] == 0 and bounds[-1][1] == n and all(b[1] == c[0] for b, c in zip(bounds, bounds[1:]))
            assert (most is None or max(sizes) <= max(most, 1)) and max(sizes) - min(sizes) <= 1
            assert count == (2 if n >= 2 * threads.MIN_THREAD_FRAMES else 1) and len(bounds) % count == 0
            assert most is not None or len(bounds) == count  # no bound: one block per thread
    assert threads.block_bounds(2000, loop.BLOCK_FRAMES) == ([(0, 1000), (1000, 2000)], 2)


def test_reweighting_passes_sorted_by_group_and_in_chunks_equal_the_plain_order(small_model, monkeypatch):
    """The reweighting passes on frames sorted by (views, noise level, component) and their point-wise steps in
    chunks of frames give the results of the passes in the caller's order on whole arrays."""
    model, contours = small_model
    bad = contours.copy()
    bad[::3, 0, 2:9] += np.array([18.0, 11.0])
    present = np.ones(bad.shape[:2], bool)
    present[1::4, 1] = False
    bad[1::4, 1] = np.nan
    settings = RobustSettings(excursion_passes=0, reindex_passes=0)
    sorted_chunks = model.infer(bad, present, robust=settings)
    assert loop.pass_order(sorted_chunks.responsibilities, present, sorted_chunks.noise_variance) is not None
    monkeypatch.setattr(loop, "CHUNK_FRAMES", 4)
    chunks = model.infer(bad, present, robust=settings)
    monkeypatch.setattr(loop, "pass_order", lambda *args: None)
    plain = model.infer(bad, present, robust=settings)
    for name in ("joints", "contours_px", "robust_weights", "responsibilities", "log_marginal_robust",
                 "noise_variance"):
        assert np.array_equal(getattr(chunks, name), getattr(sorted_chunks, name), equal_nan=True), name  # same order
        # another order of the rows: BLAS may round a row's products differently
        np.testing.assert_allclose(getattr(sorted_chunks, name), getattr(plain, name), rtol=1e-9, atol=1e-10,
                                   err_msg=name)


def test_pass_order_makes_groups_consecutive():
    rng = np.random.default_rng(9)
    present = rng.random((40, 3)) > 0.3
    s2 = rng.choice([1e-3, 1e-2], size=40)
    resp = rng.dirichlet(np.ones(4), size=40)
    order = loop.pass_order(resp, present, s2)
    key = np.stack([present[order] @ np.array([1, 2, 4]), s2[order], resp[order].argmax(axis=1)], axis=1)
    starts = np.flatnonzero(np.r_[True, (key[1:] != key[:-1]).any(axis=1)])  # each group one run
    assert len(starts) == len({tuple(k) for k in key}) and np.array_equal(np.sort(order), np.arange(40))
    assert loop.pass_order(resp[order], present[order], s2[order]) is None  # already in order
    assert loop.pass_order(resp[:1], present[:1], s2[:1]) is None
