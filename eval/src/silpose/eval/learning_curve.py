"""Learning curve N x M: held-out joint error of the MPPCA prior against training samples and components.

``python -m silpose.eval.learning_curve DATA [--n 5000 20000 ...] [--m 20 50 100 200] [--q 30]
[--structure-weight W] [--out DIR]``

For every (N, M) a ``ShapeStructureModel(M, q)`` with the structure weight W (default: the dataset's ``[train]``
``structure_weight``, as ``silpose train`` uses it, else the model's default) is fitted on N rows of the train split (the first N of
one seeded permutation, so the sets are nested; the sparse E-step from M 64 on, ``silpose.model.mppca``):
in memory, or out of core with ``--streaming`` (``fit_stream``), and scored on
the test split (for the ``motions`` preset: clips of subjects training never saw) with the standard
test noise (:data:`silpose.eval.noise.STANDARD_NOISE`), given every view and each view alone: mean
root-relative joint error, cm (``silpose.shared.metrics.pose_error_cm``, posterior mean). Points where
N < M are skipped. Rows record the fit time, EM iterations, whether EM converged and the process's
peak RSS so far. Writes ``learning_curve.json`` (settings + rows) and ``learning_curve.csv`` to
``--out`` (default ``reports/<data name>/``), rewriting both after each point, so a long run can be
stopped and its finished points are kept.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import time
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

from silpose.app.training import dataset_training
from silpose.model.defaults import DEFAULT_STRUCTURE_WEIGHT
from silpose.model.shape_model import ShapeStructureModel
from silpose.model.streaming import DatasetShards
from silpose.shared.atomic import write_text_atomic
from silpose.shared.dataset import list_shards, load_split, read_metadata
from silpose.shared.memory import peak_rss_bytes
from silpose.shared.metrics import pose_error_cm
from silpose.shared.seeds import VALIDATION_STREAM, derive_rng

from .noise import STANDARD_NOISE, apply_noise

COLUMNS = ("n_samples", "n_components", "n_latent", "pose_all_views_cm", "pose_1_view_cm", "fit_s", "n_iter",
           "converged", "e_step", "peak_rss_gib", "n_test")


def curve_point(data: Path, joints: np.ndarray, noisy: np.ndarray, n: int, m: int, q: int, *, seed: int = 0,
                max_iter: int = 60, tol: float = 1e-3, structure_weight: float = DEFAULT_STRUCTURE_WEIGHT,
                train=None) -> dict:
    """Fit one (N, M) model on ``n`` training rows (:func:`training_rows`) and score it on the noisy test
    contours (N_test, K, n, 2) px against the test joints (N_test, 19, 3) m. ``train``: the train split in
    memory (a ``DatasetSplit`` with contours and joints): the fit is in memory; None: out of core
    (``fit_stream``, which builds every shard's shape vectors once and reads them back from a temporary
    file in later EM passes, ``silpose.model.streaming``)."""
    model = ShapeStructureModel(n_components=m, n_latent=q, structure_weight=structure_weight, n_init=1,
                                max_iter=max_iter, tol=tol, random_state=seed, noise_dof=True)
    rows = training_rows(data, n, seed)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if train is None:
            model.fit_stream(data, "train", rows=rows)
        else:
            model.fit(train.contours[rows], train.joints[rows], rig=train.rig)
    fit_s = time.perf_counter() - t0
    K = noisy.shape[1]
    all_views = float(pose_error_cm(model.infer(noisy).joints, joints).mean())
    one = []
    for v in range(K):
        present = np.zeros((len(joints), K), bool)
        present[:, v] = True
        one.append(pose_error_cm(model.infer(noisy, views_present=present).joints, joints).mean())
    mix = model.mixture_
    return {"n_samples": int(n), "n_components": int(m), "n_latent": int(q), "pose_all_views_cm": all_views,
            "pose_1_view_cm": float(np.mean(one)), "fit_s": fit_s, "n_iter": int(mix.n_iter_),
            "converged": bool(mix.converged_), "e_step": mix.e_step_,
            "peak_rss_gib": peak_rss_bytes() / 2**30, "n_test": int(len(joints))}


def training_rows(data: Path, n: int, seed: int = 0) -> np.ndarray:
    """Sorted global row indices of the train split: the first ``n`` of a permutation seeded by ``seed``
    (``derive_rng(seed, VALIDATION_STREAM)``), so smaller N are subsets of larger ones."""
    total = int(sum(DatasetShards.open(data, "train").shard_rows()))
    if not 1 <= n <= total:
        raise ValueError(f"{data}: N = {n} training rows asked, the train split has {total}")
    return np.sort(derive_rng(seed, VALIDATION_STREAM).permutation(total)[:n])


def write_curve(out: Path, settings: dict, rows: list[dict]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out / "learning_curve.json", json.dumps({"settings": settings, "rows": rows}, indent=2))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=COLUMNS)
    w.writeheader()
    w.writerows(rows)
    write_text_atomic(out / "learning_curve.csv", buf.getvalue())


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m silpose.eval.learning_curve", description=__doc__.split("\n\n")[0])
    ap.add_argument("data", type=Path, help="dataset folder (train and test splits)")
    ap.add_argument("--n", type=int, nargs="+", default=[5000, 20000, 50000], help="training samples")
    ap.add_argument("--m", type=int, nargs="+", default=[20, 50, 100, 200], help="mixture components")
    ap.add_argument("--q", type=int, default=30, help="latent dimensions per component")
    ap.add_argument("--structure-weight", type=float, default=None,
                    help="weight of the joint block (default: the dataset's [train] structure_weight, else "
                         f"{DEFAULT_STRUCTURE_WEIGHT:g})")
    ap.add_argument("--n-test", type=int, default=None, help="first N test samples (default all)")
    ap.add_argument("--max-iter", type=int, default=60)
    ap.add_argument("--tol", type=float, default=1e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None, help="output folder (default reports/<data name>/)")
    ap.add_argument("--streaming", action="store_true",
                    help="fit out of core (fit_stream) instead of loading the train split's contours into memory")
    args = ap.parse_args(argv)
    out = args.out or Path("reports") / args.data.name
    weight = args.structure_weight
    if weight is None:
        metadata = read_metadata(list_shards(args.data, "train")[0]) if list_shards(args.data, "train") else {}
        weight = dataset_training(metadata, args.data).get("structure_weight", DEFAULT_STRUCTURE_WEIGHT)
    if not weight > 0:
        ap.error(f"--structure-weight must be > 0, got {weight}")
    test = load_split(args.data, "test")
    contours = np.asarray(test.contours, np.float64)[: args.n_test]
    test_joints = np.asarray(test.joints, np.float64)[: args.n_test]
    noisy = apply_noise(STANDARD_NOISE, contours, np.asarray(test.sample_id)[: args.n_test], args.seed)

    train = None if args.streaming else load_split(args.data, "train", columns=["joints", "contours"])
    settings = {"data": str(args.data), "n": args.n, "m": args.m, "q": args.q, "structure_weight": weight,
                "max_iter": args.max_iter,
                "fit": "streaming" if args.streaming else "in memory",
                "tol": args.tol, "seed": args.seed, "noise": STANDARD_NOISE.to_dict(),
                "error": "mean root-relative joint error (cm) of the posterior mean on the test split"}
    rows: list[dict] = []
    for n in args.n:
        for m in args.m:
            if n < m:
                continue
            row = curve_point(args.data, test_joints, noisy, n, m, args.q, seed=args.seed, max_iter=args.max_iter,
                              tol=args.tol, structure_weight=weight, train=train)
            rows.append(row)
            print(json.dumps(row), flush=True)
            write_curve(out, settings, rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
