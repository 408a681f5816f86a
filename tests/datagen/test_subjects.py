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
        else:  # test-only shapes: 0 or inside the range
            present = vals[vals != 0]
            assert present.size > 0, key
            assert present.min() >= spec["low"] and present.max() <= spec["high"], key


def test_test_characters_never_occur_in_training():
    train, test = _draw("train", 1000, 1), _draw("test", 1000, 2)
    shapes = ("skirt_length", "skirt_flare", "trouser_width", "hair_volume", "hair_length")
    assert all(d[k] == 0 for d in train for k in shapes)
    probs = describe_distribution("test")["clothing_probability"]
    frac_skirt = np.mean([d["skirt_length"] > 0 for d in test])
    frac_hair = np.mean([d["hair_volume"] > 0 for d in test])
    frac_trousers = np.mean([d["trouser_width"] > 0 for d in test])
    # binomial, n = 1000: 4 standard deviations ~ 0.065
    assert abs(frac_skirt - probs["skirt"]) < 0.065
    assert abs(frac_hair - probs["hair"]) < 0.065
    assert abs(frac_trousers - probs["trousers"]) < 0.065
    # other proportion ranges: test girths reach beyond anything training draws
    assert max(d["g_torso"] for d in test) > max(d["g_torso"] for d in train) + 0.1
    assert max(d["r_thigh"] for d in test) > max(d["r_thigh"] for d in train)


def test_radii_include_clothing_and_scale_with_height():
    s = sample_subject(np.random.default_rng(0), "train")
    r = subjects.joint_radii(s)
    s2 = dict(s, height=2 * s["height"])
    assert subjects.joint_radii(s2)["knee"] == pytest.approx(2 * r["knee"])
    s3 = dict(s, trouser_width=0.03, hair_volume=0.02)
    r3 = subjects.joint_radii(s3)
    assert r3["knee"] == pytest.approx(r["knee"] + 0.03) and r3["toe"] == r["toe"]
    assert r3["head"] == pytest.approx(r["head"] + 0.02)


def test_bad_split():
    with pytest.raises(ValueError, match="split"):
        sample_subject(np.random.default_rng(0), "validation")
