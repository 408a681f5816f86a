"""``BackgroundModel.candidates``: a colour frame's whole-frame steps computed beforehand (the recordings pipeline's
reader threads) and handed to ``segment`` give the masks ``segment`` gives alone, and are ignored once the model's
statistics changed (an absorb, a fit)."""

import threading

import cv2
import numpy as np
import pytest

from silpose.segment import STAGES, BackgroundModel, Candidates
from silpose.segment.synthetic import render_scene


@pytest.fixture(scope="module")
def scene():
    return render_scene(n_background=20, n_frames=6, seed=11)


def _model(scene, **kw):
    return BackgroundModel(gain=True, largest_blob=False, **kw).fit(scene.background)


@pytest.mark.parametrize("kw", [{}, {"edge_coverage": None, "cleanup_guard": None}, {"gain": False}])
def test_candidates_handed_over_give_every_stage_of_segment_alone(scene, kw):
    model = BackgroundModel(largest_blob=False, **{"gain": True, **kw}).fit(scene.background)
    for frame in scene.frames:
        c = model.candidates(frame)
        assert isinstance(c, Candidates) and c.version == model.version
        alone = model.segment(frame, return_stages=True)
        given = model.segment(frame, return_stages=True, candidates=c)
        assert tuple(given) == STAGES
        for name in STAGES:
            np.testing.assert_array_equal(given[name], alone[name], err_msg=name)
        np.testing.assert_array_equal(c.mask, alone["candidates"])


def test_candidates_computed_in_other_threads_meanwhile_give_the_same_masks(scene):
    """Four threads compute candidates of the frames while this one segments others: nothing in the model changes
    under them (the masks equal those of one thread, frame for frame)."""
    model = _model(scene)
    expected = [model.segment(f) for f in scene.frames]
    frames = list(scene.frames) * 4
    got: list = [None] * len(frames)

    def work(start):
        for i in range(start, len(frames), 4):
            got[i] = model.candidates(frames[i])

    threads = [threading.Thread(target=work, args=(s,)) for s in range(4)]
    for t in threads:
        t.start()
    for f in scene.frames:  # this thread segments meanwhile
        model.segment(f)
    for t in threads:
        t.join()
    for i, c in enumerate(got):
        np.testing.assert_array_equal(model.segment(frames[i], candidates=c), expected[i % len(expected)])


def test_candidates_from_before_an_absorb_are_ignored(scene, monkeypatch):
    """After ``absorb`` (new statistics, a new version) candidates computed before it still show the absorbed
    object; ``segment`` computes them again (and only then), so the mask is the absorbed model's."""
    model = _model(scene)
    frame = scene.frames[0]
    before = model.candidates(frame)
    where = model.segment(frame)  # the person: absorbed as if they had stood still
    assert where.sum() > 500
    v = model.version
    model.absorb(frame, where)
    assert model.version == v + 1
    after = model.candidates(frame)
    assert before.mask[where].mean() > 0.9 and after.mask[where].mean() < 0.05  # the old ones are out of date
    calls = []
    real = BackgroundModel._colour_candidates
    monkeypatch.setattr(BackgroundModel, "_colour_candidates", lambda self, *a: calls.append(1) or real(self, *a))
    fresh = model.segment(frame)
    assert len(calls) == 1 and fresh.sum() < 0.05 * where.sum()  # the absorbed person is background now
    np.testing.assert_array_equal(model.segment(frame, candidates=before), fresh)
    assert len(calls) == 2  # computed again
    np.testing.assert_array_equal(model.segment(frame, candidates=after), fresh)
    assert len(calls) == 2  # up to date: used as given


def test_a_refit_changes_the_version_and_graylevel_has_no_candidates(scene):
    model = _model(scene)
    v = model.version
    model.fit(scene.background[:10])
    assert model.version != v
    grey = np.stack([cv2.cvtColor(f, cv2.COLOR_BGR2GRAY) for f in scene.background])
    assert BackgroundModel().fit(grey).candidates(grey[0]) is None  # a graylevel model
    assert _model(scene).candidates(grey[0]) is None  # a graylevel frame on a colour model
    assert BackgroundModel(colour=False).fit(scene.background).candidates(scene.frames[0]) is None


def test_candidates_computed_while_the_model_absorbs_are_those_of_the_version_they_name(scene):
    """A thread computes candidates over and over while this one absorbs (new statistics each time): every result
    equals the candidates of the statistics of the version it names -- never half of one and half of another."""
    model = _model(scene)
    frames = scene.frames[:3]
    ref = {model.version: [model.candidates(f) for f in frames]}
    got, errors, stop = [], [], threading.Event()

    def work():
        i = 0
        try:
            while not stop.is_set():
                got.append((i % 3, model.candidates(frames[i % 3])))
                i += 1
        except BaseException as exc:  # noqa: BLE001 -- reported below
            errors.append(exc)

    t = threading.Thread(target=work)
    t.start()
    rng = np.random.default_rng(0)
    h, w = frames.shape[1:3]
    for _ in range(12):
        where = np.zeros((h, w), bool)
        y, x = rng.integers(0, h - 40), rng.integers(0, w - 40)
        where[y:y + 40, x:x + 40] = True
        model.absorb(frames[rng.integers(3)], where)
        ref[model.version] = [model.candidates(f) for f in frames]
    stop.set()
    t.join()
    assert not errors and len({c.version for _, c in got}) >= 2, (errors, len(got))
    for i, c in got:
        r = ref[c.version][i]
        for name in ("divided", "mask", "sq", "score"):
            np.testing.assert_array_equal(getattr(c, name), getattr(r, name), err_msg=name)
