"""Which camera a file is of, from its name: the naming rule shared by recordings and rig import.

Datasets name their files after the camera with more around it: CMU Panoptic's ``hd_00_00.mp4`` is camera
``00_00``, AIST++'s ``gBR_sBM_c01_d04_mBR0_ch01.mp4`` camera ``c01``, Human3.6M's ``Walking.54138969.mp4``
camera ``54138969``. :func:`camera_in_stem` reads a stem as the camera whose name's *words* (runs of letters
and digits, lower case) appear consecutively among the stem's words, so ``cam10`` is not ``cam1``.

Calibration tools and recording scripts also spell one camera differently: Pose2Sim's and anipose's calibrations
name ``cam_01`` what the videos call ``cam01`` or ``cam1``. When no camera's words match, a camera whose name
mixes letters and a number is matched by its *tokens* (:func:`name_tokens`: runs of letters, and runs of digits
read as numbers), so ``cam_01`` = ``cam01`` = ``Cam1`` = ``cam-1``, and still ``cam10`` != ``cam1`` and
``camera1`` != ``cam1``. Names that are only numbers (Human3.6M's ``54138969``, CMU's ``00_00``) keep the exact
rule: a stem's other numbers (takes, dates) would match them.
"""

from __future__ import annotations

import re

__all__ = ["name_words", "name_tokens", "camera_in_stem"]


def name_words(text: str) -> list[str]:
    """``"Walking.54138969"`` -> ``["walking", "54138969"]``: the runs of letters and digits, lower case."""
    return [w for w in re.split(r"[^0-9a-z]+", str(text).lower()) if w]


def name_tokens(text: str) -> list:
    """``"Cam_01"`` -> ``["cam", 1]``: the runs of letters (lower case) and the runs of digits as numbers."""
    return [int(t) if t.isdigit() else t for t in re.findall(r"[a-z]+|[0-9]+", str(text).lower())]


def camera_in_stem(stem: str, cameras) -> list[str]:
    """The cameras a file stem names: ``[stem]`` when it is a camera's name, else every camera whose name's
    words (letters and digits, lower case) appear consecutively among the stem's words (``hd_00_00`` holds
    ``00_00``; ``cam10`` does not hold ``cam1``), longest names first, and none nested in another match; when none
    does, the same by tokens (:func:`name_tokens`) for the cameras whose names mix letters and a number (module
    doc: ``cam01`` holds ``cam_01``)."""
    if stem in cameras:
        return [stem]
    found = _held(name_words(stem), cameras, name_words)
    if not found:
        mixed = [c for c in cameras if any(isinstance(t, int) for t in name_tokens(c))
                 and any(isinstance(t, str) for t in name_tokens(c))]
        found = _held(name_tokens(stem), mixed, name_tokens)
    return found


def _held(words: list, cameras, split) -> list[str]:
    """The cameras whose ``split(name)`` appears consecutively in ``words``, longest first, none nested in another
    match."""
    found = []
    for cam in sorted(cameras, key=lambda c: -len(split(c))):
        cw = split(cam)
        spans = [set(range(i, i + len(cw))) for i in range(len(words) - len(cw) + 1)
                 if cw and words[i : i + len(cw)] == cw]
        free = [span for span in spans if not any(span <= used for _, used in found)]
        if free:
            found.append((cam, free[0]))
    return [c for c, _ in found]
