"""Subjects: determinism, documented distributions, train vs test characters differ."""

import numpy as np
import pytest

from silpose.datagen import subjects
from silpose.datagen.subjects import SUBJECT_FIELDS, VERTICAL_RATIOS, describe_distribution, sample_subject


def _draw(split, n=400, seed=0):
    rng = np.random.default_rng(seed)
    return [sample_subject(rng, split) for _ in range(n)]


def test_fields_order_and_determinism():
    a = sample_subject(np.random.default_rng(7), "test")
    b = sample_subject(np.random.default_rng(7), "test")
    assert tuple(a) == SUBJECT_FIELDS == tuple(sample_subject(np.random.default_rng(7), "train"))
    assert a == b
    assert a != sample_subject(np.random.default_rng(8), "test")


def test_vertical_chain_sums_to_stature():
    for s in _draw("train", 50) + _draw("test", 50):
        assert sum(s[k] for k in VERTICAL_RATIOS) == pytest.approx(1.0, abs=1e-12)
        L = subjects.segment_lengths(s)
        assert sum(L[k[2:]] for k in VERTICAL_RATIOS) == pytest.approx(s["height"], abs=1e-12)


@pytest.mark.parametrize("split", ["train", "test"])
def test_samples_inside_documented_ranges(split):
    desc = describe_distribution(split)["fields"]
    draws = _draw(split)
    for key in SUBJECT_FIELDS:
        vals = np.array([d[key] for d in draws])
        spec = desc[key]
        if key in VERTICAL_RATIOS:
            continue  # rescaled after drawing (documented)
        if "value" in spec:
            assert np.all(vals == spec["value"]), key
        elif spec["distribution"] == "uniform":
            assert vals.min() >= spec["low"] and vals.max() <= spec["high"], key
            # uniform: the draws should fill most of the range
            assert vals.max() - vals.min() > 0.8 * (spec["high"] - spec["low"]), key
        else:  # worn items: 0 or inside the range
            present = vals[vals != 0]
            assert present.size > 0, key
            assert present.min() >= spec["low"] and present.max() <= spec["high"], key
            if "magnitude" in spec:  # +- uniform: both signs, never below the magnitude range
                lo, hi = spec["magnitude"]
                assert np.abs(present).min() >= lo and np.abs(present).max() <= hi, key
                assert (present > 0).any() and (present < 0).any(), key


def _old_test_subject(rng):
    """The test split's draw as the first version of subjects.py made it (independent reference: the test
    split must stay bit-identical, so test datasets and their figures are unchanged)."""
    nominal = subjects.NOMINAL_RATIOS
    ranges = {"height": (1.50, 1.98), **{k: (v * 0.92, v * 1.08) for k, v in nominal.items()},
              "r_thigh": (nominal["r_thigh"] * 0.98, nominal["r_thigh"] * 1.12),
              "r_torso_lower": (nominal["r_torso_lower"] * 0.85, nominal["r_torso_lower"] * 1.0),
              "g_torso": (0.80, 1.35), "g_limbs": (0.80, 1.30), "g_head": (0.95, 1.15)}
    old_fields = SUBJECT_FIELDS[:21]
    s = {k: 0.0 for k in old_fields}
    for key in old_fields:
        if key in ranges:
            s[key] = float(rng.uniform(*ranges[key]))
    total = sum(s[k] for k in VERTICAL_RATIOS)
    for k in VERTICAL_RATIOS:
        s[k] = s[k] / total
    u = rng.uniform(size=3)
    shapes = {k: float(rng.uniform(*r)) for k, r in (("skirt_length", (0.25, 0.75)), ("skirt_flare", (0.17, 0.30)),
                                                     ("trouser_width", (0.015, 0.04)), ("hair_volume", (0.01, 0.035)),
                                                     ("hair_length", (0.08, 0.25)))}
    if u[0] < 0.4:
        s["skirt_length"], s["skirt_flare"] = shapes["skirt_length"], shapes["skirt_flare"]
    if u[1] < 0.5:
        s["trouser_width"] = shapes["trouser_width"]
    if u[2] < 0.6:
        s["hair_volume"], s["hair_length"] = shapes["hair_volume"], shapes["hair_length"]
    return s


def test_test_split_draws_are_those_of_the_first_version():
    for seed in range(200):
        new, old = sample_subject(np.random.default_rng(seed), "test"), _old_test_subject(np.random.default_rng(seed))
        assert {k: new[k] for k in old} == old
        assert new["hair_back"] == (subjects.TEST_HAIR_BACK if old["hair_length"] > 0 else 0.0)
        assert new["skirt_top"] == new["skirt_curve"] == new["trouser_flare"] == new["jacket_bulk"] == 0.0
        # and the generator is left where the first version left it (the gait is drawn next)
        r1, r2 = np.random.default_rng(seed), np.random.default_rng(seed)
        sample_subject(r1, "test"), _old_test_subject(r2)
        assert r1.uniform() == r2.uniform()


def test_training_walkers_are_dressed_like_the_test_but_in_other_shapes():
    train, test = _draw("train", 2000, 1), _draw("test", 2000, 2)
    probs = describe_distribution("train")["clothing_probability"]
    frac = lambda ds, k: np.mean([d[k] > 0 for d in ds])  # noqa: E731
    # binomial, n = 2000: 4 standard deviations ~ 0.045
    assert abs(frac(train, "skirt_length") - probs["skirt"]) < 0.045
    assert abs(frac(train, "trouser_width") - probs["trousers"]) < 0.045
    assert abs(frac(train, "jacket_bulk") - probs["jacket"]) < 0.045
    for k in ("skirt_length", "trouser_width", "hair_volume"):
        assert abs(frac(train, k) - frac(test, k)) < 0.08, k  # as dressed as the test (hair: + the redressed)
    # garment shapes: every training skirt is curved or a coat, every test skirt a straight cone from the hips
    skirts = [d for d in train if d["skirt_length"] > 0]
    assert all(abs(d["skirt_curve"]) >= 0.01 for d in skirts)
    assert 0.25 < np.mean([d["skirt_top"] == 1.0 for d in skirts]) < 0.45
    assert all(d["skirt_curve"] == 0 and d["skirt_top"] == 0 for d in test)
    assert all(abs(d["trouser_flare"]) >= 0.006 for d in train if d["trouser_width"] > 0)
    assert all(abs(d["hair_back"] - subjects.TEST_HAIR_BACK) >= 0.15 for d in train if d["hair_length"] > 0)
    assert all(d["jacket_bulk"] == 0 for d in test)
    # combinations: nobody in training wears nothing; some test walkers do
    items = ("skirt_length", "trouser_width", "hair_volume", "jacket_bulk")
    assert all(any(d[k] > 0 for k in items) for d in train)
    assert np.mean([not any(d[k] > 0 for k in items) for d in test]) > 0.05
    # proportions: the training ranges cover the test's
    for key in ("height", "g_torso", "g_limbs", "g_head", "r_thigh", "r_torso_lower"):
        tr = describe_distribution("train")["fields"][key]
        te = describe_distribution("test")["fields"][key]
        assert tr["low"] <= te["low"] and tr["high"] >= te["high"], key


def test_radii_include_clothing_and_scale_with_height():
    s = sample_subject(np.random.default_rng(0), "test")
    s = dict(s, trouser_width=0.0, hair_volume=0.0)
    r = subjects.joint_radii(s)
    s2 = dict(s, height=2 * s["height"])
    assert subjects.joint_radii(s2)["knee"] == pytest.approx(2 * r["knee"])
    s3 = dict(s, trouser_width=0.03, hair_volume=0.02)
    r3 = subjects.joint_radii(s3)
    assert r3["knee"] == pytest.approx(r["knee"] + 0.03) and r3["toe"] == r["toe"]
    assert r3["head"] == pytest.approx(r["head"] + 0.02)
    # flared trousers widen towards the ankle, tapered ones narrow, never below the skin
    r4 = subjects.joint_radii(dict(s3, trouser_flare=0.02))
    assert (r4["hip"], r4["knee"], r4["ankle"]) == pytest.approx((r["hip"] + 0.03, r["knee"] + 0.04, r["ankle"] + 0.05))
    r5 = subjects.joint_radii(dict(s3, trouser_flare=-0.08))
    assert r5["hip"] == pytest.approx(r["hip"] + 0.03)
    assert r5["knee"] == pytest.approx(r["knee"]) and r5["ankle"] == pytest.approx(r["ankle"])
    # a jacket thickens the torso and the upper arm by its documented shares, not the legs
    r6 = subjects.joint_radii(dict(s, jacket_bulk=0.04))
    for name, share in subjects.JACKET_SHARE.items():
        assert r6[name] == pytest.approx(r[name] + share * 0.04)
    assert r6["knee"] == r["knee"] and r6["wrist"] == r["wrist"]


def test_bad_split():
    with pytest.raises(ValueError, match="split"):
        sample_subject(np.random.default_rng(0), "validation")
