"""The registry of exporters: one :class:`Exporter` per ``silpose export --to`` value.

Each entry has a name, the file suffix it writes, what it writes (help text and docs) and ``write(motion,
path) -> Path`` with one signature for all; :func:`get_exporter` names the known ones when asked for another.
Adding a format is one entry here, its writer module and its test (which reads the file back with an
independent reader). The writers import their libraries when called, so ``silpose --help`` stays light.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from .motion import Motion

__all__ = ["Exporter", "EXPORTERS", "get_exporter", "exporter_names"]


@dataclass(frozen=True)
class Exporter:
    """One export format (module docstring)."""

    name: str
    suffix: str
    what: str
    write: Callable[["Motion", Path], Path]


def _write_trc(motion, path):
    from .trc import write_trc

    return write_trc(motion, path)


def _write_c3d(motion, path):
    from .c3d_file import write_c3d

    return write_c3d(motion, path)


def _write_bvh(motion, path):
    from silpose.datagen.bvh_export import export_bvh

    return export_bvh(motion.joints, motion.fps, path, units=motion.units, up=motion.up, source=motion.source)


EXPORTERS: tuple[Exporter, ...] = (
    Exporter("trc", ".trc", "OpenSim / Pose2Sim marker file, one marker per joint, Y up", _write_trc),
    Exporter("c3d", ".c3d", "C3D point data, one point per joint (the c3d library)", _write_c3d),
    Exporter("bvh", ".bvh", "BVH of the 19-joint armature fitted to the joints (Blender's exporter)", _write_bvh),
)


def exporter_names() -> str:
    return ", ".join(e.name for e in EXPORTERS)


def get_exporter(name: str) -> Exporter:
    from .motion import ExportInputError

    for e in EXPORTERS:
        if e.name == name:
            return e
    raise ExportInputError(f"unknown format {name!r}; choose one of {exporter_names()} (--to)")
