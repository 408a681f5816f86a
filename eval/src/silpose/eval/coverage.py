"""Pose coverage: how far each test pose is from the nearest training pose (an oracle, not a method).

For every test sample, the training sample whose root-relative joints (world orientation, the model's
structure target, :mod:`silpose.shared.skeleton`) are nearest in the paper's pose error, the mean joint
distance (:func:`silpose.shared.metrics.pose_error_cm`), and that error. It is the error of a lookup that
knew the true pose and could only answer with a training pose: no method that picks a training pose can
beat it on average. A model that interpolates between training poses can: on the default preset (the procedural
walk) the nearest of 2,000 training poses is 3.61 cm off, the MPPCA's robust answer 3.32 cm. So the figure says
how far the test poses lie from the training poses, not where a model must stop; :mod:`.in_sample` gives the
other half, the model's error on poses it was fitted on. ``silpose eval`` writes both to ``coverage.json``.

Reported per activity group of the test clips (:func:`.groups.sample_groups`)::

    python -m silpose.eval.coverage data/motions [--out reports/motions/coverage.json]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from silpose.shared.atomic import write_json_atomic
from silpose.shared.dataset import load_split
from silpose.shared.metrics import pose_error_cm, root_relative

from .groups import sample_groups

#: test rows per block of the search (bounds the (block, N, 19) distance array)
BLOCK = 4


def nearest_pose(test: np.ndarray, train: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The training pose with the smallest mean joint distance to every test pose, by brute force:
    ``(index (T,), error (T,) cm)``; ``test`` (T, 19, 3), ``train`` (N, 19, 3), root-relative metres."""
    b = np.asarray(train, np.float32)
    idx = np.empty(len(test), np.int64)
    err = np.empty(len(test))
    for s in range(0, len(test), BLOCK):
        blk = np.asarray(test[s:s + BLOCK], np.float32)
        d = np.sqrt(((blk[:, None] - b[None]) ** 2).sum(axis=-1)).mean(axis=-1)  # (block, N) metres
        idx[s:s + BLOCK] = np.argmin(d, axis=1)
        err[s:s + BLOCK] = 100.0 * d.min(axis=1)
    return idx, err


def coverage(dataset: str | Path, test_dataset: str | Path | None = None) -> dict:
    """Nearest-training-pose error (cm) of the test split (of ``test_dataset``, default ``dataset``) against
    ``dataset``'s train split: ``mean_cm``, ``median_cm``, ``n_train``, ``n_test`` and, when the test poses come
    from grouped clips, ``groups`` {group: {mean_cm, n}}."""
    test_dataset = dataset if test_dataset is None else test_dataset
    tr = load_split(Path(dataset), "train", columns=["joints"]).joints
    te = load_split(Path(test_dataset), "test", columns=["joints"])
    rel_tr = root_relative(tr)
    rel_te = root_relative(te.joints)
    idx, _ = nearest_pose(rel_te, rel_tr)
    err = pose_error_cm(rel_tr[idx], rel_te)  # in float64
    out = {"mean_cm": float(err.mean()), "median_cm": float(np.median(err)), "n_train": int(len(tr)),
           "n_test": int(len(rel_te))}
    groups = sample_groups(test_dataset)
    if groups:
        g = np.array([groups.get(int(s), "?") for s in te.sample_id])
        out["groups"] = {n: {"mean_cm": float(err[g == n].mean()), "n": int((g == n).sum())}
                         for n in sorted(set(g), key=lambda x: (x != "walk", x))}
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m silpose.eval.coverage", description=__doc__.split("\n\n")[0])
    p.add_argument("data", type=Path, help="dataset folder (train and test splits)")
    p.add_argument("--out", type=Path, help="write the figures as JSON here (default: print only)")
    args = p.parse_args(argv)
    res = coverage(args.data)
    print(f"{args.data}: nearest training pose of {res['n_test']} test poses among {res['n_train']}: "
          f"mean {res['mean_cm']:.2f} cm, median {res['median_cm']:.2f} cm")
    for n, r in (res.get("groups") or {}).items():
        print(f"  {n:10s} {r['mean_cm']:6.2f} cm  (n {r['n']})")
    if args.out:
        write_json_atomic(args.out, res)
    return 0


if __name__ == "__main__":
    sys.exit(main())
