"""The evaluation's input error (its own module so that every other eval module can raise it)."""

from __future__ import annotations

__all__ = ["EvalInputError"]


class EvalInputError(FileNotFoundError):
    """Data or model missing or unreadable; the message tells the user what to run."""
