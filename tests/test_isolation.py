"""Blender isolation: shared, model, segment, app, eval and the ``silpose`` command never import bpy.

Two proofs:

(a) In this environment (where bpy IS installed) a meta-path finder makes any ``import bpy``
    fail and logs who tried. Every module of silpose.shared, .model, .segment, .app and .eval is
    imported in a subprocess, and ``silpose --help`` / ``silpose <cmd> --help`` run for every
    registered command with the blocker installed through a ``sitecustomize`` module. A command
    whose module does not exist yet makes its test fail, on purpose.
(b) A fresh virtual environment holding only ./shared and ./model (built by ``uv``) imports them
    with no bpy anywhere on its path (and without segment, app or eval: the model is a library).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from importlib.metadata import entry_points
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
ENTRY_POINT_GROUP = "silpose.commands"
#: Everything on the inference side of the data flow (docs/conventions.md, "Layers"); segment = background
#: subtraction, app = the train / infer workflows.
CHECKED_PACKAGES = ("silpose.shared", "silpose.model", "silpose.segment", "silpose.app", "silpose.eval")

BLOCKER = textwrap.dedent(
    '''
    """Isolation test: make ``import bpy`` fail, and log every attempt with its stack."""
    import os
    import sys
    import traceback


    class _BlockBpy:
        def find_spec(self, name, path=None, target=None):
            if name.split(".")[0] in ("bpy", "_bpy"):
                log = os.environ.get("SILPOSE_BPY_LOG")
                if log:
                    with open(log, "a") as f:
                        f.write(f"import {name} attempted:\\n" + "".join(traceback.format_stack()) + "\\n")
                raise ImportError(f"bpy is blocked in this process (silpose isolation test): {name}")
            return None


    sys.meta_path.insert(0, _BlockBpy())
    '''
)

IMPORT_ALL = textwrap.dedent(
    """
    import importlib, json, pkgutil, sys, traceback
    imported, failed = [], {}
    for top in sys.argv[1:]:
        try:
            pkg = importlib.import_module(top)
        except Exception:
            failed[top] = traceback.format_exc()
            continue
        imported.append(top)
        def onerror(name):
            failed[name] = traceback.format_exc()
        for info in pkgutil.walk_packages(pkg.__path__, top + ".", onerror=onerror):
            try:
                importlib.import_module(info.name)
                imported.append(info.name)
            except Exception:
                failed[info.name] = traceback.format_exc()
    print(json.dumps({"imported": imported, "failed": failed, "bpy_loaded": "bpy" in sys.modules}))
    """
)


@pytest.fixture()
def blocked_env(tmp_path):
    """Environment whose Python processes cannot import bpy (sitecustomize on PYTHONPATH)."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "sitecustomize.py").write_text(BLOCKER)
    log = tmp_path / "bpy_attempts.log"
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site)] + [p for p in [env.get("PYTHONPATH")] if p])
    env["SILPOSE_BPY_LOG"] = str(log)
    return env, log


def _attempts(log: Path) -> str:
    return log.read_text() if log.exists() else ""


def test_blocker_really_blocks_bpy(blocked_env):
    """Control: bpy is installed here, yet the blocker makes it unimportable and logs the attempt."""
    env, log = blocked_env
    r = subprocess.run([sys.executable, "-c", "import bpy"], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "blocked" in r.stderr
    assert "import bpy attempted" in _attempts(log)


def test_no_module_of_shared_model_eval_imports_bpy(blocked_env):
    env, log = blocked_env
    r = subprocess.run(
        [sys.executable, "-c", IMPORT_ALL, *CHECKED_PACKAGES],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        cwd=REPO,
    )
    assert r.returncode == 0, r.stderr
    result = json.loads(r.stdout.strip().splitlines()[-1])
    assert _attempts(log) == "", f"bpy import attempted:\n{_attempts(log)}"
    assert not result["failed"], "modules failed to import:\n" + "\n".join(
        f"--- {name}\n{tb}" for name, tb in result["failed"].items()
    )
    assert not result["bpy_loaded"]
    for name in ("silpose.shared.camera", "silpose.shared.contours", "silpose.shared.skeleton", "silpose.shared.cli"):
        assert name in result["imported"]
    for top in CHECKED_PACKAGES:
        assert any(m.startswith(top + ".") for m in result["imported"]), f"{top} has no modules yet"


def _silpose_command() -> list[str]:
    script = Path(sys.executable).parent / "silpose"
    return [str(script)] if script.exists() else [sys.executable, "-m", "silpose.shared.cli"]


COMMANDS = sorted({ep.name for ep in entry_points(group=ENTRY_POINT_GROUP)})


def test_commands_are_registered():
    assert {"gen", "validate", "preview", "train", "infer", "eval"} <= set(COMMANDS)


def test_silpose_help_without_bpy(blocked_env):
    env, log = blocked_env
    r = subprocess.run(_silpose_command() + ["--help"], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "cannot load command" not in r.stderr, r.stderr
    for cmd in COMMANDS:
        assert cmd in r.stdout
    assert _attempts(log) == "", f"bpy import attempted:\n{_attempts(log)}"


@pytest.mark.parametrize("cmd", COMMANDS)
def test_silpose_command_help_without_bpy(blocked_env, cmd):
    env, log = blocked_env
    r = subprocess.run(_silpose_command() + [cmd, "--help"], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, f"silpose {cmd} --help exited {r.returncode}:\n{r.stdout}\n{r.stderr}"
    assert "cannot load command" not in r.stderr, r.stderr
    assert "Usage" in r.stdout and cmd in r.stdout
    assert _attempts(log) == "", f"bpy import attempted:\n{_attempts(log)}"


# ---------------------------------------------------------------------- (b) a real bpy-free venv

CHECK_VENV = textwrap.dedent(
    """
    import importlib, importlib.util, json, pkgutil, sys
    import numpy as np
    import silpose.shared.camera, silpose.shared.contours, silpose.model
    mods, failed = [], {}
    for top in ("silpose.shared", "silpose.model"):
        pkg = importlib.import_module(top)
        for info in pkgutil.walk_packages(pkg.__path__, top + "."):
            try:
                importlib.import_module(info.name)
                mods.append(info.name)
            except Exception as exc:
                failed[info.name] = repr(exc)
    m = np.zeros((20, 20), bool); m[5:15, 4:12] = True
    c = silpose.shared.contours.extract_contour(m, 16)
    print(json.dumps({
        "bpy_spec": repr(importlib.util.find_spec("bpy")),
        "datagen_spec": repr(importlib.util.find_spec("silpose.datagen")),
        "eval_spec": repr(importlib.util.find_spec("silpose.eval")),
        "segment_spec": repr(importlib.util.find_spec("silpose.segment")),
        "app_spec": repr(importlib.util.find_spec("silpose.app")),
        "camera_file": silpose.shared.camera.__file__,
        "prefix": sys.prefix,
        "modules": mods,
        "failed": failed,
        "bpy_loaded": "bpy" in sys.modules,
        "contour_points": c.points.shape[0],
        "rig_cameras": len(silpose.shared.camera.default_rig()),
    }))
    """
)


def _run(cmd, env, **kw):
    return subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600, **kw)


def test_fresh_venv_with_shared_and_model_has_no_bpy(tmp_path):
    uv = shutil.which("uv")
    if uv is None:
        pytest.skip("uv is not on PATH: cannot build a bpy-free virtual environment")
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH", "PYTHONHOME")}
    venv = tmp_path / "venv"
    r = _run([uv, "venv", str(venv), "--python", "3.11", "-q"], env)
    assert r.returncode == 0, r.stderr
    py = venv / "bin" / "python"
    # --no-sources: ignore the workspace table, which would install ./shared editable (pointing back
    # into the repository) instead of as a built copy.
    install = [uv, "pip", "install", "-q", "--no-sources", "--python", str(py)]
    install += [str(REPO / "shared"), str(REPO / "model")]
    r = _run(install[:3] + ["--offline"] + install[3:], env)  # works once uv's cache holds everything
    if r.returncode != 0:
        r = _run(install, env)
    assert r.returncode == 0, f"uv pip install failed:\n{r.stderr}"
    r = _run([str(py), "-c", CHECK_VENV], env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout.strip().splitlines()[-1])
    assert res["bpy_spec"] == "None"
    assert not res["bpy_loaded"]
    # It really is the separate environment: installed copies, without datagen and eval.
    assert Path(res["prefix"]).resolve() == venv.resolve()
    assert Path(res["camera_file"]).resolve().is_relative_to(venv.resolve())
    assert res["datagen_spec"] == "None" and res["eval_spec"] == "None"
    assert res["segment_spec"] == "None" and res["app_spec"] == "None"
    assert not res["failed"], f"modules failed to import in the bpy-free venv: {res['failed']}"
    assert res["contour_points"] == 16 and res["rig_cameras"] == 4
    assert "silpose.shared.contours" in res["modules"]
    assert {"silpose.model.shape_model", "silpose.model.conditioning", "silpose.model.persistence"} <= set(res["modules"])
