"""Colour shadow rule (silpose.segment.chroma) and colour candidates, against brute-force references,
and a cast shadow with a soft (penumbra) border whose rim the NCC alone leaves."""

from collections import deque

import cv2
import numpy as np
import pytest

from silpose.segment import BackgroundModel
from silpose.segment.chroma import grow_shadows


def _grow_reference(frame, mean, cand, seeds, bounds, chroma_max):
    """Per-pixel loops: alpha = f.m / m.m, cd = |f - alpha m|, then a BFS flood fill from the seeds."""
    h, w = cand.shape
    like = np.zeros((h, w), bool)
    for y in range(h):
        for x in range(w):
            if seeds[y, x]:
                like[y, x] = True
            elif cand[y, x]:
                f = [float(v) for v in frame[y, x]]
                m = [float(v) for v in mean[y, x]]
                mm = sum(v * v for v in m)
                a = sum(p * q for p, q in zip(f, m)) / mm if mm > 0 else 0.0
                cd = sum((p - a * q) ** 2 for p, q in zip(f, m)) ** 0.5
                like[y, x] = bounds[0] <= a <= bounds[1] and cd <= chroma_max
    out = np.zeros((h, w), bool)
    queue = deque(zip(*np.nonzero(seeds)))
    for y, x in queue:
        out[y, x] = True
    while queue:
        y, x = queue.popleft()
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                v, u = y + dy, x + dx
                if 0 <= v < h and 0 <= u < w and like[v, u] and not out[v, u]:
                    out[v, u] = True
                    queue.append((v, u))
    return out


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_grow_shadows_equals_bruteforce(seed):
    rng = np.random.default_rng(seed)
    h, w = 23, 31
    mean = rng.uniform(20, 230, (h, w, 3))
    mean[0, :4] = 0.0  # black background: alpha 0
    gain = rng.uniform(0.2, 1.1, (h, w, 1))
    frame = np.clip(np.rint(mean * gain + rng.normal(0, 4, (h, w, 3))), 0, 255).astype(np.uint8)
    cand = rng.random((h, w)) < 0.7
    seeds = cand & (rng.random((h, w)) < 0.03)
    for bounds, cmax in (((0.25, 1.0), 6.0), ((0.5, 0.9), 3.0), ((0.0, 2.0), 20.0)):
        got = grow_shadows(frame, mean, cand, seeds, bounds, cmax)
        want = _grow_reference(frame, mean, cand, seeds, bounds, cmax)
        assert want.sum() > seeds.sum()  # the rule did grow something
        np.testing.assert_array_equal(got, want)
    assert not grow_shadows(frame, mean, cand, np.zeros_like(seeds), (0.25, 1.0), 6.0).any()  # no seed, no shadow


@pytest.mark.parametrize("k_sigma, min_std", [(3.0, 2.0), (4.0, 0.5)])
def test_colour_candidates_equal_the_float_definition(k_sigma, min_std):
    """RMS over channels of (f_c - mean_c) / max(std_c, min_std) > k_sigma, per pixel in float64."""
    rng = np.random.default_rng(3)
    background = rng.integers(0, 256, (6, 17, 19, 3), dtype=np.uint8)
    background[:, :3] = 255  # std 0: the floor applies
    frames = rng.integers(0, 256, (3, 17, 19, 3), dtype=np.uint8)
    model = BackgroundModel(k_sigma=k_sigma, min_std=min_std, ncc_threshold=None).fit(background)
    got = model.segment_batch(frames, return_stages=True)["candidates"]
    b = background.astype(np.float64)
    z = (frames - b.mean(axis=0)) / np.maximum(b.std(axis=0), min_std)
    rms = np.sqrt((z * z).mean(axis=-1))
    want = rms > k_sigma
    far = np.abs(rms - k_sigma) > 1e-4 * k_sigma  # float32 arithmetic: ignore exact ties
    np.testing.assert_array_equal(got[far], want[far])
    assert far.mean() > 0.99


def _soft_shadow_scene(seed=4, n_bg=20, h=120, w=160, noise=2.0):
    """Textured floor, a person (saturated red, chromatically unlike the floor) standing on a
    cast shadow whose border is a 4-pixel penumbra (the shadow factor ramps from 1 to 0.5)."""
    rng = np.random.default_rng(seed)
    tex = cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), 1.0)
    tex *= 12.0 / tex.std()
    clean = np.empty((h, w, 3), np.float32)
    clean[:] = (110.0, 140.0, 165.0)  # beige floor (BGR)
    clean += tex[..., None] * np.float32([0.8, 1.0, 1.1])
    person = np.zeros((h, w), np.uint8)
    cv2.ellipse(person, (60, 55), (9, 40), 0, 0, 360, 1, -1)
    person = person.astype(bool)
    hard = np.zeros((h, w), np.float32)
    cv2.ellipse(hard, (95, 92), (38, 9), 0, 0, 360, 1.0, -1)  # the shadow, starting at the feet
    soft = cv2.blur(hard, (5, 5))  # penumbra: 4 px ramp
    factor = 1.0 - 0.5 * soft
    img = clean * factor[..., None]
    cloth = cv2.GaussianBlur(rng.standard_normal((h, w)).astype(np.float32), (0, 0), 1.0) * 20.0  # its own texture
    img[person] = (40.0, 40.0, 200.0) + cloth[person][:, None]
    noisy = lambda a: np.clip(np.rint(a + rng.normal(0, noise, a.shape)), 0, 255).astype(np.uint8)
    background = np.stack([noisy(clean) for _ in range(n_bg)])
    shadow = (soft > 0) & ~person
    rim = shadow & (soft < 0.999)
    return background, noisy(img), person, shadow, rim


def test_penumbra_rim_is_removed_and_the_person_kept():
    background, frame, person, shadow, rim = _soft_shadow_scene()
    ncc_only = BackgroundModel(chroma_max=None).fit(background).segment(frame, return_stages=True)
    ours = BackgroundModel().fit(background).segment(frame, return_stages=True)
    rim_cand = (ncc_only["candidates"] & rim).sum()
    kept_old = (ncc_only["shadow_rejected"] & rim).sum()
    kept_new = (ours["shadow_rejected"] & rim).sum()
    fp_old = (ncc_only["final"] & ~person).sum()
    fp_new = (ours["final"] & ~person).sum()
    iou = (ours["final"] & person).sum() / (ours["final"] | person).sum()
    print(f"rim candidates {rim_cand}; kept after NCC {kept_old}, after colour growth {kept_new}; "
          f"final false positives {fp_old} -> {fp_new}; person IoU {iou:.3f}")
    assert rim_cand > 150 and kept_old > 0.3 * rim_cand  # the NCC alone leaves the rim
    assert fp_old > 100  # ... and the final mask keeps it, joined to the feet
    assert kept_new < 0.1 * kept_old and fp_new < 0.1 * fp_old
    assert iou > 0.9


def test_mixing_colour_and_graylevel_background_chunks_is_an_error():
    from silpose.segment import SegmentError

    rng = np.random.default_rng(0)
    colour = rng.integers(0, 256, (3, 8, 9, 3), dtype=np.uint8)
    model = BackgroundModel().partial_fit(colour)
    with pytest.raises(SegmentError, match=r"^frames: graylevel frames after colour ones"):
        model.partial_fit(colour[..., 0])
    BackgroundModel(colour=False).partial_fit(colour).partial_fit(colour[..., 0])  # graylevel model: fine
