"""A dataset split as ``silpose infer`` input: its contours, every view present."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from silpose.shared.dataset import list_shards, load_split

from ..errors import InferenceInputError


def is_dataset(folder: Path) -> bool:
    """True when ``folder`` holds Parquet shards (a dataset folder, not a PNG folder)."""
    return any(Path(folder).glob("*.parquet"))


def read_dataset_input(model, folder: Path, split: str):
    """The contours of a dataset split, checked against the model's rig.

    Returns (frame names (N,) ``<split>-<sample id>``, contours (N, K_rig, n, 2) px,
    views_present (N, K_rig) all True, sample ids (N,)).
    """
    if not list_shards(folder, split):
        raise InferenceInputError(f"{folder}: no shards of split {split!r} (files {split}-*-of-*.parquet)")
    data = load_split(folder, split, columns=["contours"])
    if data.contours.shape[1] != model.n_rig_views_:
        raise InferenceInputError(
            f"{folder}: the dataset has {data.contours.shape[1]} views, the model's rig has {model.n_rig_views_}"
        )
    if model.rig_ is not None and tuple(data.rig.names) != tuple(model.rig_.names):
        raise InferenceInputError(
            f"{folder}: camera names {list(data.rig.names)} differ from the model's rig {list(model.rig_.names)}"
        )
    frames = np.array([f"{split}-{int(i):06d}" for i in data.sample_id])
    return frames, data.contours, np.ones(data.contours.shape[:2], dtype=bool), data.sample_id
