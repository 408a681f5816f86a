"""Held-out clips played as recordings: each frame's own answer against the choice along the frames.

``silpose infer`` on a recording of one person keeps the top 8 hypotheses of every frame and chooses among them
along the frames (``silpose.app.inference.apply_temporal``: the Viterbi path of
:func:`silpose.model.hypotheses.temporal_choice`, one track per sequence here, and the chosen hypothesis as the
answer, :func:`silpose.model.hypotheses.sequence_answer`). The test split holds lone frames, so the other experiments
measure the frame-by-frame answer only. Here test samples are played on through :data:`SEQUENCE_LENGTH`
consecutive frames of their own (held-out) clip, or of their walk, with their own body, heading and floor
position (:mod:`silpose.datagen.sequences`, rendered by the dataset's renderer in a spawned worker), given the
evaluation's test noise, and inferred as ``silpose infer`` infers camera recordings: robust, every view, 8
hypotheses. Per frame, with the paper's pose error (cm, root-relative, :func:`silpose.shared.metrics.pose_error_cm`):

- ``per_frame``: the single answer of each frame alone (:func:`silpose.model.hypotheses.single_answer` with the most
  probable hypothesis), what the test split's robust figure measures;
- ``temporal``: the answer chosen along the sequence, what a recording of one person gets;
- ``best_of_8``: the hypothesis nearest the truth (an oracle: what a perfect choice among the eight would give).

Sequences are picked :data:`SEQUENCES_PER_CLIP` per held-out clip (its first test samples), so every clip counts
and no long clip dominates; a walk dataset's are its first :data:`WALK_SEQUENCES` test walkers, walking in place. A camera whose silhouette touches the image border is left out of that frame, as a
recording's cut silhouette would be; a frame whose body leaves an image has no view and is bridged by the choice,
not scored. The noise of frame t of sequence s is drawn as sample ``SEQUENCE_NOISE_OFFSET + s * length + t``
(streams apart from the test and in-sample ids).
"""

from __future__ import annotations

from collections import defaultdict
from types import SimpleNamespace
from pathlib import Path

import numpy as np

from silpose.datagen.sequences import SequenceError, dataset_worker_config, render_sequences_spawned
from silpose.app.inference import TOP_K, hypotheses_kept
from silpose.model.hypotheses import Hypotheses, is_flip, sequence_answer, single_answer, temporal_choice
from silpose.shared.contours import normalise
from silpose.shared.dataset import list_shards, load_split, read_metadata
from silpose.shared.metrics import pose_error_cm

from .errors import EvalInputError
from .noise import apply_noise

__all__ = ["e7_markdown", "plot_sequences", "HYPOTHESES", "SEQUENCE_LENGTH", "SEQUENCES_PER_CLIP", "SEQUENCE_NOISE_OFFSET", "pick_sequences", "render_dataset_sequences",
           "score_sequences", "sequence_experiment"]

#: frames per sequence (1 s at the bundled library's 30 fps)
SEQUENCE_LENGTH = 30
#: sequences per held-out clip
SEQUENCES_PER_CLIP = 2
#: sequences of a walk dataset (its test walkers' first samples)
WALK_SEQUENCES = 40
#: hypotheses kept per frame, as ``silpose infer`` keeps them for a recording of one person
HYPOTHESES = hypotheses_kept(TOP_K, temporal=True)
#: the noise of sequence s, frame t is drawn as sample ``SEQUENCE_NOISE_OFFSET + s * length + t``
SEQUENCE_NOISE_OFFSET = 1 << 41


def pick_sequences(sample_ids: np.ndarray, clips: np.ndarray, per_clip: int, limit: int | None = None) -> list[int]:
    """Positions (into ``sample_ids``) of the first ``per_clip`` samples of every clip (0 = the procedural walk),
    clips in increasing order, samples in increasing id; at most ``limit`` of them (None: no limit), every clip's
    first sample before any clip's second, and so on (as many clips as the limit allows)."""
    order = np.lexsort((np.asarray(sample_ids), np.asarray(clips)))
    taken: dict[int, int] = defaultdict(int)
    out, rank = [], []
    for i in order:
        c = int(clips[i])
        if taken[c] < per_clip:
            rank.append(taken[c])
            taken[c] += 1
            out.append(int(i))
    if limit is not None and len(out) > limit:
        keep = set(np.argsort(np.array(rank), kind="stable")[:max(int(limit), 0)].tolist())
        out = [p for j, p in enumerate(out) if j in keep]
    return out


def render_dataset_sequences(data_dir: str | Path, length: int = SEQUENCE_LENGTH, per_clip: int = SEQUENCES_PER_CLIP,
                             workers: int = 1, walk_sequences: int = WALK_SEQUENCES,
                             limit: int | None = None) -> dict | None:
    """Render the sequences of ``data_dir``'s test split (module docstring): ``per_clip`` per library clip, or
    ``walk_sequences`` of a walk dataset, at most ``limit`` (:func:`pick_sequences`); None for a dataset posed from BVH clips or not written by ``silpose gen``
    (no generator config in its metadata).

    Returns ``{"sample_id": (S,), "clip": (S,), "records": [[record, ...] per sequence]}``
    (:func:`silpose.datagen.sequences.render_sequences`).
    Raises:
        EvalInputError: the library changed since the dataset was made, or rendering failed.
    """
    shards = list_shards(Path(data_dir), "test")
    if not shards:
        return None
    config = read_metadata(shards[0]).get("config") or {}
    if not {"seed", "renderer", "blender_engine", "n_points", "max_redraws"} <= set(config):
        return None
    walk = config.get("motion") is None
    if not walk and config["motion"].get("source") != "library":
        return None
    test = load_split(Path(data_dir), "test", columns=["gait", "redraws"])
    try:
        worker_config = dataset_worker_config(config, test.rig, source=str(shards[0]))
    except SequenceError as exc:
        raise EvalInputError(str(exc)) from None
    clips = np.zeros(len(test.sample_id), np.int64) if walk else np.asarray(test.gait["clip"], np.int64)
    picked = pick_sequences(test.sample_id, clips, walk_sequences if walk else per_clip, limit)
    if not picked:
        return None
    requests = [(int(test.sample_id[i]), int(test.extra["redraws"][i])) for i in picked]
    try:
        records = render_sequences_spawned(worker_config, "test", requests, length, workers)
    except SequenceError as exc:
        raise EvalInputError(f"{data_dir}: {exc}") from None
    return {"sample_id": np.array([r[0] for r in requests], np.int64),
            "clip": clips[picked],
            "records": records}


def _stack(rendered: dict, n_views: int, n_points: int) -> dict:
    """Flat (F = S x T frames) arrays of the rendered sequences: contours (F, K, n, 2) px (zeros where the frame is
    not visible), joints (F, 19, 3), visible (F,), present (F, K), sequence (F,) index, t (F,) frame in sequence."""
    contours, joints, visible, present, seq, step = [], [], [], [], [], []
    for s, records in enumerate(rendered["records"]):
        for t, r in enumerate(records):
            vis = bool(r["visible"])
            contours.append(np.asarray(r["contours"], np.float64) if vis else np.zeros((n_views, n_points, 2)))
            joints.append(np.asarray(r["joints"], np.float64))
            visible.append(vis)
            present.append(~np.asarray(r["touches_border"], bool) if vis else np.zeros(n_views, bool))
            seq.append(s)
            step.append(t)
    return {"contours": np.stack(contours), "joints": np.stack(joints), "visible": np.array(visible),
            "present": np.stack(present), "sequence": np.array(seq), "t": np.array(step)}


def _hypotheses_of(res, rows: np.ndarray, n: int) -> Hypotheses:
    """The hypotheses of ``n`` frames, ``res``'s rows at positions ``rows`` (F_ok,), unused slots elsewhere."""
    h, k = res.hypotheses, res.hypotheses.k
    out = Hypotheses(joints=np.full((n, k) + h.joints.shape[2:], np.nan), probability=np.zeros((n, k)),
                     component=np.full((n, k), -1), heading=np.full((n, k), np.nan), chosen=np.zeros(n, np.intp))
    for name in ("joints", "probability", "component", "heading", "chosen"):
        getattr(out, name)[rows] = getattr(h, name)
    return out


def score_sequences(model, rendered: dict, noise, seed: int, groups: dict[int, str] | None = None) -> dict:
    """Infer the rendered sequences as ``silpose infer`` infers a recording and score the three answers
    (module docstring).

    Args:
        model: a fitted ShapeStructureModel over every view of the rig the sequences were rendered with.
        rendered: :func:`render_dataset_sequences`'s dict.
        noise: the test noise (``silpose.eval.noise.NoiseSpec``); seed: the evaluation's noise seed.
        groups: ``{clip: activity group}`` for the per-group figures (None: none).
    Returns:
        a JSON-ready dict: counts, the three answers' mean and median errors, flips (%), the share of
        frames where the choice along the frames took another hypothesis than the frame's own, and ``by_group``.
        Keys ``{per_frame,temporal,best_of_8}_{mean,median}_cm`` (``best_of_8``: of :data:`HYPOTHESES`); ``scored``
        holds every scored frame's sequence, frame and three errors (cm, 3 decimals), for :func:`plot_sequences`.
    """
    a = _stack(rendered, int(model.n_rig_views_), int(model.layout_.n_points))
    n = len(a["joints"])
    length = max(len(r) for r in rendered["records"])
    ok = a["present"].any(axis=1)
    rows = np.flatnonzero(ok)
    ids = SEQUENCE_NOISE_OFFSET + a["sequence"][rows] * length + a["t"][rows]
    clean = a["contours"][rows]
    _, centroid, scale = normalise(clean)
    noisy = apply_noise(noise, clean, ids, seed)
    res = model.infer(noisy, views_present=a["present"][rows], centroid=centroid, scale=scale, robust=True,
                      hypotheses=HYPOTHESES)
    hyp = _hypotheses_of(res, rows, n)
    mean = np.full((n,) + res.joints.shape[1:], np.nan)
    mean[rows] = res.joints
    temporal = np.zeros(n, np.intp)  # the choice apply_temporal makes, one track per sequence
    for s in range(len(rendered["records"])):
        f = np.flatnonzero(a["sequence"] == s)
        part = Hypotheses(joints=hyp.joints[f], probability=hyp.probability[f], component=hyp.component[f],
                          heading=hyp.heading[f], chosen=hyp.chosen[f])
        temporal[f] = temporal_choice(part, valid=ok[f])
    truth = a["joints"]
    answers = {"per_frame": single_answer(mean, hyp), "temporal": sequence_answer(mean, hyp, chosen=temporal)}
    err = {k: pose_error_cm(v[rows], truth[rows]) for k, v in answers.items()}
    err[f"best_of_{HYPOTHESES}"] = pose_error_cm(
        res.hypotheses.joints[np.arange(len(rows)), res.hypotheses.best_of(truth[rows])], truth[rows])
    out = {"n_sequences": len(rendered["records"]), "length": int(length), "frames": int(n),
           "frames_scored": int(len(rows)), "frames_without_view": int(n - len(rows)),
           "views_cut_pct": 100.0 * float(1.0 - a["present"][a["visible"]].mean()) if a["visible"].any() else 0.0,
           "noise": noise.label, "inference": f"robust, every view, {HYPOTHESES} hypotheses"}
    for k, e in err.items():
        out[f"{k}_mean_cm"] = float(np.mean(e))
        out[f"{k}_median_cm"] = float(np.median(e))
    for k in ("per_frame", "temporal"):
        out[f"{k}_flips_pct"] = 100.0 * float(is_flip(answers[k][rows], truth[rows]).mean())
    out["changed_pct"] = 100.0 * float(np.mean(temporal[rows] != hyp.chosen[rows]))
    out["scored"] = {"sequence": a["sequence"][rows].tolist(), "t": a["t"][rows].tolist(),
                     **{f"{k}_cm": [round(float(v), 3) for v in e] for k, e in err.items()}}
    if groups:
        clip_of_frame = rendered["clip"][a["sequence"][rows]]
        by = {}
        for g in sorted(set(groups.get(int(c), "?") for c in clip_of_frame), key=lambda x: (x != "walk", x)):
            m = np.array([groups.get(int(c), "?") == g for c in clip_of_frame])
            by[g] = {"frames": int(m.sum()), **{f"{k}_mean_cm": float(np.mean(e[m])) for k, e in err.items()}}
        out["by_group"] = by
    return out


def plot_sequences(out: dict, path: str | Path, n_panels: int = 6) -> Path | None:
    """E7's figure: pose error along the frames of the ``n_panels`` sequences whose answer the choice along the frames
    changed most (half where it helped most, half where it hurt most), each frame alone vs chosen along the frames,
    the best hypothesis dotted. None when ``out`` has no scored frames."""
    from .plots import pyplot, save_figure

    sc = out.get("scored") or {}
    if not sc.get("sequence"):
        return None
    seq = np.asarray(sc["sequence"])
    pf, tm = np.asarray(sc["per_frame_cm"]), np.asarray(sc["temporal_cm"])
    best = np.asarray(next(v for k, v in sc.items() if k.startswith("best_of_")))
    ids = np.unique(seq)
    gain = np.array([np.mean(pf[seq == s] - tm[seq == s]) for s in ids])
    order = np.argsort(-gain)
    half = max(1, n_panels // 2)
    picked = list(dict.fromkeys([*order[:half].tolist(), *order[::-1][:n_panels - half].tolist()]))[:n_panels]
    plt = pyplot()
    cols = min(3, len(picked))
    rows = int(np.ceil(len(picked) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.8 * rows), squeeze=False, sharey=True)
    t_all = np.asarray(sc["t"])
    for ax, k in zip(axes.flat, picked):
        m = seq == ids[k]
        t = t_all[m]
        ax.plot(t, pf[m], color="0.55", label="each frame alone")
        ax.plot(t, tm[m], color="C0", lw=2, label="chosen along the frames")
        ax.plot(t, best[m], color="C2", ls=":", label="best hypothesis (oracle)")
        group = (out.get("sequence_groups") or {}).get(str(int(ids[k])), "")
        ax.set_title(f"sequence {int(ids[k])}{' (' + group + ')' if group else ''}: {gain[k]:+.1f} cm", fontsize=9)
        ax.grid(alpha=0.3)
    for ax in axes[:, 0]:
        ax.set_ylabel("pose error (cm)")
    for ax in axes[-1]:
        ax.set_xlabel("frame (30 fps)")
    for ax in list(axes.flat)[len(picked):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7, loc="upper right")
    fig.suptitle(f"E7, recordings: {out['n_sequences']} sequences, mean {out['per_frame_mean_cm']:.2f} cm each frame "
                 f"alone, {out['temporal_mean_cm']:.2f} cm chosen along the frames (panels: the largest gains and "
                 "losses)", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.95))
    return save_figure(fig, path)


def e7_markdown(out: dict) -> list[str]:
    """The E7 section of ``summary.md`` (empty without figures)."""
    if not out:
        return []
    best = f"best_of_{HYPOTHESES}"
    lines = ["## E7 — recordings: the test clips played as sequences", "",
             f"{out['n_sequences']} sequences of {out['length']} frames (30 fps), {out['frames_scored']} frames scored "
             f"({out['frames_without_view']} without a view); {out['inference']}, {out['noise']} noise; pose error, cm.",
             "", "| answer | mean | median | flips (%) |", "|---|---|---|---|",
             f"| each frame alone | {out['per_frame_mean_cm']:.2f} | {out['per_frame_median_cm']:.2f} | "
             f"{out['per_frame_flips_pct']:.1f} |",
             f"| chosen along the frames (`silpose infer`, one person) | {out['temporal_mean_cm']:.2f} | "
             f"{out['temporal_median_cm']:.2f} | {out['temporal_flips_pct']:.1f} |",
             f"| best of {HYPOTHESES} hypotheses (an oracle) | {out[best + '_mean_cm']:.2f} | "
             f"{out[best + '_median_cm']:.2f} | – |", "",
             f"The choice along the frames took another hypothesis than the frame's own in {out['changed_pct']:.0f} % of "
             "the frames. Figure: `e7_sequences.png`.", ""]
    return lines


def sequence_experiment(ev, data_dir: str | Path, length: int = SEQUENCE_LENGTH, per_clip: int = SEQUENCES_PER_CLIP,
                        workers: int = 1) -> dict | None:
    """Render and score the test sequences of ``data_dir`` for an evaluation ``ev`` (its model, noise and seed; at
    most its ``n_test`` sequences, as ``silpose eval --n-test`` asks for a quick run);
    None for a dataset posed from BVH clips or not written by ``silpose gen``. Adds ``{"sequences": seconds}`` to
    ``ev.timings``."""
    import time

    t0 = time.perf_counter()
    rendered = render_dataset_sequences(data_dir, length, per_clip, workers, limit=ev.config.n_test)
    if rendered is None:
        return None
    clips = ((read_metadata(list_shards(Path(data_dir), "test")[0]).get("config") or {}).get("motion") or {}).get("clips") or []
    groups = {i: str(c.get("group", "?")) for i, c in enumerate(clips)} or None
    out = score_sequences(ev.model, rendered, ev.config.noise, ev.config.seed, groups)
    out["sample_ids"] = [int(v) for v in rendered["sample_id"]]
    if groups:
        out["sequence_groups"] = {str(s): groups.get(int(c), "?") for s, c in enumerate(rendered["clip"])}
    ev.timings["sequences"] = time.perf_counter() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    """``python -m silpose.eval.sequences DATA MODEL [--out FILE]``: E7 alone (e.g. beside an earlier report)."""
    import argparse
    import sys

    from silpose.model.persistence import load_model
    from silpose.shared.atomic import write_json_atomic

    from .experiments import EvalConfig

    p = argparse.ArgumentParser(prog="python -m silpose.eval.sequences", description=__doc__.split("\n\n")[0])
    p.add_argument("data", type=Path, help="dataset folder (its test split's clips or walkers are played)")
    p.add_argument("model", type=Path, help="model file over every view of the dataset's rig")
    p.add_argument("--out", type=Path, help="write the figures as JSON here (e.g. reports/<name>/sequences.json)")
    p.add_argument("--workers", type=int, default=1, help="spawned render workers (default 1)")
    args = p.parse_args(argv)
    for path in (args.data, args.model):
        if not path.exists():
            print(f"error: {path}: not found", file=sys.stderr)
            return 2
    try:
        ev = SimpleNamespace(model=load_model(args.model), config=EvalConfig(), timings={})
        out = sequence_experiment(ev, args.data, workers=args.workers)
    except (EvalInputError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if out is None:
        print(f"{args.data}: no sequences (a dataset posed from BVH clips, or not written by silpose gen)")
        return 0
    best = f"best_of_{HYPOTHESES}_mean_cm"
    print(f"{args.data}: {out['n_sequences']} sequences, {out['frames_scored']} frames: each frame alone "
          f"{out['per_frame_mean_cm']:.2f} cm, along the frames {out['temporal_mean_cm']:.2f} cm, best of "
          f"{HYPOTHESES} {out[best]:.2f} cm ({ev.timings['sequences']:.0f} s)")
    if args.out:
        write_json_atomic(args.out, out)
        print(plot_sequences(out, args.out.with_name("e7_sequences.png")))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
