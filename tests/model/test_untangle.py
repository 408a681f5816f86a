"""Self-intersection test against an exhaustive O(n^2) edge-pair reference, and 2-opt untangling."""

import numpy as np

from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.model.untangle import batch_crossings, crossing_pairs, self_intersecting, untangle, untangle_order


def _brute(poly: np.ndarray) -> bool:
    """Every pair of non-adjacent edges, proper crossing by the sign of cross products (the reference)."""
    n = len(poly)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            p, q, r, s = poly[i], poly[(i + 1) % n], poly[j], poly[(j + 1) % n]
            if cross(p, q, r) * cross(p, q, s) < 0 and cross(r, s, p) * cross(r, s, q) < 0:
                return True
    return False


def _figure_eight(n=40):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.stack([np.sin(t), np.sin(t) * np.cos(t)], -1) * 30 + 50


def test_matches_the_exhaustive_reference_on_random_polygons():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2 * np.pi, 30, endpoint=False)
    polys = []
    for amp in (0.0, 0.2, 0.6, 1.2):  # from a circle to a tangled star
        for _ in range(10):
            r = 20 * (1 + amp * rng.standard_normal(30).clip(-0.9, 3))
            polys.append(np.stack([r * np.cos(t), r * np.sin(t)], -1))
    polys = np.array(polys)
    got = self_intersecting(polys)
    assert list(got) == [_brute(p) for p in polys]
    assert got.any() and not got.all()


def test_untangle_makes_a_figure_eight_simple_and_keeps_points():
    f8 = _figure_eight()
    assert self_intersecting(f8) and len(crossing_pairs(f8)) >= 1
    norm = (f8 - 50) / 30.0  # the same polygon in other units
    fixed, fixed_norm = untangle(f8[None], norm[None])
    assert not self_intersecting(fixed[0]) and not self_intersecting(fixed_norm[0])
    np.testing.assert_array_equal(np.sort(fixed[0], axis=0), np.sort(f8, axis=0))  # same points, reordered
    np.testing.assert_array_equal(fixed[0, 0], f8[0])  # the start point stays first
    np.testing.assert_allclose(fixed_norm[0], (fixed[0] - 50) / 30.0)  # the same order applied to both
    # a simple polygon and a NaN polygon are left as they are
    t = np.linspace(0, 2 * np.pi, 20, endpoint=False)
    circle = np.stack([np.cos(t), np.sin(t)], -1)
    nan = np.full_like(circle, np.nan)
    out = untangle(np.stack([circle, nan]))[0]
    np.testing.assert_array_equal(out[0], circle)
    assert np.isnan(out[1]).all() and not self_intersecting(nan)


def test_infer_untangle_returns_simple_contours():
    data = make_linear_shapes(200, n_views=2, n_points=24, seed=2, pixel_noise=2.0)
    model = ShapeStructureModel(n_components=2, n_latent=8, structure_weight=2.0, noise_variance=1e-4, n_init=1,
                                random_state=0, joint_frame="metres").fit(data.contours, data.joints)
    assert self_intersecting(model.infer(data.contours[:50]).contours_px).mean() > 0.5  # tangled as inferred
    res = model.infer(data.contours[:50], untangle=True)
    assert not self_intersecting(res.contours_px).any() and not self_intersecting(res.contours_norm).any()


def _brute_pairs(poly: np.ndarray) -> list[tuple[int, int]]:
    """Every crossing pair (i < j) of one polygon, exhaustively (the reference's test, all pairs)."""
    n = len(poly)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    out = []
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            p, q, r, s = poly[i], poly[(i + 1) % n], poly[j], poly[(j + 1) % n]
            if cross(p, q, r) * cross(p, q, s) < 0 and cross(r, s, p) * cross(r, s, q) < 0:
                out.append((i, j))
    return out


def _tangled_batch(seed=5, count=24, n=30):
    """Polygons from a circle to a tangled star, with edges of uneven lengths, and one NaN polygon."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 2 * np.pi, (count, n)), axis=1)
    r = 20 * (1 + rng.uniform(0.8, 2.5, (count, 1)) * rng.standard_normal((count, n)).clip(-0.9, 3))
    polys = np.stack([r * np.cos(t), r * np.sin(t)], -1) * rng.uniform(0.1, 10, (count, 1, 1))  # another scale each
    polys[7, 3] = np.nan
    return polys


def _reference_order(poly: np.ndarray) -> np.ndarray:
    """2-opt moves one pair at a time: always the stretch of the first crossing pair of the exhaustive test."""
    order = np.arange(len(poly))
    for _ in range(200):
        hits = _brute_pairs(poly[order])
        if not hits:
            break
        i, j = hits[0]
        order[i + 1 : j + 1] = order[i + 1 : j + 1][::-1]
    return order


def test_batch_crossings_are_each_polygons_exhaustive_pairs():
    """One k-d tree for the batch, each polygon in units of its own longest edge: the pairs of every polygon
    alone, from the exhaustive reference, and none between two polygons."""
    polys = _tangled_batch()
    got = batch_crossings(polys)
    want = [(b, i, j) for b, p in enumerate(polys) if np.isfinite(p).all() for i, j in _brute_pairs(p)]
    assert [tuple(r) for r in got] == want
    assert len({b for b, _, _ in want}) > 5 and 7 not in {b for b, _, _ in want}
    for b in (0, 3):  # the one-polygon form agrees
        assert [tuple(r) for r in crossing_pairs(polys[b])] == _brute_pairs(polys[b])


def test_untangling_a_batch_makes_each_polygons_own_moves():
    """All polygons untangled together: each ends in the order its own 2-opt moves give (the reference: one
    polygon at a time, always reversing the stretch of its first crossing pair from the exhaustive test)."""
    polys = _tangled_batch(seed=11)

    fixed = untangle(polys)[0]
    for b, p in enumerate(polys):
        if np.isfinite(p).all():
            np.testing.assert_array_equal(fixed[b], p[_reference_order(p)])
            np.testing.assert_array_equal(untangle_order(p), _reference_order(p))
        else:
            np.testing.assert_array_equal(fixed[b], p)
    assert self_intersecting(polys).sum() > 5 and not self_intersecting(fixed).any()


def test_untangling_grid_polygons_with_touching_and_collinear_edges_matches_the_reference():
    """Polygons on a 4 x 4 integer grid: repeated points, edges that touch, overlap or run along each other (zero
    cross products, which are not crossings), and crossings whose segments' boxes only touch. The compiled moves
    (silpose.model.untangle_kernels: boxes first, then the sign test) end where the one-pair-at-a-time reference
    does."""
    rng = np.random.default_rng(5)

    polys = [rng.integers(0, 4, (n, 2)).astype(float) for n in (4, 5, 6, 8, 12) for _ in range(40)]
    tangled = 0
    for p in polys:
        want = _reference_order(p)
        tangled += not np.array_equal(want, np.arange(len(p)))
        np.testing.assert_array_equal(untangle_order(p), want)
    assert tangled > 50  # the grid gives many crossings, not only touching edges
