"""The fast forms of robust inference's array arithmetic give the straightforward forms' results bit for bit.

Robust inference (``silpose.model.robust``) avoids numpy's broadcasts and reductions over a last axis of 2 and
(V, n, 2w + 1) gathers on large batches; each fast form is compared here with the plain numpy expression it
replaced, with ``np.array_equal`` (not a tolerance), on inputs that include ties, NaN and absent views.
"""

from __future__ import annotations

import numpy as np

from silpose.model import features
from silpose.model.features import denormalise_contours, normalise_contours
from silpose.model.robust.excursions import ExcursionSettings, trim_excursions
from silpose.model.robust.loop import SETTLED_PX, largest_move, pseudo_observation
from silpose.model.robust.observed_views import view_scales
from silpose.model.robust.reindex import index_offsets
from silpose.model.robust.weights import frame_noise_variance


def _contours(rng, shape, n=200):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    base = np.stack([np.cos(t), 1.6 * np.sin(t)], -1) * 35 + 150
    return base + rng.normal(0, 2.0, size=shape + (n, 2))


def test_view_scales_is_the_numpy_formula():
    rng = np.random.default_rng(0)
    for v, n in ((300, 200), (70, 13), (7, 13), (3, 1), (0, 5)):  # the point-by-point sums and numpy's formula
        pts = _contours(rng, (v,), n)
        centred = pts - pts.mean(axis=1, keepdims=True)
        want = np.sqrt(np.mean(np.sum(centred ** 2, axis=-1), axis=1))
        assert np.array_equal(view_scales(pts), want)


def test_index_offsets_is_the_gathered_argmin():
    rng = np.random.default_rng(1)
    obs = np.round(_contours(rng, (80,)))  # integer pixels: many ties, the first nearest shift must win
    rec = np.round(_contours(rng, (80,)))
    for w, v in ((1, 80), (8, 80), (8, 5)):  # one shift at a time, and all at once for a few views
        obs, rec = obs[:v], rec[:v]
        shifts = np.arange(-w, w + 1)
        idx = (np.arange(200)[:, None] + shifts[None, :]) % 200
        dist = np.sqrt(np.sum((obs[:, :, None, :] - rec[:, idx, :]) ** 2, axis=-1))
        best = dist.argmin(axis=-1)
        off, d = index_offsets(obs, rec, w)
        assert np.array_equal(off, shifts[best])
        assert np.array_equal(d, np.take_along_axis(dist, best[..., None], axis=-1)[..., 0])


def test_pseudo_observation_and_largest_move():
    rng = np.random.default_rng(2)
    rec, obs = _contours(rng, (20, 3)), _contours(rng, (20, 3))
    u = rng.uniform(0, 1, size=(20, 3, 200))
    u[0] = 0.0
    assert np.array_equal(pseudo_observation(rec, obs, u), rec + u[..., None] * (obs - rec))
    new = rec + rng.normal(0, SETTLED_PX, size=rec.shape)  # moves of a few SETTLED_PX
    new[1] = rec[1]
    new[2, 0, 5, 1] = np.nan  # NaN counts as no move
    new[3] = np.nan
    new[4, 1, 7, 0] = np.inf
    want = np.abs(np.nan_to_num(new - rec)).max(axis=(1, 2, 3)) >= SETTLED_PX
    assert np.array_equal(largest_move(new, rec) >= SETTLED_PX, want)
    assert want[0] and not want[1] and not want[3] and want[4]


def test_normalisation_per_coordinate_is_the_broadcast_form():
    rng = np.random.default_rng(3)
    pts = _contours(rng, (30, 4))
    pts[2, 1] = np.nan
    q, c, s = normalise_contours(pts)
    f = pts.reshape(-1, 200, 2)
    cc = np.stack([f[:, :, 0].sum(axis=1), f[:, :, 1].sum(axis=1)], axis=-1) / 200
    qq = f - cc[:, None, :]
    flat = qq.reshape(len(qq), -1)
    ss = np.sqrt(np.einsum("ij,ij->i", flat, flat) / 200)
    qq /= np.where(ss > 0, ss, 1.0)[:, None, None]
    assert np.array_equal(q, qq.reshape(pts.shape), equal_nan=True)
    assert np.array_equal(c, cc.reshape(30, 4, 2), equal_nan=True)
    out = denormalise_contours(q, c, s)
    assert np.array_equal(out, q * s[..., None, None] + c[..., None, :], equal_nan=True)
    assert np.array_equal(denormalise_contours(q[0, 0], c[0, 0], s[0, 0]), q[0, 0] * s[0, 0] + c[0, 0])


def test_normalisation_in_chunks_and_of_strided_views(monkeypatch):
    """Chunks of contours (the last one short) and the centroid as complex numbers give the whole-array
    broadcast forms; the reconstruction is denormalised from a strided view of (N, d) shape vectors."""
    rng = np.random.default_rng(8)
    pts = _contours(rng, (23, 3))
    pts[4, 2, 9] = np.nan
    want_q, want_c, want_s = normalise_contours(pts)
    vectors = np.concatenate([want_q.reshape(23, -1), rng.normal(size=(23, 57))], axis=1)
    rec = vectors[:, :3 * 200 * 2].reshape(23, 3, 200, 2)  # strided: rows of 1,257 values
    monkeypatch.setattr(features, "CHUNK_CONTOURS", 5)  # 69 contours: 13 chunks of 5 and one of 4
    q, c, s = normalise_contours(pts)
    for got, want in ((q, want_q), (c, want_c), (s, want_s)):
        assert np.array_equal(got, want, equal_nan=True)
    assert np.array_equal(normalise_contours(pts[:, ::2])[0], want_q[:, ::2], equal_nan=True)  # a strided input
    out = denormalise_contours(rec, c, s)
    assert np.array_equal(out, rec * s[..., None, None] + c[..., None, :], equal_nan=True)



def test_normalisation_chunks_on_threads_equal_one_thread(monkeypatch):
    """A large batch's chunks of contours run on the pool's threads (``features.chunk_threads``): the same values bit
    for bit as the broadcast forms on one thread, and the chunks did run on other threads."""
    import threading

    rng = np.random.default_rng(9)
    pts = _contours(rng, (23, 3))
    pts[4, 2, 9] = np.nan
    pts[7, 1] = 150.0  # a degenerate contour: scale 0, q = 0
    want_q, want_c, want_s = normalise_contours(pts)  # 69 contours: one thread
    vectors = np.concatenate([want_q.reshape(23, -1), rng.normal(size=(23, 57))], axis=1)
    rec = vectors[:, :3 * 200 * 2].reshape(23, 3, 200, 2)
    want_px = denormalise_contours(rec, want_c, want_s)
    names = set()
    run_chunk = features._normalise_chunk

    def chunk(*args):
        names.add(threading.current_thread().name)
        run_chunk(*args)

    monkeypatch.setattr(features, "_normalise_chunk", chunk)
    monkeypatch.setattr(features, "CHUNK_CONTOURS", 5)  # 14 chunks ...
    monkeypatch.setattr(features, "THREAD_CONTOURS", 20)  # ... on threads ...
    monkeypatch.setattr(features, "THREADS", 2)  # ... two of them, whatever the machine's cores
    q, c, s = normalise_contours(pts)
    assert names and all(n.startswith("silpose-block") for n in names)
    for got, want in ((q, want_q), (c, want_c), (s, want_s)):
        assert np.array_equal(got, want, equal_nan=True)
    assert s[7, 1] == 0 and np.all(q[7, 1] == 0)
    assert np.array_equal(denormalise_contours(rec, c, s), want_px, equal_nan=True)
    assert np.array_equal(want_px, rec * want_s[..., None, None] + want_c[..., None, :], equal_nan=True)

def test_frame_noise_variance_is_the_nanmedian_form():
    rng = np.random.default_rng(4)
    obs, rec = rng.normal(size=(12, 4, 200, 2)), rng.normal(size=(12, 4, 200, 2))
    present = rng.random((12, 4)) > 0.3
    present[0] = True
    present[1] = False  # no view: the lowest level
    obs[2, 0, 3] = np.nan  # a NaN residual in a frame with every view
    present[2] = True
    r = np.linalg.norm(obs - rec, axis=-1)
    r = np.where(present[..., None], r, np.nan).reshape(12, -1)
    with np.errstate(invalid="ignore"), np.testing.suppress_warnings() as sup:
        sup.filter(RuntimeWarning)
        sigma2 = (1.4826 * np.nanmedian(r, axis=1)) ** 2 / 2.0
        got = frame_noise_variance(obs, rec, present, 0.01, 10.0)
    levels = 0.01 * 10.0 ** (np.arange(5) / 2.0)
    want = levels[np.argmin(np.abs(np.log(np.maximum(np.nan_to_num(10.0 * sigma2, nan=levels[0]), levels[0]))[:, None]
                                    - np.log(levels)[None, :]), axis=1)]
    assert np.array_equal(got, want)


def test_trimming_a_batch_equals_trimming_each_frame():
    """A view's trim depends on its own input and reconstruction only (robust_infer's second pass looks only at
    the frames re-inferred since the first)."""
    rng = np.random.default_rng(5)
    clean = _contours(rng, (6, 2))
    dirty = clean.copy()
    for i, v in ((1, 0), (4, 1)):  # a spike out and back inserted after point 60, resampled to 200 by arc length
        base = clean[i, v]
        tip = base[60] + np.array([50.0, 0.0])
        out = base[60] + np.linspace(0, 1, 25)[1:, None] * (tip - base[60])
        path = np.concatenate([base[:61], out, out[::-1][1:], base[61:], base[:1]])
        arc = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(path, axis=0), axis=1))]
        at = np.arange(200) * arc[-1] / 200
        dirty[i, v] = np.stack([np.interp(at, arc, path[:, 0]), np.interp(at, arc, path[:, 1])], -1)
    present = np.ones((6, 2), bool)
    out, changed = trim_excursions(dirty, clean, present, ExcursionSettings())
    assert changed[1, 0] and changed[4, 1] and changed.sum() == 2
    for i in range(6):
        o1, c1 = trim_excursions(dirty[i:i + 1], clean[i:i + 1], present[i:i + 1])
        assert np.array_equal(o1[0], out[i]) and np.array_equal(c1[0], changed[i])
