"""Seed derivation: the one home of every random stream in silpose.

Every random draw in silpose comes from :func:`derive_rng`, a numpy ``Generator`` seeded by a
``SeedSequence`` of integer keys. A sample's draws are therefore a pure function of
``(dataset_seed, what, which)`` and never depend on the worker count, the executor, the shard size
or retries (docs/conventions.md, "Seeds"). The keys of each stream are listed here; the constants
below are part of the data format (changing one changes every dataset or report that uses it).

| stream | keys passed to :func:`derive_rng` | used by |
|---|---|---|
| sample draw | ``seed, SPLIT_CODE[split], index, redraw`` | datagen: subject, gait, placement of a sample; ``redraw`` counts rejected draws |
| motion-capture draw | ``MOTION_STREAM, seed, SPLIT_CODE[split], index, redraw`` | datagen (``bvh_motion.BvhMotion``): clip, frame, mirror, heading and floor position of a sample posed from BVH clips (its subject still comes from the sample draw) |
| appearance | ``APPEARANCE_STREAM, seed, SPLIT_CODE["test"], index`` | datagen frames: clothing colours of a test sample (the room layout is a fixed function of the rig) |
| camera noise | ``CAMERA_NOISE_STREAM, seed, NOISE_KIND[kind], camera, index`` | ``camera_noise.noise_rng``: sensor noise and flicker of datagen's rendered frames |
| synthetic stand-in | ``seed, SPLIT_CODE[split], index`` (9 for another split name) | datagen.testing stick-figure records (tests only; three keys, never a sample-draw stream) |
| eval noise | ``seed, stream_code(name), sample_id`` | eval (``noise.sample_rng``): contour / mask noise of one test sample, one stream per family, ``name`` in ``"mask"``, ``"patches"``, ``"jitter"`` |
| training roughness | ``seed, stream_code("roughness"), sample`` | model (``augment.roughen_contours``): ragged-outline augmentation of training sample ``sample`` (``silpose train --roughness``) |
| eval garbage | ``seed, stream_code("garbage"), kind`` | eval (``garbage.garbage_masks``): the non-person inputs of the plausibility check, ``kind`` the index in ``GARBAGE_KINDS`` |
| chance baseline | ``random_state, CHANCE_STREAM`` | eval (``baselines.ChanceBaseline``): random training poses |
| baseline rows | ``seed, BASELINE_ROWS_STREAM`` | eval (``experiments.Evaluation.baseline_rows``, through :func:`draw_subset`): the training samples the ridge and MLP baselines see when the training split has more than ``EvalConfig.baseline_rows`` |
| plausibility calibration | ``seed, stream_code("plausibility")`` | ``silpose.model.plausibility``: the observation-noise draws added to held-out inputs when ``silpose train`` calibrates a model's plausibility percentiles |
| validation split | ``seed, VALIDATION_STREAM`` | ``silpose.model.selection.validation_split``: the train / validation permutation of model selection and the held-out part of ``silpose train`` |
| synthetic model | ``seed, 0`` (parameters) and ``seed, 1`` (samples) | model.synthetic test data |
| lab stature | ``seed, stream_code("lab stature"), index`` | datagen (``lab.walker_stature``): the stature of the synthetic lab recording's walker of test sample ``index`` |
| synthetic scene | ``seed, camera`` (room), ``seed, camera, 0, b`` (background frame b), ``seed, camera, 1 + frame`` (frame) | segment.composite test scenes |

Estimators that take a ``random_state`` (``MPPCA``, k-means) follow scikit-learn and call
``numpy.random.default_rng(random_state)`` themselves.
"""

from __future__ import annotations

import zlib

import numpy as np

__all__ = [
    "SPLIT_CODE",
    "APPEARANCE_STREAM",
    "MOTION_STREAM",
    "CAMERA_NOISE_STREAM",
    "NOISE_KIND",
    "CHANCE_STREAM",
    "VALIDATION_STREAM",
    "BASELINE_AUGMENT_STREAM",
    "BASELINE_ROWS_STREAM",
    "derive_rng",
    "draw_subset",
    "stream_code",
]

#: dataset split -> key of the sample-draw stream.
SPLIT_CODE = {"train": 0, "test": 1}
#: first key of the frames appearance stream (clothing colours, room props).
APPEARANCE_STREAM = 0x5EED_C010
#: first key of the motion-capture draw (clip, frame, mirror, placement) of a BVH-driven sample.
MOTION_STREAM = 0x5EED_0B7C
#: first key of the camera-noise stream.
CAMERA_NOISE_STREAM = 0x0015_E0C4
#: kind of camera-noise frame -> key.
NOISE_KIND = {"background": 0, "frames": 1}
#: last key of the chance baseline's draw of random training poses.
CHANCE_STREAM = 29
#: last key of the train / validation permutation of model selection.
VALIDATION_STREAM = 7919
#: first key of the eval's MLP-baseline training augmentation (noise seeds, view subsets).
BASELINE_AUGMENT_STREAM = 0x5EED_3A1F
#: last key of the eval's draw of the training samples the capped baselines see.
BASELINE_ROWS_STREAM = 0x5EED_CA9


def derive_rng(*keys: int) -> np.random.Generator:
    """A generator seeded by ``SeedSequence([k0, k1, ...])`` of the integer ``keys``.

    Args:
        keys: non-negative integers (numpy integers and bools are converted with ``int``).
    Returns:
        a fresh ``numpy.random.Generator`` (PCG64); the same keys always give the same draws.
    """
    if not keys:
        raise ValueError("derive_rng needs at least one key")
    ints = [int(k) for k in keys]
    if any(k < 0 for k in ints):
        raise ValueError(f"seed keys must be non-negative integers, got {ints}")
    return np.random.default_rng(np.random.SeedSequence(ints))


def draw_subset(n: int, limit: int | None, *keys: int) -> np.ndarray:
    """Sorted row indices (m,) int: all of ``range(n)`` when ``limit`` is None or >= n, else ``limit`` of them
    drawn uniformly without replacement from ``derive_rng(*keys)`` (the same keys, the same rows)."""
    n = int(n)
    if limit is None or int(limit) >= n:
        return np.arange(n)
    if int(limit) < 1:
        raise ValueError(f"draw_subset: limit must be >= 1 or None, got {limit}")
    return np.sort(derive_rng(*keys).choice(n, size=int(limit), replace=False))


def stream_code(name: str) -> int:
    """A stable integer key for a named stream: CRC-32 of its UTF-8 name."""
    return zlib.crc32(name.encode("utf-8"))
