"""characters.png: train vs test silhouettes side by side, written with preview.png and embedded in the card
only when both splits exist."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.datagen.character_sheet import CHARACTERS_NAME, choose, crop_cell, pick_characters
from silpose.datagen.characters import character_kind
from silpose.datagen.pipeline import generate
from silpose.datagen.testing import SYNTH_RENDER, tiny_config, tiny_config_toml
from silpose.shared.dataset import load_split


def _generate(tmp_path, train: int, test: int):
    cfg = tiny_config(tmp_path, tiny_config_toml(seed=4, shard_size=4, train=train, test=test))
    out = tmp_path / "tiny"
    generate(cfg, out, workers=1, render=SYNTH_RENDER, progress=False, preview=True, card=True)  # like `silpose gen`
    return out


def _non_white(img: np.ndarray) -> float:
    """Share of pixels darker than near-white (the silhouettes are drawn dark grey on white)."""
    return float(np.mean(img.min(axis=2) < 200))


def test_characters_png_written_decodes_and_is_embedded(tmp_path):
    out = _generate(tmp_path, train=8, test=8)
    png = out / CHARACTERS_NAME
    assert png.is_file() and not list(out.glob(".*.tmp"))
    bgr = cv2.imread(str(png), cv2.IMREAD_COLOR)
    assert bgr is not None and bgr.ndim == 3 and bgr.shape[2] == 3
    h, w = bgr.shape[:2]
    assert 250 < h < 2000 and 600 < w < 3000 and w > h
    # independently of the drawing code: both halves hold silhouettes (dark pixels, varied intensities)
    left, right = bgr[:, : w // 2 - 10], bgr[:, w // 2 + 10:]
    for half in (left, right):
        assert 0.03 < _non_white(half) < 0.6
        assert half.astype(np.float64).std() > 20
    card = (out / "README.md").read_text()
    assert card.count(f"]({CHARACTERS_NAME})") == 1
    # embedded in the "train vs test characters" section, before its table, with a caption saying what differs
    section = card.index("### train vs test characters (documented)")
    assert section < card.index(f"]({CHARACTERS_NAME})") < card.index("| field | train | test |")
    assert "straight cones from the hips" in card and "bulky jackets" in card


def test_no_characters_png_without_a_test_split(tmp_path):
    out = _generate(tmp_path, train=8, test=0)
    assert (out / "preview.png").is_file()
    assert not (out / CHARACTERS_NAME).exists()
    assert CHARACTERS_NAME not in (out / "README.md").read_text()


def test_picked_samples_are_labelled_with_their_character_kind(tmp_path):
    out = _generate(tmp_path, train=12, test=4)
    for split, n in (("train", 8), ("test", 4)):
        picks = pick_characters(out, split)
        assert len(picks) == n
        ref = load_split(out, split, columns=["subject"], with_masks=True)
        kinds = character_kind(ref.subject)
        for p in picks:
            row = int(np.flatnonzero(ref.sample_id == p["sample_id"])[0])
            assert p["kind"] == kinds[row]
            assert any(np.array_equal(p["mask"], ref.masks[row, k]) for k in range(ref.n_views))
        again = pick_characters(out, split)  # deterministic
        assert [(a["sample_id"], a["view"]) for a in again] == [(b["sample_id"], b["view"]) for b in picks]


def test_choose_prefers_distinct_garment_kinds_then_fills_up():
    kinds = np.array(["hair:near", "hair:near", "trousers:flared", "coat:bell", "coat:bell", "skirt:tulip+jacket",
                      "nothing"], dtype=object)
    assert choose(kinds, 4).tolist() == [3, 5, 2, 0]
    assert choose(kinds, 7).tolist() == [3, 5, 2, 0, 6, 1, 4]
    assert choose(kinds[:2], 8).tolist() == [0, 1]


def test_crop_cell_keeps_the_shape_at_equal_height():
    mask = np.zeros((240, 320), np.uint8)
    mask[50:150, 100:140] = 1  # 100 px tall, 40 px wide
    cell = crop_cell(mask, height=160, aspect=0.75)
    assert cell.shape == (160, 120)
    ys, xs = np.nonzero(cell)
    tall, wide = ys.max() - ys.min() + 1, xs.max() - xs.min() + 1
    assert tall == pytest.approx(160 / 1.12, abs=3) and wide / tall == pytest.approx(0.4, abs=0.03)
    assert crop_cell(np.zeros((10, 10), np.uint8)).sum() == 0
