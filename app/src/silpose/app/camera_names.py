"""Which camera a file is of, from its name: the naming rule shared by recordings and rig import.

Datasets name their files after the camera with more around it: CMU Panoptic's ``hd_00_00.mp4`` is camera
``00_00``, AIST++'s ``gBR_sBM_c01_d04_mBR0_ch01.mp4`` camera ``c01``, Human3.6M's ``Walking.54138969.mp4``
camera ``54138969``. :func:`camera_in_stem` reads a stem as the camera whose name's *words* (runs of letters
and digits, lower case) appear consecutively among the stem's words, so ``cam10`` is not ``cam1``.
"""

from __future__ import annotations

import re

__all__ = ["name_words", "camera_in_stem"]


def name_words(text: str) -> list[str]:
    """``"Walking.54138969"`` -> ``["walking", "54138969"]``: the runs of letters and digits, lower case."""
    return [w for w in re.split(r"[^0-9a-z]+", str(text).lower()) if w]


def camera_in_stem(stem: str, cameras) -> list[str]:
    """The cameras a file stem names: ``[stem]`` when it is a camera's name, else every camera whose name's
    words (letters and digits, lower case) appear consecutively among the stem's words (``hd_00_00`` holds
    ``00_00``; ``cam10`` does not hold ``cam1``), longest names first, and none nested in another match."""
    if stem in cameras:
        return [stem]
    words = name_words(stem)
    found = []
    for cam in sorted(cameras, key=lambda c: -len(name_words(c))):
        cw = name_words(cam)
        spans = [set(range(i, i + len(cw))) for i in range(len(words) - len(cw) + 1)
                 if cw and words[i : i + len(cw)] == cw]
        free = [span for span in spans if not any(span <= used for _, used in found)]
        if free:
            found.append((cam, free[0]))
    return [c for c, _ in found]
