"""Benchmark of contour extraction on 4-view 320x240 silhouettes (the default rig).

Run: ``uv run --frozen python -m silpose.shared.bench_contours [--samples N]``.

Silhouettes are a thick stick figure (19 joints of a standing pose, limbs drawn 9-14 px wide with
OpenCV) seen by the default rig, at random positions in the workspace. Prints, per sample of 4
views, the time of :func:`extract_contours` next to the OpenCV calls it is built on, as ratios to
``cv2.findContours`` measured in the same process (timings are noisy on a shared machine).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from .camera import default_rig
from .contours import extract_contours
from .skeleton import BONES, JOINT_INDEX

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
    import cv2

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


def main(argv: list[str] | None = None) -> None:
    import cv2

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=200)
    args = parser.parse_args(argv)
    masks = stick_masks(args.samples)

    def find(sample):
        for m in sample:
            cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)

    def components(sample):
        for m in sample:
            cv2.connectedComponentsWithStats(m, connectivity=8)

    rows = [
        ("cv2.findContours (reference)", _time(find, masks)),
        ("cv2.connectedComponentsWithStats", _time(components, masks)),
        ("extract_contours, n=200", _time(lambda s: extract_contours(s, 200), masks)),
    ]
    ref = rows[0][1]
    lengths = np.concatenate([extract_contours(s)["length"] for s in masks[:50]])
    print(f"{args.samples} samples x 4 views, 320x240, stick-figure silhouettes; cv2 threads: {cv2.getNumThreads()}")
    print("| stage | ms per sample (4 views) | ratio to findContours |")
    print("|---|---:|---:|")
    for name, sec in rows:
        print(f"| {name} | {sec * 1e3:.3f} | {sec / ref:.1f} |")
    print(f"raw contour length: median {np.median(lengths):.0f} px (min {lengths.min():.0f}, max {lengths.max():.0f})")


if __name__ == "__main__":
    main()
