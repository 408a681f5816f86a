"""Blender's user folders inside silpose's cache folder, for every worker that may import bpy.

Blender reads its user configuration, scripts and data files from ``~/.config/blender`` and writes caches
(thumbnails, Mesa's shader cache of the Workbench engine) to ``~/.cache``. A silpose worker is not a
Blender session of the user's: before any bpy import, :func:`use_silpose_blender_dirs` points Blender's
``BLENDER_USER_*`` variables and ``XDG_CACHE_HOME`` at ``<silpose cache>/blender/`` (the cache folder of
:func:`silpose.datagen.motion.clips.cache_root`: ``$SILPOSE_CACHE_DIR``, else ``$XDG_CACHE_HOME/silpose``, else
``~/.cache/silpose``), and pins ``SILPOSE_CACHE_DIR`` to that folder so the worker's own silpose cache does
not move with ``XDG_CACHE_HOME``. Variables the user set already are kept. docs/conventions.md, "Blender".
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["blender_environment", "use_silpose_blender_dirs", "CACHE_ENV"]

#: silpose's cache folder variable, as :mod:`silpose.datagen.motion.clips` reads it (not imported from there: clips
#: imports the executor, which imports this module).
CACHE_ENV = "SILPOSE_CACHE_DIR"

#: Blender's user-folder variables and the subfolder of ``<silpose cache>/blender/`` each one gets.
BLENDER_DIRS = {
    "BLENDER_USER_CONFIG": "config",
    "BLENDER_USER_SCRIPTS": "scripts",
    "BLENDER_USER_DATAFILES": "datafiles",
    "BLENDER_USER_EXTENSIONS": "extensions",
    "XDG_CACHE_HOME": "cache",
}


def blender_environment(environ=None) -> dict[str, str]:
    """The variables :func:`use_silpose_blender_dirs` sets, given the environment ``environ`` (default
    ``os.environ``); those ``environ`` sets already are left out."""
    environ = os.environ if environ is None else environ
    silpose_cache = Path(environ.get(CACHE_ENV) or Path(environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
                         / "silpose")  # as clips.cache_root() resolves it, for this environment
    wanted = {name: str(silpose_cache / "blender" / sub) for name, sub in BLENDER_DIRS.items()}
    wanted[CACHE_ENV] = str(silpose_cache)
    return {k: v for k, v in wanted.items() if not environ.get(k)}


def use_silpose_blender_dirs() -> dict[str, str]:
    """Set :func:`blender_environment` in this process (a worker, before bpy is imported); returns what it set."""
    changes = blender_environment()
    os.environ.update(changes)
    return changes
