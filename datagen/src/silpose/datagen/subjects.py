"""Randomised subjects (body proportions, girths, clothing, hair) for the generator. Pure numpy.

A *subject* is a flat ``dict[str, float]`` with the keys of :data:`SUBJECT_FIELDS`, in that
order, for both splits (docs/conventions.md, "Evaluation protocol": test characters differ from
training ones):

- ``height``: stature in metres (floor to head top, standing straight).
- ``r_*``: segment lengths as fractions of the stature. The vertical chain
  ``r_ankle + r_shank + r_thigh + r_torso_lower + r_torso_upper + r_neck + r_head`` is
  rescaled to sum to exactly 1, so ``height`` is the stature. Nominal values are Winter's
  anthropometric fractions (D. A. Winter, *Biomechanics and Motor Control of Human Movement*,
  fig. 4.1): ankle height 0.039, knee 0.285, hip 0.530, shoulder 0.818, chin 0.870,
  upper arm 0.186, forearm 0.146, foot 0.152, shoulder width 0.259, hip width 0.191.
- ``g_*``: girth multipliers (torso, limbs) and head size multiplier, 1 = nominal radii of
  :data:`NOMINAL_RADII` (metres, for a 1.75 m person; radii scale with the stature).
- Clothing and hair (0 = absent; lengths in metres unless said otherwise):
  ``skirt_length`` (fraction of the thigh + shank covered by a skirt, dress or coat),
  ``skirt_flare`` (hem radius), ``trouser_width`` (extra leg radius at the hip),
  ``hair_volume`` (extra head radius), ``hair_length`` (hair falling behind the head),
  ``skirt_top`` (where the garment hangs from: 0 = the hips (skirt, dress), 1 = the mid-torso
  (coat)), ``skirt_curve`` (radius added half-way down the garment to the straight cone from
  its top to its hem: > 0 bell, < 0 tulip, 0 straight cone), ``trouser_flare`` (extra leg radius
  at the ankle beyond ``trouser_width``: > 0 flared, < 0 tapered, 0 straight), ``jacket_bulk``
  (extra torso and upper-arm radius of a bulky jacket), ``hair_back`` (how far behind the head
  the hair falls, as a fraction of the head radius; 0 when there is no hair).

Distributions (:func:`describe_distribution` returns them as data, and :func:`compare_splits` the
side-by-side comparison, for the dataset card): every continuous field is uniform on a range
(``low``, ``high``). Both splits dress their walkers (skirt/dress/coat, trousers, hair with the
probabilities of :data:`CLOTHING_PROB`), and the training proportions cover the test's ranges.
The test characters still differ from every training character (the paper's "different
clothing, hair and body proportions", :data:`SPLIT_DIFFERENCES`):

- garment shapes: test skirts are straight cones from the hips, test trousers straight and test
  hair falls 0.6 head radii behind the head; training skirts/dresses are bell- or tulip-shaped or
  hang from the mid-torso (coats), training trousers flare or taper, training hair falls nearer
  or further behind, and training walkers may wear bulky jackets (test walkers never do);
- combinations: every training walker wears at least one item (a walker without skirt, wide
  trousers, jacket or hair is redressed with hair); 12 % of test walkers wear none;
- proportions: the test walkers' thighs are long and lower torsos short (the corner of the
  training ranges).

The draw is a pure function of the generator passed in; the test split's draws are exactly
those of the first version of this module (same calls in the same order), so test datasets are
unchanged.
"""

from __future__ import annotations

import numpy as np

from silpose.shared.skeleton import JOINT_NAMES

SPLITS = ("train", "test")

#: Vertical chain ratio keys (rescaled to sum to 1).
VERTICAL_RATIOS = ("r_ankle", "r_shank", "r_thigh", "r_torso_lower", "r_torso_upper", "r_neck", "r_head")

SUBJECT_FIELDS: tuple[str, ...] = (
    "height",
    "r_ankle",
    "r_shank",
    "r_thigh",
    "r_torso_lower",
    "r_torso_upper",
    "r_neck",
    "r_head",
    "r_upper_arm",
    "r_forearm",
    "r_foot",
    "r_shoulder_width",
    "r_hip_width",
    "g_torso",
    "g_limbs",
    "g_head",
    "skirt_length",
    "skirt_flare",
    "trouser_width",
    "hair_volume",
    "hair_length",
    "skirt_top",
    "skirt_curve",
    "trouser_flare",
    "jacket_bulk",
    "hair_back",
)

#: Nominal fractions of the stature (Winter), before the vertical chain is rescaled.
NOMINAL_RATIOS = {
    "r_ankle": 0.039,
    "r_shank": 0.246,  # knee 0.285 - ankle 0.039
    "r_thigh": 0.245,  # hip 0.530 - knee 0.285
    "r_torso_lower": 0.144,  # hip 0.530 -> mid-torso
    "r_torso_upper": 0.144,  # mid-torso -> shoulder line 0.818
    "r_neck": 0.062,  # shoulder line -> skull base (~0.88)
    "r_head": 0.120,  # skull base -> head top (1.0)
    "r_upper_arm": 0.186,
    "r_forearm": 0.146,
    "r_foot": 0.152,
    "r_shoulder_width": 0.259,
    "r_hip_width": 0.191,
}

#: Skin radii (metres) at each joint for a 1.75 m person with all girth multipliers at 1.
NOMINAL_RADII = {
    "pelvis": 0.135,
    "spine": 0.125,
    "neck": 0.075,
    "head": 0.085,
    "head_top": 0.075,
    "shoulder": 0.06,
    "elbow": 0.045,
    "wrist": 0.04,
    "hip": 0.085,
    "knee": 0.058,
    "ankle": 0.042,
    "toe": 0.035,
}
NOMINAL_HEIGHT = 1.75

#: Share of a jacket's bulk added to each joint type's radius (sleeves thinner than the body).
JACKET_SHARE = {"spine": 1.0, "pelvis": 0.5, "neck": 0.3, "shoulder": 1.0, "elbow": 0.6}

#: Hair of the test split falls this many head radii behind the head.
TEST_HAIR_BACK = 0.6

# Test: other characters. Wider stature and girth ranges than the first training split, longer
# legs / shorter lower torso, bigger heads possible, plus clothing and hair.
_TEST_RANGES: dict[str, tuple[float, float]] = {
    "height": (1.50, 1.98),
    **{k: (v * 0.92, v * 1.08) for k, v in NOMINAL_RATIOS.items()},
    "r_thigh": (NOMINAL_RATIOS["r_thigh"] * 0.98, NOMINAL_RATIOS["r_thigh"] * 1.12),
    "r_torso_lower": (NOMINAL_RATIOS["r_torso_lower"] * 0.85, NOMINAL_RATIOS["r_torso_lower"] * 1.0),
    "g_torso": (0.80, 1.35),
    "g_limbs": (0.80, 1.30),
    "g_head": (0.95, 1.15),
}

# Training: covers every test range (issue 12: proportions wide enough for the test's range);
# the test concentrates in its long-thigh, short-lower-torso corner.
_TRAIN_RANGES: dict[str, tuple[float, float]] = {
    "height": (1.48, 2.00),
    **{k: (v * 0.92, v * 1.08) for k, v in NOMINAL_RATIOS.items()},
    "r_thigh": (NOMINAL_RATIOS["r_thigh"] * 0.92, NOMINAL_RATIOS["r_thigh"] * 1.14),
    "r_torso_lower": (NOMINAL_RATIOS["r_torso_lower"] * 0.83, NOMINAL_RATIOS["r_torso_lower"] * 1.08),
    "g_torso": (0.78, 1.38),
    "g_limbs": (0.78, 1.33),
    "g_head": (0.90, 1.18),
}

#: Probability of each item in either split (the same, so the training walkers are as dressed
#: as the test's); the jacket is a training-only item.
CLOTHING_PROB = {"skirt": 0.4, "trousers": 0.5, "hair": 0.6, "jacket": 0.3, "coat_given_skirt": 0.35}
#: Kept for callers of the first version: the test split's item probabilities.
TEST_CLOTHING_PROB = {k: CLOTHING_PROB[k] for k in ("skirt", "trousers", "hair")}

_TEST_SHAPE_RANGES = {
    "skirt_length": (0.25, 0.75),
    "skirt_flare": (0.17, 0.30),
    "trouser_width": (0.015, 0.04),
    "hair_volume": (0.01, 0.035),
    "hair_length": (0.08, 0.25),
}
# Training items: ranges covering the test's, and shape parameters the test never has.
_TRAIN_SHAPE_RANGES = {
    "skirt_length": (0.15, 0.85),
    "skirt_flare": (0.12, 0.34),
    "trouser_width": (0.008, 0.05),
    "hair_volume": (0.005, 0.045),
    "hair_length": (0.05, 0.30),
    "skirt_curve": (0.01, 0.045),  # magnitude; the sign (bell / tulip) is drawn
    "trouser_flare": (0.006, 0.03),  # magnitude; the sign (flared / tapered) is drawn
    "jacket_bulk": (0.015, 0.06),
    "hair_back": (0.15, 0.4),  # distance from TEST_HAIR_BACK; nearer or further is drawn
}

#: The documented train/test differences (dataset card).
SPLIT_DIFFERENCES = (
    "garment shapes: test skirts are straight cones from the hips (skirt_curve = 0, skirt_top = 0); every "
    "training skirt or dress is bell- or tulip-shaped (|skirt_curve| >= 0.01 m) and 35 % of them are coats "
    "hanging from the mid-torso (skirt_top = 1)",
    "garment shapes: test trousers are straight (trouser_flare = 0); training trousers flare or taper "
    "(|trouser_flare| >= 0.006 m)",
    "hair shapes: test hair falls 0.6 head radii behind the head; training hair 0.2-0.45 or 0.75-1.0",
    "items: bulky jackets (jacket_bulk > 0) only in training",
    "combinations: every training walker wears at least one item (redressed with hair otherwise); "
    "test walkers may wear nothing",
    "proportions: training ranges cover the test's; test thighs are long (r_thigh x0.98-1.12 of nominal) "
    "and lower torsos short (r_torso_lower x0.85-1.0), a corner of the training ranges",
)


def _check_split(split: str) -> None:
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")


def _draw_proportions(rng: np.random.Generator, ranges: dict) -> dict[str, float]:
    s = {k: 0.0 for k in SUBJECT_FIELDS}
    for key in SUBJECT_FIELDS:
        if key in ranges:
            lo, hi = ranges[key]
            s[key] = float(rng.uniform(lo, hi))
    total = sum(s[k] for k in VERTICAL_RATIOS)
    for k in VERTICAL_RATIOS:
        s[k] = s[k] / total
    return s


def _dress_test(rng: np.random.Generator, s: dict[str, float]) -> None:
    # The first version's draws, unchanged: 3 item variates, then one value per shape range.
    u = rng.uniform(size=3)
    shapes = {k: float(rng.uniform(*r)) for k, r in _TEST_SHAPE_RANGES.items()}
    if u[0] < CLOTHING_PROB["skirt"]:
        s["skirt_length"] = shapes["skirt_length"]
        s["skirt_flare"] = shapes["skirt_flare"]
    if u[1] < CLOTHING_PROB["trousers"]:
        s["trouser_width"] = shapes["trouser_width"]
    if u[2] < CLOTHING_PROB["hair"]:
        s["hair_volume"] = shapes["hair_volume"]
        s["hair_length"] = shapes["hair_length"]
        s["hair_back"] = TEST_HAIR_BACK


def _dress_train(rng: np.random.Generator, s: dict[str, float]) -> None:
    # A fixed number of draws whatever is worn: 5 item variates, 3 signs, one value per range.
    u = rng.uniform(size=5)
    sign = np.where(rng.uniform(size=3) < 0.5, -1.0, 1.0)
    v = {k: float(rng.uniform(*r)) for k, r in _TRAIN_SHAPE_RANGES.items()}
    skirt = u[0] < CLOTHING_PROB["skirt"]
    trousers = u[1] < CLOTHING_PROB["trousers"]
    hair = u[2] < CLOTHING_PROB["hair"]
    jacket = u[3] < CLOTHING_PROB["jacket"]
    if not (skirt or trousers or hair or jacket):
        hair = True  # combinations: nobody in training wears nothing
    if skirt:
        s["skirt_length"], s["skirt_flare"] = v["skirt_length"], v["skirt_flare"]
        s["skirt_top"] = 1.0 if u[4] < CLOTHING_PROB["coat_given_skirt"] else 0.0
        s["skirt_curve"] = float(sign[0] * v["skirt_curve"])
    if trousers:
        s["trouser_width"] = v["trouser_width"]
        s["trouser_flare"] = float(sign[1] * v["trouser_flare"])
    if hair:
        s["hair_volume"], s["hair_length"] = v["hair_volume"], v["hair_length"]
        s["hair_back"] = float(TEST_HAIR_BACK + sign[2] * v["hair_back"])
    if jacket:
        s["jacket_bulk"] = v["jacket_bulk"]


def sample_subject(rng: np.random.Generator, split: str) -> dict[str, float]:
    """Draw one subject.

    Args:
        rng: the sample's generator (the only source of randomness).
        split: ``"train"`` or ``"test"``.
    Returns:
        dict with the keys of :data:`SUBJECT_FIELDS` in that order (floats; lengths in metres,
        ratios as fractions of the stature, multipliers dimensionless).
    """
    _check_split(split)
    if split == "test":
        s = _draw_proportions(rng, _TEST_RANGES)
        _dress_test(rng, s)
    else:
        s = _draw_proportions(rng, _TRAIN_RANGES)
        _dress_train(rng, s)
    return s


def segment_lengths(subject: dict[str, float]) -> dict[str, float]:
    """Absolute segment lengths in metres: ``height * r_*`` for every ratio key (prefix dropped)."""
    h = float(subject["height"])
    return {k[2:]: h * float(subject[k]) for k in SUBJECT_FIELDS if k.startswith("r_")}


def joint_radii(subject: dict[str, float]) -> dict[str, float]:
    """Skin radius in metres per joint *type* (keys of :data:`NOMINAL_RADII`), clothing included.

    Radii scale with ``height / 1.75``; torso joints with ``g_torso``, limb joints with
    ``g_limbs``, head joints with ``g_head`` (+ ``hair_volume``); leg joints get the trousers
    (``trouser_width`` at the hip, ``+ trouser_flare / 2`` at the knee, ``+ trouser_flare`` at the
    ankle, never below the skin; not the toes, which stay shoes); torso and arm joints get
    ``jacket_bulk`` times :data:`JACKET_SHARE`.
    """
    k = float(subject["height"]) / NOMINAL_HEIGHT
    r = {}
    for name, nominal in NOMINAL_RADII.items():
        if name in ("pelvis", "spine", "neck"):
            g = subject["g_torso"]
        elif name in ("head", "head_top"):
            g = subject["g_head"]
        else:
            g = subject["g_limbs"]
        r[name] = nominal * k * float(g)
    r["head"] += float(subject["hair_volume"])
    r["head_top"] += float(subject["hair_volume"])
    width, flare = float(subject["trouser_width"]), float(subject["trouser_flare"])
    for name, frac in (("hip", 0.0), ("knee", 0.5), ("ankle", 1.0)):
        r[name] += max(0.0, width + frac * flare)
    bulk = float(subject["jacket_bulk"])
    if bulk:
        for name, share in JACKET_SHARE.items():
            r[name] += share * bulk
    return r


def joint_type(name: str) -> str:
    """The joint type of joint ``name`` (a key of :func:`joint_radii`): the name without ``l_``/``r_``."""
    return name[2:] if name[:2] in ("l_", "r_") else name


def joint_radius_array(subject: dict[str, float]) -> np.ndarray:
    """(19,) skin radius (metres) at every joint of ``subject``, ``JOINT_NAMES`` order (:func:`joint_radii`)."""
    radii = joint_radii(subject)
    return np.array([radii[joint_type(n)] for n in JOINT_NAMES])


def _item_fields(split: str) -> dict[str, dict]:
    """The documented distribution of the clothing and hair fields of ``split``."""
    if split == "test":
        out = {k: {"distribution": "uniform when worn, else 0", "low": lo, "high": hi}
               for k, (lo, hi) in _TEST_SHAPE_RANGES.items()}
        out["skirt_top"] = {"value": 0.0}
        out["skirt_curve"] = {"value": 0.0}
        out["trouser_flare"] = {"value": 0.0}
        out["jacket_bulk"] = {"value": 0.0}
        out["hair_back"] = {"distribution": f"{TEST_HAIR_BACK} with hair, else 0", "low": 0.0,
                            "high": TEST_HAIR_BACK}
        return out
    r = _TRAIN_SHAPE_RANGES
    out = {k: {"distribution": "uniform when worn, else 0", "low": r[k][0], "high": r[k][1]}
           for k in ("skirt_length", "skirt_flare", "trouser_width", "hair_volume", "hair_length", "jacket_bulk")}
    out["skirt_top"] = {"distribution": "1 for a coat (35 % of skirts), else 0", "low": 0.0, "high": 1.0}
    for k in ("skirt_curve", "trouser_flare"):
        out[k] = {"distribution": "± uniform when worn (sign 50/50), else 0", "low": -r[k][1], "high": r[k][1],
                  "magnitude": list(r[k])}
    lo, hi = r["hair_back"]
    out["hair_back"] = {"distribution": f"{TEST_HAIR_BACK} ± uniform({lo}, {hi}) with hair, else 0",
                        "low": 0.0, "high": TEST_HAIR_BACK + hi}
    return out


def describe_distribution(split: str) -> dict:
    """The documented distribution of :func:`sample_subject` for ``split``, as plain data.

    Returns:
        ``{"split", "fields": {key: {"distribution": .., "low": .., "high": ..} | {"value": 0.0}},
        "clothing_probability": {...}, "differences": [...] (train/test), "notes": [...]}``.
    """
    _check_split(split)
    ranges = _TRAIN_RANGES if split == "train" else _TEST_RANGES
    items = _item_fields(split)
    fields: dict[str, dict] = {}
    for key in SUBJECT_FIELDS:
        if key in ranges:
            lo, hi = ranges[key]
            fields[key] = {"distribution": "uniform", "low": round(lo, 6), "high": round(hi, 6)}
        else:
            fields[key] = items[key]
    probs = ({k: CLOTHING_PROB[k] for k in ("skirt", "trousers", "hair")} if split == "test"
             else dict(CLOTHING_PROB))
    out = {
        "split": split,
        "fields": fields,
        "clothing_probability": probs,
        "differences": list(SPLIT_DIFFERENCES),
        "notes": [
            "r_* are fractions of the stature (Winter's anthropometric table); the vertical chain "
            f"{'+'.join(VERTICAL_RATIOS)} is rescaled to sum to 1 after drawing.",
            "g_* multiply the nominal skin radii (metres at 1.75 m stature): " + repr(NOMINAL_RADII),
            "items are drawn independently with clothing_probability"
            + ("; a training walker drawn with none gets hair" if split == "train" else ""),
        ],
    }
    return out
