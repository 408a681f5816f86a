"""Blender run by silpose writes its user configuration and caches into silpose's cache folder, not into
~/.config/blender and ~/.cache: every spawned worker sets Blender's user-folder variables before bpy loads."""

from __future__ import annotations

import os

from silpose.datagen.blender_env import BLENDER_DIRS, blender_environment
from silpose.datagen.executor import spawned_map


def test_environment_points_into_the_silpose_cache(tmp_path):
    env = blender_environment({"SILPOSE_CACHE_DIR": str(tmp_path)})
    assert env["BLENDER_USER_CONFIG"] == str(tmp_path / "blender" / "config")
    assert env["XDG_CACHE_HOME"] == str(tmp_path / "blender" / "cache")
    assert "SILPOSE_CACHE_DIR" not in env  # set by the user: kept
    kept = blender_environment({"XDG_CACHE_HOME": str(tmp_path / "x"), "BLENDER_USER_CONFIG": "/mine"})
    assert "BLENDER_USER_CONFIG" not in kept and kept["SILPOSE_CACHE_DIR"] == str(tmp_path / "x" / "silpose")


def test_spawned_workers_get_the_variables(tmp_path, monkeypatch):
    monkeypatch.delenv("SILPOSE_CACHE_DIR", raising=False)
    for name in BLENDER_DIRS:
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    names = [*BLENDER_DIRS, "SILPOSE_CACHE_DIR"]
    got = dict(spawned_map(os.getenv, [(n, n) for n in names], workers=1))  # os.getenv runs in the worker
    cache = tmp_path / "home" / ".cache" / "silpose"
    assert got["SILPOSE_CACHE_DIR"] == str(cache)  # the driver's silpose cache, not moved by XDG_CACHE_HOME
    assert got["BLENDER_USER_CONFIG"] == str(cache / "blender" / "config")
    assert got["XDG_CACHE_HOME"] == str(cache / "blender" / "cache")


def test_the_cache_variable_is_the_clips_cache_variable():
    from silpose.datagen import blender_env
    from silpose.datagen.motion import clips

    assert blender_env.CACHE_ENV == clips.CACHE_ENV
