"""The held-out part of a train split, kept out of ``silpose train``'s fit and scored.

A procedurally walked dataset draws every sample afresh (a new person, gait and heading), so a seeded
random split of the samples holds out unseen poses (``silpose.model.selection.validation_split``).
A dataset posed from motion-capture clips (``gait.clip`` > 0, docs/conventions.md, "Dataset format")
is different: frames of one clip a few frames apart are near-copies, so a random split scores
memorisation and picks models that memorise. There the held-out part takes whole clips
(``silpose.model.selection.validation_split_groups``); each procedural-walk sample (``clip`` 0) stays
a group of its own. Model selection (``silpose train --select``) carves its validation split the same
way from the fitted part.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.model.selection import validation_split, validation_split_groups
from silpose.shared.dataset import load_split


def clip_groups(root: str | Path, split: str = "train") -> np.ndarray | None:
    """(N,) int64 group of every row of ``split`` (row order of ``load_split``): the clip index for
    motion-capture rows, a distinct negative number for every procedural-walk row; None when no row
    poses a clip (a walk-only dataset, or one written before ``gait.clip`` existed)."""
    gait = load_split(root, split, columns=["gait"]).gait
    if "clip" not in gait:
        return None
    clip = np.rint(np.asarray(gait["clip"], dtype=np.float64)).astype(np.int64)
    if not np.any(clip > 0):
        return None
    return np.where(clip > 0, clip, -1 - np.arange(clip.size))


def heldout_split(n: int, fraction: float, seed: int, groups: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(fit indices, held-out indices) of ``n`` rows: whole groups held out when ``groups`` (N,) is given
    (:func:`clip_groups`), else a seeded random split of the rows."""
    if groups is None:
        return validation_split(n, fraction, seed)
    if len(groups) != n:
        raise ValueError(f"groups has {len(groups)} entries for {n} rows")
    return validation_split_groups(groups, fraction, seed)
