"""Train vs test characters side by side, for the dataset card (issue 12; docs/conventions.md,
"Evaluation protocol": test characters differ from training ones).

:func:`side_by_side` puts the documented subject distributions of both splits
(:func:`silpose.datagen.subjects.describe_distribution`) in one table with the documented
differences; :func:`measured_comparison` measures them on the generated subjects: the share of
walkers wearing each item, the share of test walkers whose character *kind* (garment shapes and
item combination, :func:`character_kind`) never occurs in training, and how far each test walker
is from its nearest training walker in the standardised subject space compared with how far
training walkers are from each other. Pure numpy.
"""

from __future__ import annotations

import numpy as np

from .subjects import SPLIT_DIFFERENCES, SUBJECT_FIELDS, TEST_HAIR_BACK, describe_distribution

#: The items a walker can wear, with the subject field that says it is worn (> 0).
ITEMS = {"skirt, dress or coat": "skirt_length", "coat (from the mid-torso)": "skirt_top", "wide trousers": "trouser_width",
         "hair": "hair_length", "bulky jacket": "jacket_bulk"}
_NN_CHUNK = 512


def _cell(spec: dict) -> str:
    if "value" in spec:
        return f"{spec['value']:g}"
    dist = spec.get("distribution", "")
    lo, hi = spec.get("low", ""), spec.get("high", "")
    rng = f"{lo:.4g} – {hi:.4g}" if isinstance(lo, float) and isinstance(hi, float) else f"{lo} – {hi}"
    return rng if dist == "uniform" else f"{rng} ({dist})"


def side_by_side() -> str:
    """Markdown: one row per subject field with the train and test distributions, item probabilities, and
    the documented differences."""
    tr, te = describe_distribution("train"), describe_distribution("test")
    lines = ["| field | train | test |", "|---|---|---|"]
    for key in SUBJECT_FIELDS:
        a, b = _cell(tr["fields"][key]), _cell(te["fields"][key])
        lines.append(f"| {key} | {a} | {b}{'' if a != b else ' (same)'} |")
    for item in sorted(set(tr["clothing_probability"]) | set(te["clothing_probability"])):
        lines.append(f"| probability: {item} | {tr['clothing_probability'].get(item, 0)} | "
                     f"{te['clothing_probability'].get(item, 0)} |")
    lines += ["", "How every test character differs from the training characters:", ""]
    lines += [f"- {d}" for d in SPLIT_DIFFERENCES]
    return "\n".join(lines) + "\n"


def character_kind(subject: dict[str, np.ndarray]) -> np.ndarray:
    """(N,) string: the garment shapes and item combination of each walker (columns of ``subject``).

    Skirt shape (straight cone / bell / tulip, from the hips or a coat), trouser shape (straight /
    flared / tapered), hair shape (the test's 0.6 head radii behind, nearer or further), jacket, or
    ``"nothing"``; joined with ``+``.
    """
    n = len(np.asarray(subject["height"]))
    out = []
    for i in range(n):
        v = {k: float(np.asarray(subject[k])[i]) for k in SUBJECT_FIELDS if k in subject}
        parts = []
        if v.get("skirt_length", 0) > 0:
            curve = v.get("skirt_curve", 0.0)
            shape = "straight" if curve == 0 else ("bell" if curve > 0 else "tulip")
            parts.append(f"{'coat' if v.get('skirt_top', 0) >= 0.5 else 'skirt'}:{shape}")
        if v.get("trouser_width", 0) > 0:
            flare = v.get("trouser_flare", 0.0)
            parts.append("trousers:" + ("straight" if flare == 0 else ("flared" if flare > 0 else "tapered")))
        if v.get("hair_length", 0) > 0:
            back = v.get("hair_back", TEST_HAIR_BACK)
            parts.append("hair:" + ("0.6" if np.isclose(back, TEST_HAIR_BACK) else ("near" if back < TEST_HAIR_BACK else "far")))
        if v.get("jacket_bulk", 0) > 0:
            parts.append("jacket")
        out.append("+".join(parts) or "nothing")
    return np.array(out, dtype=object)


def _standardised(subject: dict[str, np.ndarray], keys: list[str]) -> np.ndarray:
    """(N, F) subject fields divided by the width of the training split's documented range."""
    fields = describe_distribution("train")["fields"]
    cols = []
    for k in keys:
        spec = fields[k]
        width = float(spec.get("high", 0) - spec.get("low", 0)) if "value" not in spec else 0.0
        cols.append(np.asarray(subject[k], dtype=np.float64) / (width if width > 0 else 1.0))
    return np.stack(cols, axis=1)


def nearest_distances(query: np.ndarray, reference: np.ndarray, exclude_self: bool = False) -> np.ndarray:
    """(Nq,) Euclidean distance of each row of ``query`` (Nq, F) to its nearest row of ``reference``
    (Nr, F); ``exclude_self``: query is reference and a row's own distance is skipped."""
    ref_sq = np.einsum("ij,ij->i", reference, reference)
    out = np.empty(len(query))
    for start in range(0, len(query), _NN_CHUNK):
        q = query[start:start + _NN_CHUNK]
        d2 = np.einsum("ij,ij->i", q, q)[:, None] - 2.0 * q @ reference.T + ref_sq[None, :]
        if exclude_self:
            d2[np.arange(len(q)), start + np.arange(len(q))] = np.inf
        out[start:start + len(q)] = np.sqrt(np.maximum(d2.min(axis=1), 0.0))
    return out


def measured_comparison(train: dict[str, np.ndarray], test: dict[str, np.ndarray]) -> str:
    """Markdown: measured item shares, character kinds and nearest-training-character distances.

    ``train``/``test`` are the splits' ``subject`` columns (field -> (N,) array).
    """
    rows = ["| measured | train | test |", "|---|---|---|"]
    for label, key in ITEMS.items():
        if key in train and key in test:
            rows.append(f"| wears {label} | {100 * np.mean(np.asarray(train[key]) > 0):.1f} % | "
                        f"{100 * np.mean(np.asarray(test[key]) > 0):.1f} % |")
    kt, ks = character_kind(train), character_kind(test)
    unseen = ~np.isin(ks, np.unique(kt))
    rows.append(f"| character kinds (garment shapes + combination) | {len(np.unique(kt))} | {len(np.unique(ks))} |")
    rows.append(f"| test walkers whose kind no training walker has | – | {100 * unseen.mean():.1f} % |")
    keys = [k for k in SUBJECT_FIELDS if k in train and k in test]
    a, b = _standardised(train, keys), _standardised(test, keys)
    d_train = nearest_distances(a, a, exclude_self=True)
    d_test = nearest_distances(b, a)
    rows.append(f"| distance to the nearest training walker (median, standardised) | {np.median(d_train):.3f} "
                f"(to another training walker) | {np.median(d_test):.3f} |")
    rows.append(f"| share farther than the training walkers' median | 50 % | "
                f"{100 * np.mean(d_test > np.median(d_train)):.1f} % |")
    note = ("\nKinds: `skirt:straight` is a straight cone from the hips, `bell`/`tulip` a curved profile, `coat:` "
            "one hanging from the mid-torso; trousers `straight`/`flared`/`tapered`; hair `0.6` head radii behind "
            "the head (the test's), `near`/`far` otherwise. Distances: every subject field divided by the width of "
            "its documented training range, Euclidean.")
    return "\n".join(rows) + "\n" + note + "\n"
