"""Evaluation on a frames dataset: segmentation quality and what it costs the pose.

On ``<frames dir>`` (``data/<preset>/frames``: per-camera background and frames, plus the truth
split "test" whose row i is frame i), with the same model and the same frames:

- **segmented**: the camera path of ``silpose infer --frames`` (background subtraction, the largest blob's
  contour, inference; :func:`silpose.app.recordings.one_person.run_one_person`), with the plain posterior
  (no robust inference, no hypotheses) so that the two inputs differ only in their silhouettes;
- **true**: the truth split's clean contours (extracted from the true masks) given to the model.

Measures per frame: mask IoU ``|S & T| / |S | T|`` of the segmented vs the true mask per camera
(:func:`silpose.shared.metrics.mask_iou`; an empty segmentation scores 0; a camera without frames is
left out); pose error (cm, root-relative, :func:`silpose.shared.metrics.pose_error_cm`); one-sided
Chamfer distance D(true clean contour -> reconstruction) in px, mean over the modelled views. Views
the segmentation lost are reconstructed by the model and placed with their true normalisation
(docs/conventions.md, "Evaluation protocol"), like E2.

Outputs in the report folder: ``frames.md`` (tables of mean / median / quartiles), ``frames.parquet``
(one row per frame and input), ``frames_errors.png`` (paper-style box plots) and
``frames_example.png`` (the frame nearest the median segmented pose error, paper Fig. 9 style).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from silpose.app.recordings.one_person import run_one_person
from silpose.app.recordings.pipeline import RecordingOptions
from silpose.shared.atomic import atomic_path, write_text_atomic
from silpose.shared.dataset import DatasetError, load_split
from silpose.shared.metrics import chamfer_errors, mask_iou, place_contours, pose_error_cm

from .errors import EvalInputError
from .plots import paper_boxplot, pyplot, save_figure
from .tables import QUARTILE_HEADERS, fmt, fmt_stats, markdown_table, stats

FILES = ("frames.md", "frames.parquet", "frames_errors.png", "frames_example.png")


def run_frames_evaluation(frames_dir, model, progress=None, chunk: int = 32) -> dict:
    """Run both paths on a frames dataset; returns a dict of per-frame arrays and the pipeline result.

    Keys: sample_id (N,), frames (N,), cameras, iou (N, K) (NaN for cameras without frames),
    pose_cm / chamfer_px (dicts "segmented" / "true" -> (N,)), n_views (dict -> (N,)), status (N, K),
    masks_packed (list of per-frame packed masks), pipeline (OnePersonResult), timings.
    """

    frames_dir = Path(frames_dir)
    try:
        truth = load_split(frames_dir, "test", with_masks=True)
    except DatasetError as exc:
        raise EvalInputError(f"cannot read the truth split of the frames dataset {frames_dir}: {exc}") from exc
    names = list(model.rig_.names) if model.rig_ is not None else []
    if tuple(truth.rig.names) != tuple(names):
        raise EvalInputError(f"{frames_dir}: truth cameras {list(truth.rig.names)} differ from the model's rig {names}")
    K = len(names)
    iou = np.full((len(truth), K), np.nan)
    packed: list = [None] * len(truth)

    def on_chunk(ch) -> None:
        for i, name in enumerate(ch.names):
            j = ch.start + i
            if name != f"{j:05d}" or j >= len(truth):
                raise EvalInputError(f"{frames_dir}/frames: frame {name!r} at position {j} does not name truth row "
                                     f"{j:05d} (the truth split has {len(truth)} rows)")
            per_cam = {}
            for c, m in ch.masks.items():
                k = names.index(c)
                iou[j, k] = mask_iou(m[i], truth.masks[j, k])
                per_cam[c] = np.packbits(m[i])
            packed[j] = per_cam

    # at the rig cameras' own size (work_person_px=0): the masks are scored against the truth's
    opt = RecordingOptions(overlays=False, chunk=chunk, robust=False, hypotheses=0, work_person_px=0)
    fr = run_one_person(model, frames_dir, opt, frames_layout=True, temporal=False, on_chunk=on_chunk,
                        progress=progress)
    n = len(fr.frames)
    if n != len(truth):
        raise EvalInputError(f"{frames_dir}: {n} frames per camera but {len(truth)} truth rows")
    views = list(model.layout_.views)
    sizes = np.array([(truth.rig[v].height, truth.rig[v].width) for v in views])
    true_c = truth.contours[:, views]
    seg = fr.result
    recon = np.where(seg.views_present[..., None, None], seg.contours_px,
                     place_contours(seg.contours_norm, truth.centroid[:, views], truth.scale[:, views]))
    ref = model.infer(truth.contours, input_views=range(model.n_rig_views_))
    out = {"sample_id": truth.sample_id, "frames": fr.frames, "cameras": names, "iou": iou, "status": fr.status,
           "masks_packed": packed, "pipeline": fr, "timings": fr.timings, "pose_cm": {}, "chamfer_px": {},
           "n_views": {"segmented": seg.views_present.sum(1), "true": ref.views_present.sum(1)}}
    for key, res, rc in (("segmented", seg, recon), ("true", ref, ref.contours_px)):
        out["pose_cm"][key] = pose_error_cm(res.joints, truth.joints)
        one, _ = chamfer_errors(true_c, rc, sizes)
        out["chamfer_px"][key] = np.nanmean(one, axis=1)
    return out


def frames_table(ev: dict):
    """One row per frame and input (pandas DataFrame)."""
    rows = []
    for key in ("segmented", "true"):
        for i, sid in enumerate(ev["sample_id"]):
            r = {"sample_id": int(sid), "frame": str(ev["frames"][i]), "input": key,
                 "pose_cm": float(ev["pose_cm"][key][i]), "chamfer_px": float(ev["chamfer_px"][key][i]),
                 "n_views_used": int(ev["n_views"][key][i])}
            for k, c in enumerate(ev["cameras"]):
                r[f"iou_{c}"] = float(ev["iou"][i, k]) if key == "segmented" else np.nan
            r["iou_mean"] = float(np.nanmean(ev["iou"][i])) if key == "segmented" and np.isfinite(ev["iou"][i]).any() else np.nan
            rows.append(r)
    return pd.DataFrame(rows)


def frames_markdown(ev: dict, frames_dir, figures: list[str]) -> str:
    """``frames.md``: IoU per camera; pose and Chamfer from segmented vs true silhouettes."""
    qh = QUARTILE_HEADERS
    iou_rows = [[c, str(int(np.isfinite(ev["iou"][:, k]).sum())), fmt_stats(stats(ev["iou"][:, k]))]
                for k, c in enumerate(ev["cameras"])]
    iou_rows.append(["all cameras", str(int(np.isfinite(ev["iou"]).sum())), fmt_stats(stats(ev["iou"].ravel()))])
    err_rows = []
    for key, label in (("segmented", "segmented silhouettes (camera frames)"), ("true", "true silhouettes")):
        err_rows.append([label, str(stats(ev["pose_cm"][key])["n"]), fmt_stats(stats(ev["pose_cm"][key])),
                         fmt_stats(stats(ev["chamfer_px"][key])), fmt(float(np.mean(ev["n_views"][key])))])
    st = ev["status"]
    counts = {s: int((st == s).sum()) for s in np.unique(st.astype(str))}
    t = ev["timings"]
    parts = [f"# Camera frames — {Path(frames_dir)}", "",
             "The same model on the same frames, given (a) the silhouettes the paper's background subtraction "
             "extracts from the camera frames (`silpose infer --frames`), (b) the true silhouettes. Mask IoU: "
             "segmented vs true mask per camera and frame (empty segmentation = 0). Pose error: cm, root-relative. "
             "Contour error: one-sided Chamfer D(true clean contour -> reconstruction), px, mean over views; views the "
             "segmentation lost are inferred and placed with their true normalisation; n counts frames with a pose "
             "(a frame whose segmentation failed in every view has none).", "",
             "## Mask IoU", "",
             markdown_table(["camera", "n", *[f"IoU {h}" for h in qh]], iou_rows), "",
             "## Pose and contour errors", "",
             markdown_table(["input", "n", *[f"pose {h} (cm)" for h in qh], *[f"Chamfer {h} (px)" for h in qh], "views used (mean)"],
                    err_rows), "",
             "Segmentation status over (frame, camera): " + ", ".join(f"{k} {v}" for k, v in counts.items()) + ".", "",
             "Seconds: " + ", ".join(f"{k} {v:.2f}" for k, v in t.items()) + ".", ""]
    parts += [f"![{f}]({f})" for f in figures] + [""]
    return "\n".join(parts)


def plot_frames(ev: dict, path) -> Path:
    """Box plots: IoU per camera; pose and Chamfer errors from segmented vs true silhouettes."""
    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(12, 4))
    paper_boxplot(axes[0], [ev["iou"][:, k] for k in range(len(ev["cameras"]))], list(ev["cameras"]), "mask IoU",
                  "Segmentation vs true masks")
    labels = ["segmented", "true"]
    paper_boxplot(axes[1], [ev["pose_cm"][k] for k in labels], labels, "pose error (cm)", "Pose")
    paper_boxplot(axes[2], [ev["chamfer_px"][k] for k in labels], labels, "Chamfer true→recon (px)", "Contours")
    fig.suptitle("Camera frames: segmented vs true silhouettes, same model and frames")
    return save_figure(fig, path)


def example_overlay(ev: dict, model, frames_dir, path) -> Path | None:
    """Paper Fig. 9-style figure of the frame whose segmented pose error is nearest the median."""
    from silpose.app.recordings.frames_source import open_frames_folder
    from silpose.app.recordings.sources import CameraReader

    from .frames_figure import overlay_figure

    pose = ev["pose_cm"]["segmented"]
    if not np.isfinite(pose).any():
        return None
    j = int(np.nanargmin(np.abs(pose - np.nanmedian(pose))))
    images = {}
    for c, src in open_frames_folder(frames_dir, model.rig_).recording.sources.items():
        reader = CameraReader(src, grey=False)
        try:
            reader.seek(j)
            images[c] = reader.read()
        finally:
            reader.close()
    rig, fr = model.rig_, ev["pipeline"]
    masks = []
    for c in rig.names:
        p = ev["masks_packed"][j].get(c) if ev["masks_packed"][j] else None
        cam = rig[list(rig.names).index(c)]
        masks.append(None if p is None else np.unpackbits(p, count=cam.width * cam.height).reshape(cam.height, cam.width).astype(bool))
    recon = np.full((len(rig),) + fr.result.contours_px.shape[2:], np.nan)
    recon[list(fr.result.views)] = fr.result.contours_px[j]
    return overlay_figure(path, [images.get(c) for c in rig.names], masks, recon,
                          list(fr.status[j]), fr.result.joints[j], rig,
                          f"frame {fr.frames[j]} (median segmented pose error {pose[j]:.1f} cm; "
                          f"from true silhouettes {ev['pose_cm']['true'][j]:.1f} cm)")


def write_frames_report(frames_dir, model, out_dir, progress=None) -> tuple[dict, dict[str, Path]]:
    """Run :func:`run_frames_evaluation` and write the four files; returns (evaluation, written paths)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ev = run_frames_evaluation(frames_dir, model, progress=progress)
    written = {}
    with atomic_path(out / "frames.parquet") as tmp:
        pq.write_table(pa.Table.from_pandas(frames_table(ev), preserve_index=False), tmp, compression="zstd")
    written["frames_results"] = out / "frames.parquet"
    written["frames_errors"] = plot_frames(ev, out / "frames_errors.png")
    ex = example_overlay(ev, model, frames_dir, out / "frames_example.png")
    if ex is not None:
        written["frames_example"] = ex
    md = frames_markdown(ev, frames_dir, [p.name for k, p in written.items() if p.suffix == ".png"])
    write_text_atomic(out / "frames.md", md)
    written["frames_summary"] = out / "frames.md"
    return ev, written


def frames_note(ev: dict) -> str:
    """One line for summary.md's notes."""
    return (f"camera frames (frames.md): mean mask IoU {np.nanmean(ev['iou']):.3f}; pose error mean "
            f"{np.nanmean(ev['pose_cm']['segmented']):.2f} cm from segmented vs {np.nanmean(ev['pose_cm']['true']):.2f} cm "
            f"from true silhouettes; Chamfer {np.nanmean(ev['chamfer_px']['segmented']):.2f} vs "
            f"{np.nanmean(ev['chamfer_px']['true']):.2f} px ({len(ev['sample_id'])} frames)")
