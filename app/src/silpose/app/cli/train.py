"""``silpose train``: fit the shape+structure model on a dataset's train split.

Only light modules are imported at module level (typer, pathlib, typing); numpy, sklearn,
pyarrow and rich come with the work, imported inside the command (:mod:`silpose.app.training`),
so ``silpose --help`` stays fast.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Optional

import typer

from silpose.shared.cli import fail

from ..errors import InputError


def train(
    preset: Annotated[str, typer.Argument(help="Preset name (fits on data/<preset>/) or a dataset folder.")] = "default",
    out: Annotated[Optional[Path], typer.Option("--out", "-o", help="Model file (default: models/<name>.npz).")] = None,
    select: Annotated[bool, typer.Option("--select", help="Choose q, M, structure weight and noise on a validation split first.")] = False,
    n_components: Annotated[Optional[int], typer.Option("--components", "-M", min=1, help="Mixture components M (default: the dataset config's [train] components, else 60 lowered for small data).")] = None,
    n_latent: Annotated[Optional[int], typer.Option("--latent", "-q", min=1, help="Latent dimension q per component (default: the dataset config's [train] latent, else 40 lowered for small data).")] = None,
    structure_weight: Annotated[Optional[float], typer.Option(help="Weight of the joint block in the shape vector.")] = None,
    noise_variance: Annotated[Optional[float], typer.Option(min=0.0, help="Observation noise s² at inference (normalised units²).")] = None,
    views: Annotated[Optional[str], typer.Option(help="Views to model, comma-separated rig indices (default: all).")] = None,
    max_iter: Annotated[int, typer.Option(min=1, help="EM iterations per run at most.")] = 200,
    n_init: Annotated[int, typer.Option(min=1, help="EM runs from different k-means starts; the best is kept.")] = 1,
    fits: Annotated[Optional[int], typer.Option(min=1, help="EM fits from seeds seed, seed+1, ... pooled into one mixture "
                                      "(the average of their densities): on small data a single fit's error varies "
                                      "about 10 % with its start, 5 fits beat every one of them; inference costs "
                                      "as much as M x fits components. In memory only. Default: the dataset "
                                      "config's [train] fits (the default preset's: 5), else 1.")] = None,
    tol: Annotated[float, typer.Option(help="EM stops when the mean log-likelihood gains less than this "
                                       "(nats per sample per iteration).")] = 0.1,  # app.training.DEFAULT_TOL
    seed: Annotated[int, typer.Option(help="Seed of the k-means starts and the held-out/validation splits.")] = 0,
    heldout: Annotated[float, typer.Option(help="Fraction of train held out for the held-out log-likelihood.")] = 0.1,
    data_root: Annotated[Path, typer.Option(help="Folder holding the presets' datasets.")] = Path("data"),
    progress: Annotated[bool, typer.Option(help="Show EM progress.")] = True,
    streaming: Annotated[bool, typer.Option("--streaming", help="Out-of-core fit: EM reads the train shards one at a time "
                                            "(memory bounded by one shard, not the dataset).")] = False,
    executor: Annotated[str, typer.Option(help="Where the streaming EM runs its per-shard tasks: 'local' (this process) "
                                          "or 'ray' (one Ray task per shard; implies --streaming; uses the running Ray "
                                          "instance or RAY_ADDRESS, else starts a local one).")] = "local",
    workers: Annotated[Optional[int], typer.Option(min=1, help="CPUs of the local Ray instance if one is started (default: all cores).")] = None,
    roughness: Annotated[Optional[float], typer.Option(min=0.0, help="Training augmentation: ragged-outline copies of the "
                                             "training contours like real segmentation, this many px of normal wander "
                                             "(0 = off; silpose.model.augment). Default: 1 px, one copy, when at most "
                                             "5,000 samples are fitted; off above.")] = None,
    roughness_copies: Annotated[int, typer.Option(min=0, help="Ragged copies added per training sample "
                                                  "(0 = replace each sample by one).")] = 1,
    mirror: Annotated[str, typer.Option(help="Training augmentation for mirror-symmetric rigs (the paper's): add the "
                                        "mirrored person of every training sample, seen by the mirrored cameras "
                                        "(silpose.shared.rig_symmetry). 'auto': when the rig has a symmetry and at "
                                        "most 10,000 samples result; 'on': always (error if the rig has none); "
                                        "'off'. Real calibrations have no symmetry, so 'auto' changes nothing for them.")] = "auto",
) -> None:
    """Fit the shape+structure model (mixture of PPCA over contours + joints) on a dataset's train split.

    Writes the model file and a training report (<model>.report.md and .json: EM iterations,
    log-likelihood curve, time, held-out log-likelihood and joint error on a held-out part of train).
    The model is fitted on the rest of train.

    By default the train split is loaded into memory. --streaming (or --executor ray) fits the
    same model by streaming EM over the Parquet shards (one shard's features in memory at a time;
    locally, each shard's features are built once and read back from a temporary file in later
    passes; on Ray, one task per shard); the k-means + PPCA start is then fitted on at most 5,000 rows
    drawn across the shards (all rows if there are fewer, which gives the in-memory start).
    """
    from silpose.model.augment import Roughness
    from silpose.model.persistence import ModelFileError
    from silpose.model.streaming import StreamingError
    from silpose.shared.dataset import DatasetError

    from ..training import run_training

    if not 0.0 < heldout < 1.0:
        fail("train", f"the held-out fraction must be in (0, 1), got {heldout:g} (--heldout)")
    try:
        view_tuple = None if views is None else tuple(int(v) for v in views.split(",") if v.strip())
    except ValueError:
        fail("train", f"--views must be comma-separated integers, got {views!r}")
    try:
        result = run_training(
            preset, out=out, select=select, n_components=n_components, n_latent=n_latent,
            structure_weight=structure_weight, noise_variance=noise_variance, views=view_tuple,
            max_iter=max_iter, n_init=n_init, n_fits=fits, tol=tol, seed=seed, heldout=heldout, data_root=data_root,
            progress=progress, streaming=streaming, executor=executor, workers=workers,
            roughness=("auto" if roughness is None and roughness_copies == 1 else
                       Roughness(amplitude_px=1.0 if roughness is None else roughness, copies=roughness_copies)
                       if roughness is None or roughness > 0 else None),
            mirror=mirror,
        )
    except (InputError, DatasetError, ModelFileError, StreamingError, ValueError) as exc:
        fail("train", str(exc))
    except KeyboardInterrupt:
        fail("train", "interrupted; nothing was written", 130)
    print(result.summary())
