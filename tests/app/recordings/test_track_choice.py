"""The answer of several people chosen along their tracks a chunk at a time, with the next chunk ahead
(silpose.app.recordings.chunk_rows.choose_along_tracks). Reference: the whole-sequence Viterbi path
(silpose.model.hypotheses.temporal_choice) over every frame known when a chunk is decided."""

from types import SimpleNamespace

import numpy as np

from silpose.app.recordings.chunk_rows import ChunkInference, choose_along_tracks
from silpose.model.hypotheses import Hypotheses, heading, temporal_choice
from silpose.shared.skeleton import JOINT_INDEX, N_JOINTS


def _body(facing: float, rng) -> np.ndarray:
    """(19, 3) a body facing ``facing`` radians (its left 90 deg counter-clockwise of it), other joints random."""
    j = rng.normal(0, 0.05, (N_JOINTS, 3))
    for side, y in (("l", 0.1), ("r", -0.1)):
        j[JOINT_INDEX[f"{side}_hip"]] = (0.0, y, 0.0)
        j[JOINT_INDEX[f"{side}_shoulder"]] = (0.0, 2 * y, 0.5)
    c, s = np.cos(facing), np.sin(facing)
    return j @ np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]])


def _track(facing: np.ndarray, prob: np.ndarray, rng) -> Hypotheses:
    """Two hypotheses per frame: the body facing ``facing`` and facing the other way; ``prob`` (T, 2)."""
    joints = np.stack([[_body(f, rng), _body(f + np.pi, rng)] for f in facing])
    return Hypotheses(joints, prob, np.tile([0, 1], (len(facing), 1)), heading(joints), np.zeros(len(facing), np.intp))


def _chunk(rows: list[tuple[int, int]], hyp: Hypotheses) -> ChunkInference:
    """A chunk of rows (track key, step) with their hypotheses (the inference's result stands in by its hypotheses)."""
    people = [SimpleNamespace(track=SimpleNamespace(key=k), step=s) for k, s in rows]
    n = len(rows)
    return ChunkInference(people=people, seen=[], step0=min(s for _, s in rows), view_status=np.full((n, 1), "ok"),
                          used=np.ones((n, 1), bool), detected=np.ones(n, bool), rows=np.arange(n),
                          result=SimpleNamespace(hypotheses=hyp))


def test_a_chunk_is_decided_by_the_path_best_at_the_end_of_the_next():
    """Track 7's first chunk favours the flipped pose (0.9 : 0.1), its next chunk the right one for longer. Decided
    alone, the first chunk keeps the flip; with the next chunk ahead it takes the whole sequence's path. Track 3,
    interleaved in the same chunks, is chosen on its own frames only."""
    rng = np.random.default_rng(0)
    facing = np.linspace(0.0, 0.4, 10)
    prob = np.tile([0.8, 0.2], (10, 1))
    prob[:4] = [0.1, 0.9]
    seven = _track(facing, prob, rng)
    three = _track(facing + 2.0, rng.dirichlet([1, 1], 10), rng)
    first, second = np.arange(4), np.arange(4, 10)

    def chunks():  # each chunk holds both tracks' rows, in step order
        return [_chunk([(k, s) for s in part for k in (7, 3)], Hypotheses.concat(
            [h.take(np.array([s])) for s in part for h in (seven, three)])) for part in (first, second)]

    c1, _ = chunks()
    choose_along_tracks(c1, None, {})
    alone = c1.hypotheses.chosen[::2]
    c1, c2 = chunks()
    paths = {}
    choose_along_tracks(c1, c2, paths)
    ahead = c1.hypotheses.chosen[::2]
    assert paths[7].step == 3 and paths[3].step == 3  # the paths end after the chunk decided, not the look-ahead
    choose_along_tracks(c2, None, paths)
    rest = c2.hypotheses.chosen[::2]
    kw = {}
    assert list(alone) == list(temporal_choice(seven.take(first), **kw)) == [1] * 4
    whole = temporal_choice(seven, **kw)
    assert list(ahead) == list(whole[first]) == [0] * 4
    assert list(rest) == list(whole[second])
    assert list(c1.hypotheses.chosen[1::2]) == list(temporal_choice(three, **kw)[first])
