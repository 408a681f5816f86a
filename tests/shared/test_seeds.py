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


def test_stream_code_is_stable_crc32():
    import zlib

    assert stream_code("jitter") == zlib.crc32(b"jitter")
