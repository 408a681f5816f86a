"""Drill: a process SIGKILLed while saving a model over an existing model file.

``save_model`` writes a temporary file, fsyncs it and renames it over the target. Whenever the
writer dies, the file under the model's name must load (``load_model`` verifies the arrays' sha256)
and be exactly one complete version: the one before the interrupted save (or, if the kill landed
after the rename, the new one) -- never a mixture or a truncated file.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from silpose.model.persistence import load_model, save_model
from silpose.app.training import fit_dataset
from silpose.model.shape_model import ShapeStructureModel
from silpose.shared.dataset import load_split

# Shared by the saving child and the checking test: version j of the model's parameters (about
# 4 MB of float64, M = 5 components, q = 60, so a save takes long enough to be interrupted).
_VERSIONS = r"""
import numpy as np

M, Q = 5, 60

def version(j, d):
    rng = np.random.default_rng(1000 + j)
    return {"weights": np.full(M, 1.0 / M), "means": rng.normal(size=(M, d)),
            "components": rng.normal(size=(M, d, Q)), "noise_variance": np.full(M, 0.1 + j)}
"""

_SAVER = _VERSIONS + r"""
import sys
from silpose.model.persistence import load_model, save_model

path = sys.argv[1]
model = load_model(path)
model.n_components, model.n_latent = M, Q
for j in range(1_000_000):
    for name, value in version(j, model.layout_.dim).items():
        setattr(model.mixture_, name + "_", value)
    print("saving", j, flush=True)
    save_model(path, model)
    print("saved", j, flush=True)
"""

_ns: dict = {}
exec(_VERSIONS, _ns)
version = _ns["version"]


@pytest.fixture(scope="module")
def first_model(clean_dataset):
    root, _ = clean_dataset
    return fit_dataset(ShapeStructureModel(1, 2, n_init=1, max_iter=5), load_split(root, "train"))


def _arrays(model) -> dict:
    mix = model.mixture_
    return {"weights": mix.weights_, "means": mix.means_, "components": mix.components_,
            "noise_variance": mix.noise_variance_}


def _kill_while_saving(path, min_saves: int):
    """Run the saver, SIGKILL it as soon as a temporary file appears after ``min_saves`` saves.
    Returns (lines printed, temporaries left)."""
    proc = subprocess.Popen([sys.executable, "-c", _SAVER, str(path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")), daemon=True)
    reader.start()
    deadline = time.monotonic() + 120
    try:
        while proc.poll() is None and time.monotonic() < deadline:
            if sum(l.startswith("saved") for l in list(lines)) >= min_saves and list(path.parent.glob(f".{path.name}.*.tmp")):
                break
            time.sleep(0.0005)
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.kill()
        proc.wait()
        reader.join(5)
    assert proc.returncode == -signal.SIGKILL, proc.stderr.read()[-2000:]
    return [l.split() for l in lines], sorted(path.parent.glob(f".{path.name}.*.tmp"))


@pytest.mark.parametrize("min_saves", [0, 3])
def test_model_file_survives_sigkill_during_save(first_model, tmp_path, min_saves):
    """Kill the saver while a temporary file exists (retried until a kill really lands mid-save)."""
    for attempt in range(5):
        path = tmp_path / f"try{attempt}" / "tiny.npz"
        save_model(path, first_model)
        before = _arrays(load_model(path))
        lines, temporaries = _kill_while_saving(path, min_saves)
        _check_one_complete_version(path, before, lines, temporaries, min_saves)
        if temporaries:
            return
    pytest.fail("no kill landed during a save in 5 attempts: the drill did not test anything")


def _check_one_complete_version(path, before, lines, temporaries, min_saves) -> None:
    saved = [int(j) for what, j in lines if what == "saved"]
    saving = [int(j) for what, j in lines if what == "saving"]
    assert len(saved) >= min_saves
    loaded = load_model(path)  # raises ModelFileError if torn: it checks every array's sha256
    got = _arrays(loaded)
    d = loaded.layout_.dim
    # The complete versions the file may hold: the last finished save, or the interrupted one if
    # the kill came after its rename but before it reported.
    candidates = {"before": before} if not saved else {f"v{saved[-1]}": version(saved[-1], d)}
    if saving and (not saved or saving[-1] != saved[-1]):
        candidates[f"v{saving[-1]}"] = version(saving[-1], d)
    matches = [name for name, ref in candidates.items()
               if all(got[k].shape == ref[k].shape and np.array_equal(got[k], ref[k]) for k in ref)]
    assert len(matches) == 1, (list(candidates), lines[-3:])
    if temporaries:  # killed mid-save: the file is the PREVIOUS version, untouched
        assert matches[0] == list(candidates)[0], (matches, lines[-3:])
    # the next save over the same name works despite the dead writer's temporary
    save_model(path, loaded)
    np.testing.assert_array_equal(load_model(path).mixture_.means_, got["means"])
