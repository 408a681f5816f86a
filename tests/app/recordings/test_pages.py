"""A recording's run allocates numpy arrays in ordinary pages (``silpose.app.recordings.pages``): numpy's
huge-page request is off during the run, as seen from the run's own progress callback, and restored after it; the
user's ``NUMPY_MADVISE_HUGEPAGE`` wins."""

from __future__ import annotations

import numpy as np

from silpose.app.recordings.pages import ordinary_pages
from silpose.app.recordings.pipeline import RecordingOptions, run_recording

_switch = np.core.multiarray._set_madvise_hugepage


def _now() -> bool:
    """numpy's current huge-page request (read by setting it to itself)."""
    value = _switch(True)
    _switch(value)
    return value


def test_ordinary_pages_switch_numpys_request_off_and_back(monkeypatch):
    monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
    before = _switch(True)
    try:
        with ordinary_pages():
            assert _now() is False
        assert _now() is True
        monkeypatch.setenv("NUMPY_MADVISE_HUGEPAGE", "1")  # the user's choice stands
        with ordinary_pages():
            assert _now() is True
    finally:
        _switch(before)


def test_a_run_allocates_in_ordinary_pages_and_restores_numpys_setting(two_cylinders, tiny_model, tmp_path,
                                                                        monkeypatch):
    monkeypatch.delenv("NUMPY_MADVISE_HUGEPAGE", raising=False)
    before = _switch(True)
    seen = []
    try:
        run_recording(tiny_model, two_cylinders, tmp_path / "out", RecordingOptions(masks=True, overlays=False,
                      max_steps=3), progress=lambda done, total: seen.append(_now()))
        assert seen and not any(seen)
        assert _now() is True
    finally:
        _switch(before)
