"""The installed silpose version: ``silpose --version`` prints it, reports and dataset cards record it."""

from __future__ import annotations

from importlib.metadata import PackageNotFoundError, version

DISTRIBUTION = "silpose-shared"  # the distribution that installs the ``silpose`` command; every package shares its version


def silpose_version() -> str:
    """The installed silpose version ("unknown" when running from a source tree that was never installed)."""
    try:
        return version(DISTRIBUTION)
    except PackageNotFoundError:
        return "unknown"
