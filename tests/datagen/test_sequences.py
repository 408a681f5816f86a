"""Test samples played on as sequences (silpose.datagen.sequences): the sequence passes through the dataset's own
sample, frame for frame as the generator rendered it, and moves on through the clip (or the walk cycle)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from silpose.datagen.lab import CYCLE_S
from silpose.datagen.motion.library import load_library
from silpose.datagen.sequences import (WALK_FPS, SequenceError, dataset_worker_config, render_sequences_spawned,
                                       sequence_frames)
from silpose.shared.dataset import list_shards, load_split, read_metadata


def test_sequence_frames_hold_the_frame_and_stay_inside_the_clip():
    used = np.arange(10, 40, 4)  # 8 library frames: 10, 14, ..., 38
    assert sequence_frames(used, 14, 3) == [14, 18, 22]
    assert sequence_frames(used, 34, 4) == [26, 30, 34, 38]  # the clip ends first: the window moves back
    assert sequence_frames(used, 22, 20) == list(used)  # a clip shorter than the window: all of it
    with pytest.raises(ValueError, match="frame 15"):
        sequence_frames(used, 15, 3)


def _config_and_test(dataset):
    config = read_metadata(list_shards(dataset, "test")[0])["config"]
    test = load_split(dataset, "test", columns=["gait", "redraws", "joints", "contours"])
    return config, test


def test_a_library_sequence_passes_through_the_dataset_sample_and_plays_its_clip(library_dataset):
    config, test = _config_and_test(library_dataset)
    worker = dataset_worker_config(config, test.rig, "t")
    lib = load_library(config["motion"]["library"]["path"])
    picks = [0, 1, 2]
    requests = [(int(test.sample_id[i]), int(test.extra["redraws"][i])) for i in picks]
    for i, records in zip(picks, render_sequences_spawned(worker, "test", requests, 5, workers=2)):
        frames = [int(r["gait"]["frame"]) for r in records]
        clip = config["motion"]["clips"][int(test.gait["clip"][i])]
        used = lib.frame[lib.rows([c["id"] for c in lib.clips].index(clip["id"]))]
        assert frames == sequence_frames(used, int(test.gait["frame"][i]), 5)  # consecutive library frames
        own = frames.index(int(test.gait["frame"][i]))
        r = records[own]
        assert r["visible"] and r["sample_id"] == int(test.sample_id[i])
        # the generator's own sample, to the bit: same body, clip frame, heading, place and renderer
        np.testing.assert_array_equal(r["joints"], test.joints[i])
        np.testing.assert_array_equal(r["contours"], test.contours[i])
        other = records[(own + 1) % len(records)]
        assert other["visible"] and not np.array_equal(other["joints"], r["joints"])  # the person moves on
        assert {k: v for k, v in other["gait"].items() if k != "frame"} == {k: v for k, v in r["gait"].items()
                                                                             if k != "frame"}


def test_a_walk_sequence_advances_the_phase_at_the_lab_cycle(tmp_path):
    from silpose.datagen.config import load_config
    from silpose.datagen.pipeline import generate

    (tmp_path / "w.toml").write_text('name = "walk-small"\nseed = 2\nrenderer = "raster"\nshard_size = 4\n'
                                     'n_points = 50\nmax_redraws = 50\n[splits]\ntest = 2\n')
    generate(load_config(tmp_path / "w.toml"), tmp_path / "ds", workers=1, progress=False)
    config, test = _config_and_test(tmp_path / "ds")
    assert "motion" not in config
    worker = dataset_worker_config(config, test.rig)
    [records] = render_sequences_spawned(worker, "test", [(int(test.sample_id[0]), int(test.extra["redraws"][0]))], 3)
    np.testing.assert_array_equal(records[0]["contours"], test.contours[0])
    phases = [r["gait"]["phase"] for r in records]
    np.testing.assert_allclose(np.diff(phases) % 1.0, 1.0 / (WALK_FPS * CYCLE_S), atol=1e-6)


def test_worker_config_refuses_bvh_datasets_and_changed_libraries(library_dataset, tmp_path):
    config, test = _config_and_test(library_dataset)
    with pytest.raises(SequenceError, match="motion.source"):
        dataset_worker_config(dict(config, motion={"source": "bvh"}), test.rig, "m.json")
    changed = json.loads(json.dumps(config))
    changed["motion"]["library"]["frames_sha256"] = "0" * 64
    with pytest.raises(SequenceError, match="m.json: field 'motion.library.frames_sha256'"):
        dataset_worker_config(changed, test.rig, "m.json")
    gone = json.loads(json.dumps(config))
    gone["motion"]["clips"][1]["id"] = "no_such_clip"
    with pytest.raises(SequenceError, match="no_such_clip"):
        dataset_worker_config(gone, test.rig, "m.json")
