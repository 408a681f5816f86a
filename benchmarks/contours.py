"""Contour extraction on 4-view 320x240 silhouettes (the default rig), against ``cv2.findContours``.

Section ``contours`` of ``python -m benchmarks.run``. Silhouettes are a thick stick figure (19
joints of a standing pose, limbs drawn 9-14 px wide with OpenCV) seen by the default rig, at random
positions in the workspace. Rows: per sample of 4 views, the time of
:func:`silpose.shared.contours.extract_contours` next to the OpenCV calls it is built on, as ratios
to ``cv2.findContours`` measured in the same process (timings are noisy on a shared machine).
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from silpose.shared.camera import default_rig
from silpose.shared.contours import extract_contours
from silpose.shared.skeleton import BONES, JOINT_INDEX

# A standing pose, metres, pelvis at 0.95 m (x forward, y left, z up).
_POSE = {
    "pelvis": (0, 0, 0.95), "spine": (0, 0, 1.2), "neck": (0, 0, 1.5), "head": (0, 0, 1.62),
    "head_top": (0, 0, 1.75), "l_shoulder": (0, 0.19, 1.45), "l_elbow": (0.05, 0.24, 1.18),
    "l_wrist": (0.1, 0.25, 0.93), "r_shoulder": (0, -0.19, 1.45), "r_elbow": (0.05, -0.24, 1.18),
    "r_wrist": (0.1, -0.25, 0.93), "l_hip": (0, 0.1, 0.93), "l_knee": (0.03, 0.11, 0.5),
    "l_ankle": (0, 0.11, 0.08), "l_toe": (0.15, 0.11, 0.02), "r_hip": (0, -0.1, 0.93),
    "r_knee": (0.03, -0.11, 0.5), "r_ankle": (0, -0.11, 0.08), "r_toe": (0.15, -0.11, 0.02),
}  # fmt: skip


def stick_masks(n_samples: int, seed: int = 0) -> np.ndarray:
    """(n_samples, 4, 240, 320) uint8 silhouettes of the stick figure at random workspace positions."""
    rig = default_rig()
    joints = np.array([_POSE[name] for name in sorted(JOINT_INDEX, key=JOINT_INDEX.get)], float)
    rng = np.random.default_rng(seed)
    w, h = rig.image_size
    out = np.zeros((n_samples, len(rig), h, w), np.uint8)
    for s in range(n_samples):
        offset = np.append(rng.uniform(-1.2, 1.2, 2), 0.0)
        px = rig.project(joints + offset)  # (4, 19, 2)
        for v in range(len(rig)):
            for a, b in BONES:
                width = 14 if b <= 4 else 9
                pa, pb = np.round(px[v, [a, b]]).astype(int)
                cv2.line(out[s, v], tuple(pa), tuple(pb), 1, width)
            cv2.circle(out[s, v], tuple(np.round(px[v, JOINT_INDEX["head"]]).astype(int)), 8, 1, -1)
    return out


def _time(fn, masks: np.ndarray, repeats: int = 3) -> float:
    """Best of ``repeats`` mean seconds per sample of ``fn(sample_masks)``."""
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for sample in masks:
            fn(sample)
        best = min(best, (time.perf_counter() - t0) / len(masks))
    return best


def run(n_samples: int = 200, repeats: int = 3, n_points: int = 200, seed: int = 0) -> list[dict]:
    """Rows ``{"stage", "samples", "ms_per_sample", "ratio_to_findcontours"}`` (best of ``repeats``
    mean times per sample of 4 views; ratio = ms_per_sample / that of the cv2.findContours row, the
    first), the extract_contours row adding the raw contour length (median, min, max px, first 50 samples)."""
    masks = stick_masks(n_samples, seed)

    def find(sample):
        for m in sample:
            cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)

    def components(sample):
        for m in sample:
            cv2.connectedComponentsWithStats(m, connectivity=8)

    timed = [
        ("cv2.findContours (reference)", _time(find, masks, repeats)),
        ("cv2.connectedComponentsWithStats", _time(components, masks, repeats)),
        (f"extract_contours, n={n_points}", _time(lambda s: extract_contours(s, n_points), masks, repeats)),
    ]
    ref = timed[0][1]
    rows = [{"stage": name, "samples": n_samples, "ms_per_sample": 1e3 * sec, "ratio_to_findcontours": sec / ref}
            for name, sec in timed]
    lengths = np.concatenate([extract_contours(s)["length"] for s in masks[:50]])
    rows[-1].update(contour_px_median=float(np.median(lengths)), contour_px_min=float(lengths.min()),
                    contour_px_max=float(lengths.max()), cv2_threads=cv2.getNumThreads())
    return rows
