"""The errors of silpose's workflows: bad user input, reported in one line naming the file or folder.

``silpose train`` / ``silpose infer`` turn them into ``silpose <command>: error: <message>``.
"""

from __future__ import annotations


class InputError(ValueError):
    """Bad input to a workflow (file, folder, option); the message names it."""


class TrainingError(InputError):
    """Bad ``silpose train`` input (dataset folder, options)."""


class InferenceInputError(InputError):
    """Bad ``silpose infer`` input; the message names the file or folder."""


class FramesInputError(InferenceInputError):
    """Bad camera frames input (a frames folder, an image folder or a video); the message names the file or folder."""


class RecordingError(InferenceInputError):
    """Bad recording input (``silpose infer --videos``): a video, the videos folder, an option; names the file."""
