"""Top-K hypotheses, facing direction, flips, the view-pair consensus and the Viterbi choice.

References: skeletons built and rotated by hand (the heading of a rotated skeleton is the rotation
angle), and an exhaustive search over every path for the Viterbi choice.
"""

import itertools

import numpy as np
import pytest

from silpose.model.hypotheses import (
    TEMPORAL_POSE_SIGMA_M,
    TEMPORAL_TEMPERATURE,
    TEMPORAL_TURN_SIGMA_DEG,
    Hypotheses,
    consensus_choice,
    continue_choice,
    heading,
    heading_error,
    is_flip,
    single_answer,
    sequence_answer,
    temporal_choice,
    top_hypotheses,
    wrap_angle,
)
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.synthetic import make_linear_shapes
from silpose.shared.skeleton import JOINT_INDEX, N_JOINTS


def _skeleton(facing: float, rng=None) -> np.ndarray:
    """(19, 3) a body facing +x (its left along +y) rotated by ``facing`` about z; other joints random."""
    rng = np.random.default_rng(0) if rng is None else rng
    j = rng.normal(0, 0.05, size=(N_JOINTS, 3)) * [0.3, 0.3, 1.0]
    j[JOINT_INDEX["l_hip"]] = [0.0, 0.1, 0.0]
    j[JOINT_INDEX["r_hip"]] = [0.0, -0.1, 0.0]
    j[JOINT_INDEX["l_shoulder"]] = [0.0, 0.18, 0.5]
    j[JOINT_INDEX["r_shoulder"]] = [0.0, -0.18, 0.5]
    c, s = np.cos(facing), np.sin(facing)
    return j @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]).T


def test_heading_is_the_rotation_angle():
    angles = np.radians([0, 30, 90, 179, -120])
    skel = np.stack([_skeleton(a) for a in angles])
    np.testing.assert_allclose(wrap_angle(heading(skel) - angles), 0.0, atol=1e-9)
    assert heading_error(_skeleton(0.2), _skeleton(0.2 + np.pi)) == pytest.approx(np.pi)
    assert is_flip(_skeleton(0.0), _skeleton(np.radians(100))) and not is_flip(_skeleton(0.0), _skeleton(np.radians(80)))
    with pytest.raises(ValueError, match="19, 3"):
        heading(np.zeros((4, 3)))


def test_top_hypotheses_sorts_merges_and_pads():
    a, b, c = _skeleton(0.0), _skeleton(np.pi), _skeleton(1.0)
    near_a = a + 0.005  # 0.87 cm from a: merged into it (root-relative: the shift cancels anyway)
    near_a[3] += 0.01
    comp = np.stack([b, a, near_a, c])[None]  # (1, 4, 19, 3)
    resp = np.array([[0.30, 0.40, 0.25, 0.05]])
    h = top_hypotheses(comp, resp, k=3, merge_cm=3.0)
    assert list(h.component[0]) == [1, 0, 3]  # a (0.40 + 0.25 merged), b, c
    np.testing.assert_allclose(h.probability[0], [0.65, 0.30, 0.05])
    np.testing.assert_allclose(wrap_angle(h.heading[0] - [0.0, np.pi, 1.0]), 0.0, atol=1e-9)
    assert h.chosen[0] == 0 and np.array_equal(h.best_joints[0], a)
    # fewer distinct components than k: unused slots are empty
    h5 = top_hypotheses(comp, resp, k=5, merge_cm=3.0)
    assert list(h5.component[0]) == [1, 0, 3, -1, -1] and np.isnan(h5.joints[0, 3:]).all()
    assert h5.probability[0, 3:].sum() == 0


def test_best_of_is_the_nearest_hypothesis():
    truth = _skeleton(0.5)[None]
    comp = np.stack([_skeleton(0.5 + np.pi), _skeleton(0.6), _skeleton(2.0)])[None]
    h = top_hypotheses(comp, np.array([[0.7, 0.2, 0.1]]), k=3)
    assert h.best_of(truth)[0] == 1 and h.best_of(truth, k=1)[0] == 0


def test_consensus_follows_the_majority_of_votes():
    comp = np.stack([_skeleton(np.pi), _skeleton(0.0), _skeleton(0.1)])[None].repeat(3, axis=0)
    resp = np.array([[0.6, 0.3, 0.1]] * 3)
    h = top_hypotheses(comp, resp, k=3, merge_cm=0.1)
    votes = np.array([[0.05, 0.1, -0.1, 3.0, np.nan, np.nan],  # 3 of 4 votes face ~0: the first such hypothesis
                      [0.05, 3.1, np.nan, np.nan, np.nan, np.nan],  # a tie: the most probable stays
                      [np.nan] * 6])  # no votes: the most probable stays
    assert list(consensus_choice(h, votes)) == [1, 0, 0]


def _brute_force(h: Hypotheses, sigma: float, temperature: float = 1.0, pose_sigma: float | None = None) -> list[int]:
    t, k = h.probability.shape
    best, arg = np.inf, None
    for path in itertools.product(range(k), repeat=t):
        cost = -np.log(h.probability[np.arange(t), path]).sum() / temperature
        d = wrap_angle(np.diff(h.heading[np.arange(t), path]))
        cost += 0.5 * np.sum((d / sigma) ** 2)
        if pose_sigma is not None:
            chosen = h.joints[np.arange(t), path]  # (t, 19, 3)
            dj = np.array([np.mean(np.linalg.norm(chosen[i + 1] - chosen[i], axis=1)) for i in range(t - 1)])
            cost += 0.5 * np.sum((dj / pose_sigma) ** 2)
        if cost < best:
            best, arg = cost, list(path)
    return arg


def test_temporal_choice_is_the_optimal_path_and_removes_a_flip():
    rng = np.random.default_rng(4)
    t_len = 6
    facing = np.linspace(0.0, 0.5, t_len)  # a person turning slowly
    joints = np.stack([[_skeleton(f), _skeleton(f + np.pi)] for f in facing])
    prob = np.tile([0.8, 0.2], (t_len, 1))
    prob[3] = [0.1, 0.9]  # frame 3 alone favours the flipped hypothesis
    h = Hypotheses(joints, prob, np.tile([0, 1], (t_len, 1)), heading(joints), np.zeros(t_len, dtype=np.intp))
    path = temporal_choice(h, turn_sigma_deg=20.0, temperature=1.0, pose_sigma_m=None)
    assert list(path) == [0] * t_len
    assert list(path) == _brute_force(h, np.radians(20.0))
    # random hypotheses: the Viterbi path equals the exhaustive optimum, untempered and tempered, with and without
    # the joints' continuity (random poses too, so the joint term and the heading term disagree)
    for temperature, pose_sigma in ((1.0, None), (3.0, None), (1.0, 0.3), (100.0, 0.15)):
        for _ in range(5):
            prob = rng.dirichlet(np.ones(3), size=5)
            joints = np.stack([[_skeleton(a) + rng.normal(0, 0.1, (N_JOINTS, 3)) for a in rng.uniform(-np.pi, np.pi, 3)]
                               for _ in range(5)])
            hr = Hypotheses(joints, prob, np.tile([0, 1, 2], (5, 1)), heading(joints), np.zeros(5, dtype=np.intp))
            assert (list(temporal_choice(hr, turn_sigma_deg=40.0, temperature=temperature, pose_sigma_m=pose_sigma))
                    == _brute_force(hr, np.radians(40.0), temperature, pose_sigma))


def test_the_default_choice_follows_the_continuous_heading_not_the_overconfident_frames():
    """Overconfident responsibilities (module doc): in every frame the top hypothesis holds 0.9999 of the weight,
    but its heading jumps 69 deg between frames (a component that fits each frame's outline, facing no steady way);
    the other hypothesis faces one way throughout. With 20 deg a frame, untempered, the path follows the weights
    (9.2 nats a frame to leave them, 6.0 for each jump); with the defaults (9 deg: 29 nats a jump), or tempered at 20
    deg, it follows the steady heading."""
    t_len = 8
    jump = np.where(np.arange(t_len) % 2 == 0, np.pi, np.pi - 1.2)
    joints = np.stack([[_skeleton(0.0), _skeleton(a)] for a in jump])
    prob = np.tile([1e-4, 1 - 1e-4], (t_len, 1))
    h = Hypotheses(joints, prob, np.tile([0, 1], (t_len, 1)), heading(joints), np.zeros(t_len, dtype=np.intp))
    loose = dict(turn_sigma_deg=20.0, temperature=1.0, pose_sigma_m=None)
    assert list(temporal_choice(h, **loose)) == [1] * t_len
    assert list(temporal_choice(h, **loose)) == _brute_force(h, np.radians(20.0))
    assert list(temporal_choice(h, turn_sigma_deg=20.0, temperature=100.0, pose_sigma_m=None)) == [0] * t_len
    assert list(temporal_choice(h)) == [0] * t_len
    assert list(temporal_choice(h)) == _brute_force(h, np.radians(TEMPORAL_TURN_SIGMA_DEG), TEMPORAL_TEMPERATURE,
                                                    TEMPORAL_POSE_SIGMA_M)
    with pytest.raises(ValueError, match="temperature"):
        temporal_choice(h, temperature=0.0)
    with pytest.raises(ValueError, match="pose_sigma_m"):
        temporal_choice(h, pose_sigma_m=-1.0)


def test_the_joint_term_follows_the_moving_limbs_when_the_heading_cannot_tell():
    """Two hypotheses face the same way, one the steadily moving pose, the other a pose that jumps back and forth
    by 20 cm (a leg forward in one frame, back in the next) and holds more weight in every frame. The heading
    term cannot tell them apart; the joint term keeps the steady one."""
    t_len = 6
    steady = np.stack([_skeleton(0.0) + 0.01 * t for t in range(t_len)])
    jumpy = np.stack([_skeleton(0.0) + (0.2 if t % 2 else -0.2) * np.eye(3)[0] for t in range(t_len)])
    joints = np.stack([steady, jumpy], axis=1)
    h = Hypotheses(joints, np.tile([0.3, 0.7], (t_len, 1)), np.tile([0, 1], (t_len, 1)), heading(joints),
                   np.zeros(t_len, dtype=np.intp))
    assert list(temporal_choice(h, pose_sigma_m=None)) == [1] * t_len
    assert list(temporal_choice(h)) == [0] * t_len


def _random_track(rng, t_len: int, k: int = 3) -> Hypotheses:
    """Hypotheses of a track of ``t_len`` frames with random weights, headings and poses; a few unused slots."""
    joints = np.stack([[_skeleton(a) + rng.normal(0, 0.05, (N_JOINTS, 3)) for a in rng.uniform(-np.pi, np.pi, k)]
                       for _ in range(t_len)])
    comp = np.tile(np.arange(k), (t_len, 1))
    comp[rng.random((t_len, k)) < 0.15] = -1
    comp[:, 0] = 0  # every frame has a hypothesis
    joints[comp < 0] = np.nan
    prob = np.where(comp >= 0, rng.dirichlet(np.ones(k), size=t_len), 0.0)
    return Hypotheses(joints, prob, comp, heading(joints), np.zeros(t_len, dtype=np.intp))


def test_continue_choice_in_chunks_is_the_best_path_at_each_chunks_end():
    """A track fed in chunks: each chunk's slots equal the whole-prefix Viterbi path (temporal_choice over every
    frame up to the chunk's last, an independent run with no carried state) on the chunk's frames; frames skipped
    by the track (gaps in the steps) widen the expected motion as frame_gap does; the first chunk alone is
    temporal_choice of its frames. The path's end is not the chunk's written choice alone: a path that went wrong
    can be left at the next chunk."""
    rng = np.random.default_rng(7)
    for trial in range(6):
        t_len = 14
        h = _random_track(rng, t_len)
        steps = np.cumsum(rng.integers(1, 3, t_len)) + 100
        kw = dict(turn_sigma_deg=40.0, temperature=(1.0, 10.0)[trial % 2], pose_sigma_m=(None, 0.2)[trial % 2])
        end, got = None, np.zeros(t_len, dtype=np.intp)
        bounds = [0, 1, 5, 6, 11, t_len]
        for a, b in zip(bounds[:-1], bounds[1:]):
            got[a:b], end = continue_choice(h.take(np.arange(a, b)), steps[a:b], end, **kw)
            prefix = temporal_choice(h.take(np.arange(b)), frame_gap=np.diff(steps[:b], prepend=steps[0]).astype(float),
                                     **kw)
            assert list(got[a:b]) == list(prefix[a:b])
            assert end.step == steps[b - 1] and end.cost.min() == 0.0
        first, _ = continue_choice(h.take(np.arange(5)), steps[:5], None, **kw)
        assert list(first) == list(temporal_choice(h.take(np.arange(5)), frame_gap=np.diff(steps[:5], prepend=steps[0])
                                                   .astype(float), **kw))


def test_a_continued_track_leaves_a_flip_the_next_frames_refute():
    """The first chunk's only frame favours a flipped pose (0.9 : 0.1) and has to be answered alone; the next chunk
    faces the other way throughout. Carried costs let the new chunk start from the right-facing hypothesis of the
    frame before (its slots say so), where only the written choice carried would keep the flip."""
    facing = np.linspace(0.0, 0.3, 6)
    joints = np.stack([[_skeleton(f), _skeleton(f + np.pi)] for f in facing])
    prob = np.tile([0.7, 0.3], (6, 1))
    prob[0] = [0.1, 0.9]
    h = Hypotheses(joints, prob, np.tile([0, 1], (6, 1)), heading(joints), np.zeros(6, dtype=np.intp))
    kw = dict(temperature=1.0, pose_sigma_m=None)
    first, end = continue_choice(h.take(np.arange(1)), np.array([0]), None, **kw)
    assert list(first) == [1]  # alone, the flip wins
    rest, end = continue_choice(h.take(np.arange(1, 6)), np.arange(1, 6), end, **kw)
    assert list(rest) == [0] * 5
    assert list(temporal_choice(h, **kw)) == [0] * 6  # the whole sequence at once agrees
    hard = h.take(np.arange(6))  # only the written choice carried: frame 0 holds the flip alone
    hard.component[0, 0], hard.probability[0] = -1, [0.0, 1.0]
    assert list(temporal_choice(hard, **kw)[1:]) == [1] * 5
    # a chunk without a usable hypothesis keeps slot 0 and leaves the path's end where it was
    empty = Hypotheses(np.full((2, 2, N_JOINTS, 3), np.nan), np.zeros((2, 2)), np.full((2, 2), -1), np.full((2, 2), np.nan),
                       np.zeros(2, dtype=np.intp))
    slots, same = continue_choice(empty, np.array([7, 8]), end, **kw)
    assert list(slots) == [0, 0] and same is end
    with pytest.raises(ValueError, match="steps"):
        continue_choice(h.take(np.arange(2)), np.array([3, 3]), None)
    with pytest.raises(ValueError, match="steps"):
        continue_choice(h.take(np.arange(2)), np.array([5, 6]), end)  # not after the end's step (5)
    with pytest.raises(ValueError, match="hypotheses"):
        continue_choice(_random_track(np.random.default_rng(0), 2, k=3), np.array([9, 10]), end)


def test_single_answer_keeps_the_mean_unless_the_choice_faces_the_other_way():
    mean = np.stack([_skeleton(0.1), _skeleton(0.2), _skeleton(0.0)])
    joints = np.stack([[_skeleton(0.3), _skeleton(np.pi)], [_skeleton(0.2 + 2.0), _skeleton(0.2)],
                       [_skeleton(np.pi), _skeleton(0.0)]])
    h = Hypotheses(joints, np.tile([0.6, 0.4], (3, 1)), np.array([[0, 1], [0, 1], [0, -1]]), heading(joints),
                   np.array([0, 0, 0]))
    got = single_answer(mean, h)
    np.testing.assert_array_equal(got[0], mean[0])  # chosen 17 deg away: the mean
    np.testing.assert_array_equal(got[1], joints[1, 0])  # chosen 115 deg away (> 90): the hypothesis
    np.testing.assert_array_equal(got[2], joints[2, 0])  # a flip: the hypothesis
    np.testing.assert_array_equal(single_answer(mean, h, chosen=np.array([1, 1, 1]))[:2], [joints[0, 1], mean[1]])
    assert np.array_equal(single_answer(mean, h, chosen=np.array([1, 1, 1]))[2], mean[2])  # unused slot: the mean
    np.testing.assert_array_equal(single_answer(mean, None), mean)


def test_sequence_answer_is_the_chosen_hypothesis_where_there_is_one():
    mean = np.stack([_skeleton(0.1), _skeleton(0.2), _skeleton(0.0)])
    joints = np.stack([[_skeleton(0.3), _skeleton(np.pi)], [_skeleton(0.25), _skeleton(0.2)],
                       [_skeleton(np.pi), _skeleton(0.0)]])
    h = Hypotheses(joints, np.tile([0.6, 0.4], (3, 1)), np.array([[0, 1], [0, 1], [0, -1]]), heading(joints),
                   np.array([0, 1, 1]))
    got = sequence_answer(mean, h)
    np.testing.assert_array_equal(got[0], joints[0, 0])  # 17 deg from the mean: still the hypothesis
    np.testing.assert_array_equal(got[1], joints[1, 1])
    np.testing.assert_array_equal(got[2], mean[2])  # the chosen slot is unused: the mean
    np.testing.assert_array_equal(sequence_answer(mean, h, chosen=np.zeros(3, np.intp))[2], joints[2, 0])
    np.testing.assert_array_equal(sequence_answer(mean, None), mean)


def test_temporal_choice_bridges_frames_without_views():
    facing = np.zeros(5)
    joints = np.stack([[_skeleton(f), _skeleton(f + np.pi)] for f in facing])
    prob = np.tile([0.9, 0.1], (5, 1))
    prob[4] = [0.3, 0.7]
    h = Hypotheses(joints, prob, np.tile([0, 1], (5, 1)), heading(joints), np.zeros(5, dtype=np.intp))
    valid = np.array([True, True, False, False, True])
    assert list(temporal_choice(h, valid=valid, turn_sigma_deg=20.0, temperature=1.0, pose_sigma_m=None)) == [0] * 5
    # a long gap allows a real turn: with sigma grown by the gap, frame 4's evidence wins
    gap = np.array([1, 1, 1, 1, 40.0])
    assert temporal_choice(h, valid=valid, frame_gap=gap, turn_sigma_deg=20.0, temperature=1.0, pose_sigma_m=None)[4] == 1
    with pytest.raises(ValueError, match="turn_sigma_deg"):
        temporal_choice(h, turn_sigma_deg=0.0)


def test_model_hypotheses_match_component_means():
    data = make_linear_shapes(300, n_views=3, n_points=16, seed=5)
    model = ShapeStructureModel(n_components=3, n_latent=5, structure_weight=2.0, noise_variance=1e-3, n_init=1,
                                random_state=0, joint_frame="metres").fit(data.contours, data.joints)
    res = model.infer(data.contours[:40], hypotheses=3, consensus=False)
    h = res.hypotheses
    assert h.joints.shape == (40, 3, N_JOINTS, 3) and (h.chosen == 0).all()
    # slot 0 is the most probable component's conditional mean (InferenceResult.joints_best)
    np.testing.assert_allclose(h.joints[:, 0], res.joints_best, atol=1e-9)
    np.testing.assert_array_equal(h.component[:, 0], res.responsibilities.argmax(1))
    assert np.all(np.diff(h.probability, axis=1) <= 1e-12)
    # the consensus needs >= 3 present views; with 2 it keeps the most probable
    present = np.ones((40, 3), bool)
    present[:, 2] = False
    assert (model.infer(data.contours[:40], present, hypotheses=3).hypotheses.chosen == 0).all()
    with pytest.raises(ValueError, match="hypotheses"):
        model.infer(data.contours[:2], hypotheses=-1)


def test_top_hypotheses_equal_one_frame_at_a_time_in_plain_python():
    """The batched loop against a per-frame reference written out: components by decreasing weight (stable), each
    merged into the nearest kept hypothesis within 3 cm (mean root-relative joint distance) or kept in the next slot;
    then sorted by merged probability. Near-duplicate components force merges; some frames' weights underflow."""
    rng = np.random.default_rng(4)
    n, m, k = 25, 30, 3
    cj = rng.normal(0, 0.3, (n, m, 19, 3))
    cj[:, 10:20] = cj[:, :10] + rng.normal(0, 0.005, (n, 10, 19, 3))  # within 3 cm of components 0-9
    r = rng.dirichlet(np.full(m, 0.2), n)
    r[::3, 2:] = 0.0
    got = top_hypotheses(cj, r, k)
    for f in range(n):
        kept, probs, comps = [], [], []
        for i in sorted(range(m), key=lambda i: -r[f, i]):
            rel = cj[f, i] - cj[f, i, :1]
            d = [np.linalg.norm((h - h[:1]) - rel, axis=-1).mean() for h in kept]
            if d and min(d) < 0.03:
                probs[int(np.argmin(d))] += r[f, i]
            elif len(kept) < k:
                kept.append(cj[f, i]), probs.append(r[f, i]), comps.append(i)
        order = sorted(range(len(kept)), key=lambda j: -probs[j])
        np.testing.assert_array_equal(got.component[f, :len(kept)], [comps[j] for j in order])
        np.testing.assert_allclose(got.probability[f, :len(kept)], [probs[j] for j in order], rtol=1e-12, atol=0)
        np.testing.assert_array_equal(got.joints[f, :len(kept)], np.array([kept[j] for j in order]))
    assert (got.probability[:, 0] > r.max(axis=1)).any()  # some weight was merged
