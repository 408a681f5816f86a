"""Identities (``silpose infer --videos``): ids and identity switches of four walkers crossing, masks and colour.

Section ``identities`` of ``python -m benchmarks.run``; also ``python -m benchmarks.identities --work DIR``
(keeps the recording and model in ``DIR`` and reuses them on the next call). Inputs (not timed): the lab
recording of :mod:`silpose.datagen.lab` with :data:`~silpose.datagen.lab.FOUR_WALKERS` (four walkers of
different statures and builds crossing in front of four 644x486 cameras on one wall, ``n_frames`` frames at
25 fps, lossy mask videos); colour videos of the same frames, each walker painted in their own shirt and
trousers colours over a textured room (:func:`silpose.segment.composite.composite_people`, nearer walkers
over farther ones), with an empty-room clip per camera; a model of the lab rig trained on ``train`` walkers
(tiny hyperparameters: the tracker does not depend on the model).

The same four people on the same paths, timed so that nobody walks through anybody
(:data:`~silpose.datagen.lab.FOUR_WALKERS_APART`: pelvises at least 0.56 m apart; in the first recording walker 2 is
within 0.3 m of another in 23 % of the frames, which real people never are), masks and colour: what a real recording
of four people walking should give. Further inputs: the mask videos with walkers hidden from every camera for 1.6-2
s (:data:`HIDDEN`; two at once), made from the walkers' own masks; and the walkers apart as a real background
subtraction gives them (:func:`degraded_videos`: holes, bites and stuck-on blobs, a body cut at the waist or without
its legs in some views, specks of clutter). Rows ``identities``, one per input and tracker (``appearance``: with the
per-person appearance model, :mod:`silpose.app.recordings.appearance`; ``motion only``: without it; on the third
input also ``appearance, --max-people 4``): ids, identity switches, person-frames found, rows off every true person,
the share of the joints inside the person's own silhouette (2 px) in the views used
(:mod:`benchmarks.recording_scores`), time steps/s.

Measured 2026-12-05 (``python -m benchmarks.identities``, 200 frames, 2-core machine, appearance tracker; ids /
switches / person-frames paired of 800 / rows off every person / joints inside): walkers passing through each other,
masks 5 / 11 / 635 / 9 / 0.940, colour 4 / 7 / 582 / 6 / 0.937; walkers apart, masks 4 / 4 / 768 / 0 / 0.987,
colour 4 / 5 / 728 / 0 / 0.983 (motion only: the same apart, 13 and 5 switches through each other); apart and
degraded, masks 4 / 6 / 753 / 3 / 0.976 (either tracker). Apart, the
masks' switches are two brief swaps (1 and 2 frames) where walkers 0 and 1 pass 0.6 m apart; colour's are those and
one lasting swap of walkers 2 and 3 at frame 26.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from . import subproc

N_FRAMES, TRAIN = 200, 120
#: walker -> (first, last + 1) frames hidden from every camera (behind a pillar, out of the room): two at once,
#: so a re-emerging walker must be told from the other lost one
HIDDEN = {0: (40, 80), 3: (45, 85), 2: (110, 160)}


def make_inputs(work: Path, n_frames: int = N_FRAMES, train: int = TRAIN) -> tuple[Path, Path]:
    """The recording (with ``colour/`` and ``empty/``) and the model in ``work``, made when missing."""
    import numpy as np

    from silpose.datagen.lab import FOUR_WALKERS, lab_rig, make_lab_recording

    from .recordings import TINY_MODEL, _train

    lab, model = work / "lab", work / "train" / "lab.npz"
    if not (lab / "truth.npz").is_file():
        make_lab_recording(lab, walkers=FOUR_WALKERS, n_frames=n_frames)
    if not (lab / "colour").is_dir():
        colour_videos(lab, lab_rig())
    if not (lab / "hidden").is_dir():
        hidden_videos(lab, lab_rig(), HIDDEN)
    if not model.is_file():
        (work / "train").mkdir(parents=True, exist_ok=True)
        _train(work / "train", train, 100, TINY_MODEL)
    assert np.load(lab / "truth.npz")["joints"].shape[0] == n_frames
    return lab, model


def make_apart(work: Path, n_frames: int = N_FRAMES) -> Path:
    """The recording of :data:`~silpose.datagen.lab.FOUR_WALKERS_APART` (with ``colour/``, ``empty/`` and
    ``degraded/``) in ``work/apart``, made when missing."""
    from silpose.datagen.lab import FOUR_WALKERS_APART, lab_rig, make_lab_recording

    lab = work / "apart"
    if not (lab / "truth.npz").is_file():
        make_lab_recording(lab, walkers=FOUR_WALKERS_APART, n_frames=n_frames)
    if not (lab / "colour").is_dir():
        colour_videos(lab, lab_rig())
    if not (lab / "degraded").is_dir():
        degraded_videos(lab, lab_rig())
    return lab


#: the degraded input (:func:`degraded_videos`): per walker and view, holes biting into the outline and blobs
#: stuck to it (:func:`silpose.eval.noise.corrupt_mask`: counts, radii px), the share of views cut at the waist or
#: losing the legs; per image, specks of clutter (mean count, radius px up to)
DEGRADED = {"holes": 3, "hole_px": 4.0, "blobs": 2, "blob_px": 4.0, "cut": 0.1, "legs": 0.05, "specks": 10, "speck_px": 8}


def degraded_videos(lab: Path, rig, seed: int = 0, spec: dict = DEGRADED) -> None:
    """``lab/degraded/<camera>.mp4``: the lab's walkers as a real background subtraction gives them
    (:data:`DEGRADED`): each walker's clean mask in each view with holes and stuck-on blobs, in some views cut in
    two at the waist (a dark belt) or without the legs (trousers the colour of the floor), specks of clutter about
    the image; then the OR of the walkers, through JPEG and mp4v (:func:`silpose.datagen.lab.lossy`). Seeded."""
    import cv2
    import numpy as np

    from silpose.datagen.lab import LAB_FPS, lossy, unpack_masks
    from silpose.eval.noise import corrupt_mask

    rng = np.random.default_rng(seed)
    masks = unpack_masks(np.load(lab / "truth.npz"))  # (T, P, K, H, W)
    (lab / "degraded").mkdir(exist_ok=True)
    for k, cam in enumerate(rig):
        w = cv2.VideoWriter(str(lab / "degraded" / f"{cam.name}.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), LAB_FPS,
                            (cam.width, cam.height), isColor=False)
        for f in range(len(masks)):
            img = np.zeros((cam.height, cam.width), np.uint8)
            for m in masks[f, :, k]:
                if not m.any():
                    continue
                m = corrupt_mask(m, rng, n_holes=spec["holes"], hole_radius=spec["hole_px"], n_blobs=spec["blobs"],
                                 blob_radius=spec["blob_px"])
                ys = np.flatnonzero(m.any(axis=1))
                top, height = ys[0], ys[-1] + 1 - ys[0]
                u = rng.random()
                if u < spec["cut"]:
                    waist = int(top + height * rng.uniform(0.4, 0.6))
                    m[waist:waist + int(rng.integers(2, 6))] = 0
                elif u < spec["cut"] + spec["legs"]:
                    m[int(top + 0.55 * height):] = 0
                img |= m
            for _ in range(rng.poisson(spec["specks"])):
                cv2.circle(img, (int(rng.integers(cam.width)), int(rng.integers(cam.height))),
                           int(rng.integers(1, spec["speck_px"] + 1)), 1, -1)
            w.write(lossy(img * np.uint8(255)))
        w.release()


def colour_videos(lab: Path, rig, n_background: int = 20) -> None:
    """``lab/colour/<camera>.mp4`` (each walker in their own clothes, :func:`~silpose.segment.composite.composite_people`)
    and ``lab/empty/<camera>.mp4`` (empty-room clips)."""
    import cv2
    import numpy as np

    from silpose.datagen.lab import LAB_FPS, unpack_masks
    from silpose.segment.composite import background_frames, composite_people, room

    truth = np.load(lab / "truth.npz")
    masks = unpack_masks(truth)  # (T, P, K, H, W)
    pelvis = truth["joints"][:, :, 0]  # (T, P, 3)
    for d in ("colour", "empty"):
        (lab / d).mkdir(exist_ok=True)
    for k, cam in enumerate(rig):
        size = (cam.width, cam.height)
        clean = room(k, size)
        depth = cam.to_camera(pelvis.reshape(-1, 3))[:, 2].reshape(pelvis.shape[:2])
        for path, frames in ((lab / "colour" / f"{cam.name}.mp4",
                              (composite_people(masks[f, :, k], truth["clothing_bgr"], np.argsort(-depth[f]), k, f,
                                                clean=clean) for f in range(len(masks)))),
                             (lab / "empty" / f"{cam.name}.mp4", iter(background_frames(k, size, n_background)))):
            w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), LAB_FPS, size)
            for img in frames:
                w.write(img)
            w.release()


def hidden_videos(lab: Path, rig, hidden: dict) -> None:
    """``lab/hidden/<camera>.mp4``: the lab's mask videos with walkers left out of some frames (``hidden``:
    walker -> (first, stop) frame), made like the lab's own (the OR of the walkers' clean masks, through JPEG
    and mp4v: :func:`silpose.datagen.lab.lossy`)."""
    import cv2
    import numpy as np

    from silpose.datagen.lab import LAB_FPS, lossy, unpack_masks

    masks = unpack_masks(np.load(lab / "truth.npz"))  # (T, P, K, H, W)
    shown = np.ones(masks.shape[:2], bool)
    for p, (a, b) in hidden.items():
        shown[a:b, p] = False
    (lab / "hidden").mkdir(exist_ok=True)
    for k, cam in enumerate(rig):
        w = cv2.VideoWriter(str(lab / "hidden" / f"{cam.name}.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), LAB_FPS,
                            (cam.width, cam.height), isColor=False)
        for f in range(len(masks)):
            w.write(lossy((masks[f, shown[f], k].any(axis=0) * 255).astype(np.uint8)))
        w.release()


def measure(model: str, videos: str, out: str, background: str | None, appearance: bool, max_people: int = 0) -> dict:
    """Child side: one pipeline run, scored against the truth beside ``videos``."""
    import time

    import numpy as np

    from benchmarks.recording_scores import joints_inside, read_rows, read_view_status, score_rows
    from silpose.app.recordings.pipeline import RecordingOptions, run_recording
    from silpose.datagen.lab import unpack_masks
    from silpose.model.persistence import load_model

    from .recordings import warm_compiled

    warm_compiled()
    t0 = time.perf_counter()
    opt = RecordingOptions(masks=background is None, background=None if background is None else Path(background),
                           overlays=False, hypotheses=0)
    if not appearance:
        opt.appearance = False
    if max_people:
        opt.max_people = max_people
    s = run_recording(model, videos, out, opt)
    wall = time.perf_counter() - t0
    truth = np.load(Path(videos).parent / "truth.npz")
    rows = read_rows(Path(out) / "joints.parquet")
    sc = score_rows(rows, truth["joints"])
    inside = joints_inside(rows, read_view_status(Path(out) / "joints.parquet"), sc["per_row"]["paired"],
                           unpack_masks(truth), list(load_model(model).rig_))
    return {"ids": sc["persons"], "identity_switches": sc["identity_switches"], "person_frames": sc["person_frames"],
            "paired": sc["paired"], "false_rows": sc["false_rows"], "joints_inside": inside["share"],
            "steps_per_s": s.n_steps / wall}


def run(n_frames: int = N_FRAMES, train: int = TRAIN, work: str | None = None, colour: bool = True,
        trackers: tuple = ("appearance", "motion only")) -> list[dict]:
    """Make the inputs (in ``work``, kept; else a temporary folder), run and score (module docstring)."""
    with tempfile.TemporaryDirectory(prefix="silpose-bench-ids-") as tmp:
        folder = Path(work) if work else Path(tmp)
        lab, model = make_inputs(folder, n_frames, train)
        apart = make_apart(folder, n_frames)
        rows = []
        inputs = ([("mask videos", lab / "masks", None)] + ([("colour videos", lab / "colour", lab / "empty")] if colour else [])
                  + [("mask videos, walkers hidden " + ", ".join(f"{p} {a}-{b}" for p, (a, b) in HIDDEN.items()),
                      lab / "hidden", None)]
                  + [("mask videos, walkers apart", apart / "masks", None),
                     ("mask videos, walkers apart, degraded", apart / "degraded", None)]
                  + ([("colour videos, walkers apart", apart / "colour", apart / "empty")] if colour else []))
        for label, videos, background in inputs:
            for tracker in trackers + (("appearance, --max-people 4",) if "hidden" in label else ()):
                out = Path(tmp) / f"out-{len(rows)}"
                res = subproc.call("benchmarks.identities", "measure", dict(model=str(model), videos=str(videos), out=str(out),
                                                              background=None if background is None else str(background),
                                                              appearance=tracker.startswith("appearance"),
                                                              max_people=4 if "max-people" in tracker else 0))
                if res.error:
                    raise RuntimeError(f"identities: {label}, {tracker} failed ({res.error})")
                rows.append({"name": "identities", "input": label, "tracker": tracker, "frames": n_frames, **res.value})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--work", default=None, help="folder keeping the recording and model between runs")
    ap.add_argument("--frames", type=int, default=N_FRAMES)
    ap.add_argument("--no-colour", action="store_true")
    ap.add_argument("--trackers", default="appearance,motion only")
    a = ap.parse_args(argv)
    for row in run(a.frames, work=a.work, colour=not a.no_colour, trackers=tuple(a.trackers.split(","))):
        print(json.dumps(row))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
