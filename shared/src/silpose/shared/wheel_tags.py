"""Make installed wheels' ``WHEEL`` tags agree with the wheel files ``uv.lock`` installed them from.

Why: bpy 5.0.1's wheel ``bpy-5.0.1-cp311-cp311-manylinux_2_28_x86_64.whl`` carries a
``bpy-5.0.1.dist-info/WHEEL`` file that says ``Tag: cp39-cp39-manylinux_2_28_x86_64`` (a packaging
error upstream: the file name is right, the metadata is not). uv chooses a wheel by its file name,
but decides whether an *installed* distribution still fits the interpreter by the tags in its
``WHEEL`` file (``uv-installer`` ``RequirementSatisfaction::check``: "Platform tags mismatch ...
compatible with CPython 3.9 (cp39), but you're using CPython 3.11"). So every ``uv sync`` and
every ``uv run`` (which syncs first) uninstalled and reinstalled bpy's 2,621 files -- and a
Blender worker running at that moment lost its ``bpy`` (``module 'bpy' has no attribute 'ops'``).
No uv setting skips that check (``reinstall``/``no-sync`` are the only knobs, and ``no-sync`` is a
command-line flag or environment variable, not a project setting), and PyPI's file cannot be
changed, so the installed copy is corrected instead.

What: :func:`repair` finds every installed distribution whose ``WHEEL`` tags all mismatch this
interpreter while ``uv.lock`` lists a wheel of the same name and version whose *file name* fits
it, and rewrites the ``Tag:`` lines to that file name's tags (and the ``WHEEL`` line of
``RECORD`` to the new hash and size). It touches nothing when every tag already fits, so running it
again is free. ``just setup`` runs it after ``uv sync``, and the ``silpose`` command checks at
start, so ``uv run silpose ...`` right after a fresh ``uv sync`` also stops the churn.

Usage: ``python -m silpose.shared.wheel_tags [--check] [--lock uv.lock]``.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import sys
import sysconfig
import tomllib
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote, urlparse

from packaging.tags import Tag, parse_tag, sys_tags
from packaging.utils import canonicalize_name, parse_wheel_filename

from .atomic import write_text_atomic

__all__ = ["Repair", "default_lock", "find_mismatches", "repair", "main"]


@dataclass(frozen=True)
class Repair:
    """One installed distribution whose ``WHEEL`` tags contradict its wheel's file name."""

    name: str
    version: str
    dist_info: Path
    installed_tags: tuple[str, ...]
    wheel_file: str
    wheel_tags: tuple[str, ...]

    def describe(self) -> str:
        return (f"{self.name} {self.version}: WHEEL says {', '.join(self.installed_tags)}, its wheel {self.wheel_file} "
                f"says {', '.join(self.wheel_tags)}")


def default_lock() -> Path | None:
    """``uv.lock`` of the project whose environment runs this interpreter (``<project>/.venv``), if any."""
    lock = Path(sys.prefix).parent / "uv.lock"
    return lock if lock.is_file() else None


def _lock_wheels(lock: Path) -> dict[tuple[str, str], list[str]]:
    """``{(canonical name, version): [wheel file names]}`` from a ``uv.lock``."""
    with open(lock, "rb") as f:
        data = tomllib.load(f)
    out: dict[tuple[str, str], list[str]] = {}
    for pkg in data.get("package", []):
        names = []
        for wheel in pkg.get("wheels", []):
            ref = wheel.get("filename") or wheel.get("url") or wheel.get("path") or ""
            names.append(unquote(Path(urlparse(ref).path).name))
        if names:
            out[(canonicalize_name(pkg["name"]), str(pkg.get("version", "")))] = names
    return out


def _wheel_tag_lines(text: str) -> list[str]:
    return [line.split(":", 1)[1].strip() for line in text.splitlines() if line.startswith("Tag:")]


def find_mismatches(site_packages: Path | None = None, lock: Path | None = None,
                    supported: list[Tag] | None = None) -> list[Repair]:
    """Installed distributions in ``site_packages`` (default: this interpreter's) whose ``WHEEL`` tags
    all mismatch ``supported`` (default: ``packaging.tags.sys_tags()``) but whose locked wheel's
    file name matches. Reads only the ``WHEEL`` files unless one mismatches (then the lock too); finds
    nothing without a lock file."""
    site_packages = Path(site_packages or sysconfig.get_paths()["platlib"])
    supported = list(sys_tags()) if supported is None else supported
    rank = {tag: i for i, tag in enumerate(supported)}
    suspects = []
    for wheel_file in sorted(site_packages.glob("*.dist-info/WHEEL")):
        lines = _wheel_tag_lines(wheel_file.read_text(errors="replace"))
        try:
            tags = {t for line in lines for t in parse_tag(line)}
        except ValueError:
            continue  # an unparsable tag: not ours to fix
        if tags and not tags & rank.keys():
            suspects.append((wheel_file.parent, tuple(lines)))
    if not suspects:
        return []
    lock = lock or default_lock()
    if lock is None or not Path(lock).is_file():
        return []  # nothing to compare with: leave the environment alone
    locked = _lock_wheels(lock)
    repairs = []
    for dist_info, lines in suspects:
        name, _, version = dist_info.name[: -len(".dist-info")].partition("-")
        best = None
        for filename in locked.get((canonicalize_name(name), version), []):
            try:
                tags = parse_wheel_filename(filename)[3]
            except ValueError:
                continue
            fits = [rank[t] for t in tags if t in rank]
            if fits and (best is None or min(fits) < best[0]):
                best = (min(fits), filename, tags)
        if best:
            repairs.append(Repair(name, version, dist_info, lines, best[1], tuple(sorted(str(t) for t in best[2]))))
    return repairs


def _record_hash(data: bytes) -> str:
    return "sha256=" + base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()


def _apply(r: Repair) -> None:
    wheel = r.dist_info / "WHEEL"
    lines = wheel.read_text().splitlines(keepends=True)
    first = next(i for i, line in enumerate(lines) if line.startswith("Tag:"))  # the new tags go where the old were
    tags = [f"Tag: {t}\n" for t in r.wheel_tags]
    text = "".join(lines[:first] + tags + [line for line in lines[first:] if not line.startswith("Tag:")])
    write_text_atomic(wheel, text)
    record = r.dist_info / "RECORD"
    if record.is_file():
        entry = f"{r.dist_info.name}/WHEEL"
        rows = record.read_text().splitlines()
        new = [f"{entry},{_record_hash(text.encode())},{len(text.encode())}" if row.split(",", 1)[0] == entry else row
               for row in rows]
        if new != rows:
            write_text_atomic(record, "\n".join(new) + "\n")


def repair(site_packages: Path | None = None, lock: Path | None = None,
           supported: list[Tag] | None = None) -> list[Repair]:
    """Rewrite the ``WHEEL`` tags of every :func:`find_mismatches` result; returns what was repaired."""
    found = find_mismatches(site_packages, lock, supported)
    for r in found:
        _apply(r)
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m silpose.shared.wheel_tags", description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="only report; exit 1 if a repair is needed")
    parser.add_argument("--lock", type=Path, default=None, help="uv.lock (default: beside this environment)")
    args = parser.parse_args(argv)
    if args.lock is not None and not args.lock.is_file():
        parser.error(f"{args.lock}: lock file not found")
    found = find_mismatches(lock=args.lock) if args.check else repair(lock=args.lock)
    for r in found:
        print(f"{'mismatch' if args.check else 'repaired'}: {r.describe()}", file=sys.stderr)
    return 1 if (args.check and found) else 0


if __name__ == "__main__":
    raise SystemExit(main())
