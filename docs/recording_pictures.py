"""Draw the README's recording pictures: overlay frames of ``silpose infer --videos`` and its floor plan.

    python docs/recording_pictures.py --model LAB_MODEL.npz [--lab LAB_FOLDER] [--out docs/images]

``LAB_MODEL.npz``: a model of the lab rig (``benchmarks/recordings.py`` trains one; the README's was
trained on 1,600 walkers, M 10, q 30). ``LAB_FOLDER``: a lab recording made by
``silpose.datagen.lab.make_lab_recording`` (default: a new 150-frame one in a temporary folder). The
pictures: ``recording_overlay_crossing.png`` (the four cameras at the first frame where some view of a
person is merged with the other person), ``recording_overlay_apart.png`` (the first frame where both people
are used in all four views) and ``recording_floorplan.png``.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pyarrow.parquet as pq

from silpose.app.recordings.pipeline import RecordingOptions, run_recording
from silpose.datagen.lab import make_lab_recording
from silpose.shared.atomic import atomic_path, write_bytes_atomic

TILE_WIDTH = 400  # px per camera in the 2 x 2 picture


def overlay_frame(overlays: Path, cameras: list[str], frame: int) -> np.ndarray:
    """(H, W, 3) BGR: frame ``frame`` of every camera's overlay video, 2 x 2, each TILE_WIDTH wide."""
    tiles = []
    for cam in cameras:
        cap = cv2.VideoCapture(str(overlays / f"{cam}.mp4"))
        cap.set(cv2.CAP_PROP_POS_FRAMES, frame)
        ok, img = cap.read()
        cap.release()
        if not ok:
            raise RuntimeError(f"{overlays / cam}.mp4: no frame {frame}")
        h, w = img.shape[:2]
        tiles.append(cv2.resize(img, (TILE_WIDTH, round(h * TILE_WIDTH / w)), interpolation=cv2.INTER_AREA))
    sep = np.full((tiles[0].shape[0], 2, 3), 255, np.uint8)
    rows = [np.hstack([tiles[i], sep, tiles[i + 1]]) for i in (0, 2)]
    return np.vstack([rows[0], np.full((2, rows[0].shape[1], 3), 255, np.uint8), rows[1]])


def pick_frames(joints: Path) -> tuple[int, int]:
    """(crossing, apart): the first frame with a merged view, the first with both people in all views."""
    t = pq.read_table(joints, columns=["frame", "n_views", "view_status"]).to_pandas()
    merged = t[t.view_status.apply(lambda v: "merged" in list(v))]
    per_frame = t.groupby("frame").n_views.agg(["min", "size"])
    apart = per_frame[(per_frame["size"] >= 2) & (per_frame["min"] == 4)]
    if merged.empty or apart.empty:
        raise RuntimeError(f"{joints}: no frame with a merged view, or none with both people in every view")
    return int(merged.frame.iloc[0]), int(apart.index[0])


def write_png(path: Path, img: np.ndarray) -> None:
    ok, png = cv2.imencode(".png", img)
    if not ok:
        raise OSError(f"{path}: could not encode")
    write_bytes_atomic(path, png.tobytes())


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", required=True, type=Path)
    ap.add_argument("--lab", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "images")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="silpose-recording-pictures-") as tmp:
        tmp = Path(tmp)
        lab = args.lab or make_lab_recording(tmp / "lab", n_frames=150)
        out = tmp / "out"
        summary = run_recording(str(args.model), lab / "masks", out, RecordingOptions(masks=True, overlays=True))
        cameras = sorted(p.stem for p in (out / "overlays").glob("*.mp4"))
        crossing, apart = pick_frames(out / "joints.parquet")
        first = int(pq.read_table(out / "joints.parquet", columns=["frame"]).column("frame").to_numpy().min())
        first = min(first, 0)  # overlay videos start at the recording's first frame (0 without offsets)
        for name, frame in (("crossing", crossing), ("apart", apart)):
            write_png(args.out / f"recording_overlay_{name}.png", overlay_frame(out / "overlays", cameras, frame - first))
            print(f"{args.out / f'recording_overlay_{name}.png'}: frame {frame}")
        with atomic_path(args.out / "recording_floorplan.png") as dst:
            shutil.copyfile(out / "floorplan.png", dst)
        print(f"{args.out / 'recording_floorplan.png'}; {summary.n_persons} people, {summary.n_steps} steps")


if __name__ == "__main__":
    main()
