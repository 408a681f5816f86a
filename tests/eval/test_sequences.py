"""E7, recordings (silpose.eval.sequences): held-out clips played as sequences and scored three ways; the figures
are recomputed here through the app's own recording path (``apply_temporal`` on each sequence alone)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from silpose.app.inference import apply_temporal
from silpose.app.training import fit_dataset
from silpose.eval.experiments import EvalConfig
from silpose.eval.noise import apply_noise
from silpose.eval.sequences import (HYPOTHESES, SEQUENCE_NOISE_OFFSET, pick_sequences, render_dataset_sequences,
                                    score_sequences, sequence_experiment)
from silpose.model.hypotheses import single_answer
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.contours import normalise
from silpose.shared.dataset import load_split
from silpose.shared.metrics import pose_error_cm


def test_pick_sequences_takes_the_first_samples_of_every_clip():
    ids = np.array([7, 3, 9, 4, 5, 8])
    clips = np.array([2, 2, 1, 2, 0, 1])
    got = pick_sequences(ids, clips, 2)
    assert [(int(clips[i]), int(ids[i])) for i in got] == [(0, 5), (1, 8), (1, 9), (2, 3), (2, 4)]
    assert len(pick_sequences(ids, clips, 1)) == 3
    # a limit keeps every clip's first sample before any clip's second, in the same order
    assert [(int(clips[i]), int(ids[i])) for i in pick_sequences(ids, clips, 2, limit=4)] == [(0, 5), (1, 8), (1, 9),
                                                                                              (2, 3)]
    assert [(int(clips[i]), int(ids[i])) for i in pick_sequences(ids, clips, 2, limit=2)] == [(0, 5), (1, 8)]
    assert pick_sequences(ids, clips, 2, limit=10) == got and pick_sequences(ids, clips, 2, limit=0) == []


@pytest.fixture(scope="module")
def scored(library_dataset):
    train = load_split(library_dataset, "train")
    model = fit_dataset(ShapeStructureModel(n_components=3, n_latent=4, n_init=1, max_iter=20, random_state=0), train)
    rendered = render_dataset_sequences(library_dataset, length=6, per_clip=1)
    cfg = EvalConfig()
    return model, rendered, cfg, score_sequences(model, rendered, cfg.noise, cfg.seed)


def test_the_figures_are_the_app_recording_path_on_each_sequence(scored, library_dataset):
    model, rendered, cfg, out = scored
    test = load_split(library_dataset, "test", columns=["gait"])
    assert out["n_sequences"] == len(set(np.asarray(test.gait["clip"]).tolist())) == len(rendered["records"])
    assert out["frames"] == sum(len(r) for r in rendered["records"])
    per_frame, temporal, best = [], [], []
    for s, records in enumerate(rendered["records"]):
        ok = [t for t, r in enumerate(records) if r["visible"] and not np.any(r["touches_border"])]
        clean = np.stack([records[t]["contours"] for t in ok]).astype(np.float64)
        truth = np.stack([records[t]["joints"] for t in ok]).astype(np.float64)
        noisy = apply_noise(cfg.noise, clean, SEQUENCE_NOISE_OFFSET + s * out["length"] + np.array(ok), cfg.seed)
        _, centroid, scale = normalise(clean)
        res = model.infer(noisy, centroid=centroid, scale=scale, robust=True, hypotheses=HYPOTHESES)
        per_frame += list(pose_error_cm(single_answer(res.joints, res.hypotheses), truth))
        best += list(pose_error_cm(res.hypotheses.joints[np.arange(len(ok)), res.hypotheses.best_of(truth)], truth))
        temporal += list(pose_error_cm(apply_temporal(res).joints, truth))  # what silpose infer writes
    assert out["frames_scored"] == len(per_frame)
    assert out["per_frame_mean_cm"] == pytest.approx(np.mean(per_frame), rel=1e-9)
    assert out["temporal_mean_cm"] == pytest.approx(np.mean(temporal), rel=1e-9)
    assert out[f"best_of_{HYPOTHESES}_mean_cm"] == pytest.approx(np.mean(best), rel=1e-9)
    assert out[f"best_of_{HYPOTHESES}_mean_cm"] <= min(out["per_frame_mean_cm"], out["temporal_mean_cm"])


def test_a_dataset_not_written_by_the_generator_has_no_sequences(stick_dataset):
    assert render_dataset_sequences(stick_dataset) is None


def test_the_module_cli_says_what_is_missing(stick_dataset, tmp_path, capsys):
    from silpose.eval.sequences import main

    assert main([str(tmp_path / "none"), str(tmp_path / "m.npz")]) == 2
    assert "none: not found" in capsys.readouterr().err


def test_the_figure_shows_the_sequences(scored, tmp_path):
    import cv2

    from silpose.eval.sequences import plot_sequences

    *_, out = scored
    assert len(out["scored"]["sequence"]) == out["frames_scored"]
    path = plot_sequences(out, tmp_path / "e7.png")
    img = cv2.imread(str(path))
    assert img is not None and img.shape[0] > 200 and img.std() > 10  # a real, non-blank image
    assert plot_sequences({"scored": {}}, tmp_path / "none.png") is None


def test_the_summary_section_carries_the_figures(scored):
    from silpose.eval.sequences import e7_markdown

    *_, out = scored
    text = "\n".join(e7_markdown(out))
    assert f"| each frame alone | {out['per_frame_mean_cm']:.2f} | {out['per_frame_median_cm']:.2f} |" in text
    assert f"| {out['temporal_mean_cm']:.2f} | {out['temporal_median_cm']:.2f} |" in text
    assert e7_markdown({}) == []


def test_the_experiment_plays_at_most_n_test_sequences(scored, library_dataset):
    """``silpose eval --n-test N`` asks for a quick run: E7 plays at most N sequences, the first sample of the
    first N clips (a clip's second sample only once every clip has one)."""
    model, _, cfg, _ = scored
    ev = SimpleNamespace(model=model, config=EvalConfig(n_test=2), timings={})
    out = sequence_experiment(ev, library_dataset, length=4)
    test = load_split(library_dataset, "test", columns=["gait"])
    clips = np.asarray(test.gait["clip"])
    first_of = {int(c): int(test.sample_id[clips == c].min()) for c in np.unique(clips)}
    assert len(first_of) >= 2
    assert out["n_sequences"] == 2 and out["frames"] == 8 and ev.timings["sequences"] > 0
    assert out["sample_ids"] == [first_of[c] for c in sorted(first_of)[:2]]
