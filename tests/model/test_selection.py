"""Model selection on synthetic data whose true latent dimension is known."""

import numpy as np
import pytest

from silpose.model.augment import Roughness, roughen_contours
from silpose.model.selection import (
    VALIDATION_ROUGHNESS_SEED,
    choose,
    results_markdown,
    select,
    unit_weight_loglik,
    validation_split,
)
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.metrics import pose_error_cm
from silpose.shared.skeleton import root_relative


def test_validation_split_is_a_seeded_partition():
    tr, va = validation_split(101, 0.2, seed=4)
    assert va.size == 20 and tr.size == 81
    np.testing.assert_array_equal(np.sort(np.r_[tr, va]), np.arange(101))
    tr2, va2 = validation_split(101, 0.2, seed=4)
    np.testing.assert_array_equal(va, va2)
    assert not np.array_equal(va, validation_split(101, 0.2, seed=5)[1])
    with pytest.raises(ValueError, match="fraction"):
        validation_split(10, 1.0)


def test_validation_split_keys_are_the_documented_stream():
    """The permutation is SeedSequence([seed, 7919]) (silpose.shared.seeds.VALIDATION_STREAM): changing
    the keys would change every held-out split and model."""
    perm = np.random.default_rng(np.random.SeedSequence([4, 7919])).permutation(101)
    tr, va = validation_split(101, 0.2, seed=4)
    np.testing.assert_array_equal(va, np.sort(perm[:20]))
    np.testing.assert_array_equal(tr, np.sort(perm[20:]))


def test_selection_scores_root_relative_predictions_like_an_explicit_loop():
    """Selection scores with silpose.shared.metrics.pose_error_cm; on root-relative predictions (what
    infer returns) it is the mean Euclidean joint distance to the root-relative truth, in cm."""
    rng = np.random.default_rng(0)
    pred, true = root_relative(rng.normal(size=(4, 19, 3))), rng.normal(size=(4, 19, 3))
    rel = root_relative(true)
    ref = [100 * np.mean([np.sqrt(((pred[i, j] - rel[i, j]) ** 2).sum()) for j in range(19)]) for i in range(4)]
    np.testing.assert_allclose(pose_error_cm(pred, true), ref, rtol=1e-12)


def test_grid_prefers_the_true_latent_dimension():
    data = make_linear_shapes(300, n_views=2, n_points=12, n_factors=4, n_clusters=1, seed=11)
    calls = []
    res = select(
        data.contours, data.joints,
        grid={"n_latent": (1, 4), "n_components": (1,), "structure_weight": (1.0, 3.0), "noise_variance": (0.0, 1e-3)},
        val_fraction=0.25, seed=2, max_iter=50, progress=lambda i, n, row: calls.append((i, n)),
    )
    assert len(res.rows) == 2 * 2 * 2 and calls[-1] == (4, 4)
    assert res.best["n_latent"] == 4  # one factor cannot explain a 4-factor pose space
    err_q1 = min(r["val_error_cm"] for r in res.rows if r["n_latent"] == 1)
    assert res.best["val_error_cm"] < 0.5 * err_q1
    assert all(r["real_em"] for r in res.rows)  # M = 1: the closed form is the maximum-likelihood fit
    # the table row reproduces: refit the winner by hand and score the same (ragged) validation frames
    tr, va = validation_split(300, 0.25, seed=2)
    b = res.best
    m = ShapeStructureModel(b["n_components"], b["n_latent"], structure_weight=b["structure_weight"], n_init=1,
                            max_iter=50, tol=1e-3, random_state=2).fit(data.contours[tr], data.joints[tr])
    c_val = roughen_contours(data.contours[va], Roughness(), 2 + VALIDATION_ROUGHNESS_SEED, va)
    pred = m.infer(c_val, noise_variance=b["noise_variance"]).joints
    assert pose_error_cm(pred, data.joints[va]).mean() == pytest.approx(b["val_error_cm"], rel=1e-9)
    # held-out log-likelihood in structure-weight-1 units: log p_w(w s) + 57 log w
    ll = m.score_samples(data.contours[va], data.joints[va]).mean() + 57 * np.log(b["structure_weight"])
    assert ll == pytest.approx(b["val_loglik"], rel=1e-9)
    md = res.to_markdown()
    assert md.count("\n") == 2 + len(res.rows) and md.count("| * |") == 1
    assert results_markdown(res.rows).count("| * |") == 0


def test_unit_weight_loglik_adds_the_jacobian_of_the_structure_weighting():
    """The structure weight multiplies the 57 joint coordinates (and nothing else) of the shape vector, a
    linear map with Jacobian w^57: log p(s) = log p_w(w s) + 57 log w."""
    data = make_linear_shapes(200, n_views=1, n_points=8, n_factors=2, n_clusters=1, seed=3)
    m1 = ShapeStructureModel(1, 2, structure_weight=1.0, n_init=1, max_iter=20).fit(data.contours, data.joints)
    m10 = ShapeStructureModel(1, 2, structure_weight=10.0, n_init=1, max_iter=20).fit(data.contours, data.joints)
    scale = np.ones(m1.layout_.dim)
    scale[m1.layout_.contour_dim:] = 10.0
    assert m1.layout_.dim - m1.layout_.contour_dim == 57
    np.testing.assert_allclose(m10.features(data.contours, data.joints), m1.features(data.contours, data.joints) * scale,
                               rtol=1e-12)
    raw = np.array([1.0, -2.0])
    np.testing.assert_allclose(unit_weight_loglik(m10, raw), raw + 57 * np.log(10.0), rtol=1e-12)
    np.testing.assert_allclose(unit_weight_loglik(m1, raw), raw, rtol=1e-12)


def _row(q, m, score, ll, real=True, n_par=None, s2=0.03):
    return {"n_latent": q, "n_components": m, "structure_weight": 30.0, "noise_variance": s2, "val_score_cm": score,
            "val_loglik": ll, "real_em": real, "n_parameters": n_par if n_par is not None else q * m}


def test_choose_a_smaller_model_that_matches_the_error_wins():
    rows = [_row(40, 20, 3.00, 1000.0), _row(30, 10, 3.05, 1500.0), _row(20, 10, 3.50, 1800.0)]
    best, how = choose(rows, error_tolerance=0.02)
    assert (best["n_latent"], best["n_components"]) == (30, 10)  # within 2 % and 2.7x fewer parameters
    assert how["pool"] == "real EM fits" and len(how["matching"]) == 2
    best, _ = choose(rows, error_tolerance=0.01)
    assert (best["n_latent"], best["n_components"]) == (40, 20)  # 3.05 is 1.7 % worse: no longer a match


def test_choose_skips_frozen_fits_and_dominated_ones_and_picks_the_best_noise_per_fit():
    rows = [_row(40, 20, 2.50, 3000.0, real=False), _row(30, 10, 3.00, 900.0), _row(30, 10, 2.90, 900.0, s2=0.1),
            _row(20, 5, 2.95, 1200.0, n_par=10**6)]
    best, how = choose(rows, error_tolerance=0.0)
    assert best["n_components"] == 10 and best["noise_variance"] == 0.1  # the frozen 2.50 fit is not eligible
    # (20, 5) is worse on score but better on log-likelihood: both are on the Pareto front
    assert sorted(k[1] for k in how["pareto"]) == [5, 10]
    best, _ = choose(rows, error_tolerance=0.05)  # now both match; the smaller parameter count wins
    assert best["n_components"] == 10
    rows.append(_row(30, 12, 2.92, 800.0, n_par=1))  # dominated by (30, 10) at s2 0.1: never chosen
    best, how = choose(rows, error_tolerance=0.05)
    assert best["n_components"] == 10 and [30, 12, 30.0, 0.03] not in how["pareto"]
    frozen_only = [_row(40, 20, 2.5, 10.0, real=False), _row(40, 10, 2.6, 10.0, real=False)]
    best, how = choose(frozen_only)
    assert how["pool"].startswith("all fits") and best["n_components"] == 20


def test_bad_grid():
    data = make_linear_shapes(20, n_views=1, n_points=8)
    with pytest.raises(ValueError, match="unknown grid keys"):
        select(data.contours, data.joints, grid={"q": (1,)})
    with pytest.raises(ValueError, match="empty"):
        select(data.contours, data.joints, grid={"n_latent": ()})


def test_group_validation_split_holds_out_whole_groups():
    from silpose.model.selection import validation_split_groups

    groups = np.repeat(np.arange(20), np.arange(1, 21))  # uneven group sizes, 210 rows
    tr, va = validation_split_groups(groups, 0.2, seed=3)
    assert len(tr) + len(va) == len(groups) and len(va) > 0 and len(tr) > 0
    assert set(groups[tr]).isdisjoint(groups[va])
    assert 0.1 < len(va) / len(groups) <= 0.3
    tr2, va2 = validation_split_groups(groups, 0.2, seed=3)
    np.testing.assert_array_equal(va, va2)
    with pytest.raises(ValueError, match="2 groups"):
        validation_split_groups(np.zeros(5), 0.2)
