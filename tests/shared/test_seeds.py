"""silpose.shared.seeds: one derivation, equal to numpy's SeedSequence recipe it documents."""

import numpy as np
import pytest

from silpose.shared.seeds import derive_rng, stream_code


def test_matches_seedsequence_recipe():
    a = derive_rng(7, 1, 12, 0).random(5)
    b = np.random.default_rng(np.random.SeedSequence([7, 1, 12, 0])).random(5)
    np.testing.assert_array_equal(a, b)


def test_keys_change_the_stream_and_numpy_ints_are_accepted():
    assert derive_rng(7, 1).random() != derive_rng(7, 2).random()
    assert derive_rng(np.int64(7), True).random() == derive_rng(7, 1).random()


@pytest.mark.parametrize("keys", [(), (-1,), (3, -2)])
def test_bad_keys(keys):
    with pytest.raises(ValueError):
        derive_rng(*keys)


def test_stream_codes_and_stream_constants_are_pinned():
    """The keys are part of the data format (a change alters every dataset and report made with them):
    pinned to the literal values the published datasets and reports were made with."""
    from silpose.shared import seeds

    assert [stream_code(n) for n in ("jitter", "patches", "mask")] == [0x9DABE016, 0x002FE8B4, 0x7F6FC330]
    assert stream_code("") == 0 and stream_code("é") == 0x0E048D3E  # CRC-32 of its UTF-8 bytes c3 a9
    assert seeds.SPLIT_CODE == {"train": 0, "test": 1}
    assert (seeds.APPEARANCE_STREAM, seeds.CAMERA_NOISE_STREAM) == (0x5EEDC010, 0x15E0C4)
    assert seeds.NOISE_KIND == {"background": 0, "frames": 1}
    assert (seeds.CHANCE_STREAM, seeds.VALIDATION_STREAM) == (29, 7919)
    assert seeds.MOTION_STREAM == 0x5EED0B7C  # motion-capture draws (clip, frame, mirror, placement)
