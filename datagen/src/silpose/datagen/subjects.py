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
- Test-only shapes (always 0 in the training split): ``skirt_length`` (fraction of the thigh +
  shank covered by a skirt or coat flaring from the hips), ``skirt_flare`` (hem radius, metres),
  ``trouser_width`` (extra leg radius, metres), ``hair_volume`` (extra head radius, metres),
  ``hair_length`` (length of hair falling behind the head, metres).

Distributions (:func:`describe_distribution` returns them as data for the dataset card):
every field is uniform on a range (``low``, ``high``); the test split widens the stature and
girth ranges, shifts the leg/torso balance, and adds clothing and hair with the probabilities
in :data:`TEST_CLOTHING_PROB`. The draw is a pure function of the generator passed in.
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

_TRAIN_RANGES: dict[str, tuple[float, float]] = {
    "height": (1.55, 1.90),
    **{k: (v * 0.95, v * 1.05) for k, v in NOMINAL_RATIOS.items()},
    "g_torso": (0.85, 1.15),
    "g_limbs": (0.85, 1.15),
    "g_head": (0.92, 1.08),
}

# Test: other characters. Wider stature and girth ranges, longer legs / shorter torso balance
# shifted, bigger heads possible, plus clothing and hair the training split never has.
_TEST_RANGES: dict[str, tuple[float, float]] = {
    "height": (1.50, 1.98),
    **{k: (v * 0.92, v * 1.08) for k, v in NOMINAL_RATIOS.items()},
    "r_thigh": (NOMINAL_RATIOS["r_thigh"] * 0.98, NOMINAL_RATIOS["r_thigh"] * 1.12),
    "r_torso_lower": (NOMINAL_RATIOS["r_torso_lower"] * 0.85, NOMINAL_RATIOS["r_torso_lower"] * 1.0),
    "g_torso": (0.80, 1.35),
    "g_limbs": (0.80, 1.30),
    "g_head": (0.95, 1.15),
}

#: Probability of each test-only shape in the test split, and its range when present.
TEST_CLOTHING_PROB = {"skirt": 0.4, "trousers": 0.5, "hair": 0.6}
_TEST_SHAPE_RANGES = {
    "skirt_length": (0.25, 0.75),
    "skirt_flare": (0.17, 0.30),
    "trouser_width": (0.015, 0.04),
    "hair_volume": (0.01, 0.035),
    "hair_length": (0.08, 0.25),
}


def _check_split(split: str) -> None:
    if split not in SPLITS:
        raise ValueError(f"split must be one of {SPLITS}, got {split!r}")


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
    ranges = _TRAIN_RANGES if split == "train" else _TEST_RANGES
    s = {k: 0.0 for k in SUBJECT_FIELDS}
    for key in SUBJECT_FIELDS:
        if key in ranges:
            lo, hi = ranges[key]
            s[key] = float(rng.uniform(lo, hi))
    total = sum(s[k] for k in VERTICAL_RATIOS)
    for k in VERTICAL_RATIOS:
        s[k] = s[k] / total
    # Always draw the clothing variates (fixed number of draws whatever the split) so the
    # stream is simple; only the test split uses them.
    u = rng.uniform(size=3)
    shapes = {k: float(rng.uniform(*r)) for k, r in _TEST_SHAPE_RANGES.items()}
    if split == "test":
        if u[0] < TEST_CLOTHING_PROB["skirt"]:
            s["skirt_length"] = shapes["skirt_length"]
            s["skirt_flare"] = shapes["skirt_flare"]
        if u[1] < TEST_CLOTHING_PROB["trousers"]:
            s["trouser_width"] = shapes["trouser_width"]
        if u[2] < TEST_CLOTHING_PROB["hair"]:
            s["hair_volume"] = shapes["hair_volume"]
            s["hair_length"] = shapes["hair_length"]
    return s


def segment_lengths(subject: dict[str, float]) -> dict[str, float]:
    """Absolute segment lengths in metres: ``height * r_*`` for every ratio key (prefix dropped)."""
    h = float(subject["height"])
    return {k[2:]: h * float(subject[k]) for k in SUBJECT_FIELDS if k.startswith("r_")}


def joint_radii(subject: dict[str, float]) -> dict[str, float]:
    """Skin radius in metres per joint *type* (keys of :data:`NOMINAL_RADII`), clothing included.

    Radii scale with ``height / 1.75``; torso joints with ``g_torso``, limb joints with
    ``g_limbs``, head joints with ``g_head`` (+ ``hair_volume``); leg joints get
    ``trouser_width`` added (not the toes, which stay shoes).
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
    for name in ("hip", "knee", "ankle"):
        r[name] += float(subject["trouser_width"])
    return r


def joint_type(name: str) -> str:
    """The joint type of joint ``name`` (a key of :func:`joint_radii`): the name without ``l_``/``r_``."""
    return name[2:] if name[:2] in ("l_", "r_") else name


def joint_radius_array(subject: dict[str, float]) -> np.ndarray:
    """(19,) skin radius (metres) at every joint of ``subject``, ``JOINT_NAMES`` order (:func:`joint_radii`)."""
    radii = joint_radii(subject)
    return np.array([radii[joint_type(n)] for n in JOINT_NAMES])


def describe_distribution(split: str) -> dict:
    """The documented distribution of :func:`sample_subject` for ``split``, as plain data.

    Returns:
        ``{"fields": {key: {"distribution": "uniform", "low": .., "high": ..} | {"value": 0.0}},
        "clothing_probability": {...} (test only), "notes": [...]}``.
    """
    _check_split(split)
    ranges = _TRAIN_RANGES if split == "train" else _TEST_RANGES
    fields: dict[str, dict] = {}
    for key in SUBJECT_FIELDS:
        if key in ranges:
            lo, hi = ranges[key]
            fields[key] = {"distribution": "uniform", "low": round(lo, 6), "high": round(hi, 6)}
        elif split == "test":
            lo, hi = _TEST_SHAPE_RANGES[key]
            fields[key] = {"distribution": "uniform when present, else 0", "low": lo, "high": hi}
        else:
            fields[key] = {"value": 0.0}
    out = {
        "split": split,
        "fields": fields,
        "notes": [
            "r_* are fractions of the stature (Winter's anthropometric table); the vertical chain "
            f"{'+'.join(VERTICAL_RATIOS)} is rescaled to sum to 1 after drawing.",
            "g_* multiply the nominal skin radii (metres at 1.75 m stature): " + repr(NOMINAL_RADII),
        ],
    }
    if split == "test":
        out["clothing_probability"] = dict(TEST_CLOTHING_PROB)
        out["notes"].append(
            "test characters: wider stature/girth ranges, longer thighs and shorter lower torso, "
            "plus skirts/coats flaring from the hips, wider trousers and hair that training never has"
        )
    return out
