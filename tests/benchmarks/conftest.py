"""Benchmark test fixtures. ``benchmarks/`` is not an installed package: put the checkout's root on
``sys.path`` so ``import benchmarks`` works, as ``python -m benchmarks.run`` from the root does."""

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from benchmarks import inputs  # noqa: E402


@pytest.fixture(scope="session")
def tiny_dir(tmp_path_factory):
    """A folder holding the tiny dataset and model that ``--quick`` sections generate without data
    (made once per test session with the real generator and trainer, ``benchmarks.inputs.make_tiny``)."""
    folder = tmp_path_factory.mktemp("bench-tiny")
    inputs.make_tiny(folder, with_model=True)
    return folder


@pytest.fixture
def tiny_cache(tiny_dir, monkeypatch):
    """Point the sections' tiny-input cache at :func:`tiny_dir` (what the runner does for its children)."""
    monkeypatch.setenv(inputs.CACHE_ENV, str(tiny_dir))
    return tiny_dir
