"""Datasets and models for the sections that need them: the user's, a tiny generated one, or a skip row.

The frames, memory and protocol sections measure on a generated dataset (``data/<preset>/``) and,
for frames and protocol, its trained model (``models/<preset>.npz``). When those are missing:

- ``fallback="tiny"`` (the ``--quick`` runs): generate a tiny dataset in a temporary folder with the
  real generator (the ``smoke`` preset, raster renderer, split sizes overridden) and train a small
  model on it with the real trainer, so a fresh clone with no data runs every section;
- ``fallback="skip"`` (the full runs): the section returns one row saying what it needs, instead of
  timing a tiny dataset where a real one was meant.

Inside one ``python -m benchmarks.run`` the tiny inputs are made once and shared by every section
(the runner points :data:`CACHE_ENV` at its temporary folder); otherwise each call makes its own.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

#: environment variable naming a folder where tiny inputs are generated once and reused
CACHE_ENV = "SILPOSE_BENCH_TINY_DIR"
#: split sizes of the tiny dataset: enough test samples for the quick frames (16) and protocol (40) runs
TINY_SPLITS = {"train": 80, "test": 40}
TINY_MODEL = {"n_components": 2, "n_latent": 5, "max_iter": 20, "n_init": 1}


@dataclass
class Inputs:
    """What a section measures on: ``data`` (dataset folder), ``model`` (model file or None), ``label``
    (shown in the rows: the path, or "tiny generated ..."), ``skip`` (a reason, when nothing runs)."""

    data: Path | None
    model: Path | None
    label: str
    skip: str | None = None


def skip_row(section: str, reason: str) -> dict:
    """The one row of a section that did not run for lack of inputs."""
    return {"name": section, "skipped": reason}


def make_tiny(folder: Path, with_model: bool) -> tuple[Path, Path | None]:
    """Generate the tiny dataset (and train its model) in ``folder``, unless already there.

    Returns (dataset folder, model file or None). Uses the public generator and trainer:
    ``silpose.datagen.config.load_config("smoke", ...)``, ``silpose.datagen.pipeline.generate`` and
    ``silpose.app.training.run_training``.
    """
    # imported here: the runner and the memory section's measuring children import this module for
    # its constants and resolve(), and must not pay for (or have their baseline RSS include) these
    from silpose.datagen.config import load_config
    from silpose.datagen.pipeline import generate

    data, model, done = folder / "data", folder / "tiny.npz", folder / "data.done"
    if not done.is_file():  # generate() resumes a folder an interrupted call left behind
        config = load_config("smoke", splits=dict(TINY_SPLITS), shard_size=40)
        generate(config, data, workers=1, progress=False)
        done.touch()
    if with_model and not model.is_file():
        from silpose.app.training import run_training

        run_training(str(data), out=model, progress=False, **TINY_MODEL)
    return data, (model if with_model else None)


def resolve(section: str, data: str, model: str | None, fallback: str, scratch: Path) -> Inputs:
    """The inputs of ``section``: ``data`` (and ``model`` if not None) when they exist, else the fallback.

    ``fallback``: "tiny" (generate in :data:`CACHE_ENV`'s folder, or in ``scratch``) or "skip".
    """
    if fallback not in ("tiny", "skip"):
        raise ValueError(f"{section}: fallback must be 'tiny' or 'skip', got {fallback!r}")
    data_p, model_p = Path(data), None if model is None else Path(model)
    if data_p.is_dir() and (model_p is None or model_p.is_file()):
        return Inputs(data_p, model_p, str(data_p) + ("" if model_p is None else f" + {model_p}"))
    missing = str(data_p) if not data_p.is_dir() else str(model_p)
    if fallback == "skip":
        need = f"needs {data_p}" + ("" if model_p is None else f" and {model_p}")
        return Inputs(None, None, "", skip=f"skipped: {need} ({missing} not found; just gen / just train)")
    folder = Path(os.environ.get(CACHE_ENV) or scratch)
    tiny_data, tiny_model = make_tiny(folder, with_model=model_p is not None)
    label = f"tiny generated dataset ({TINY_SPLITS['train']} + {TINY_SPLITS['test']} samples; {missing} not found)"
    return Inputs(tiny_data, tiny_model, label)

