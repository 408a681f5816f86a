"""Structural checks of a BVH file that Blender's importer does not make (pure, no bpy).

Blender's importer (``io_anim_bvh``) reads the motion values itself; what it silently accepts
was measured (bpy 5.0.1) and is checked here before importing, in the import worker:

==============================================  ====================================================
malformed file                                  Blender's importer
==============================================  ====================================================
fewer motion lines than ``Frames:`` says        imports the lines there are, no warning
a line with MORE values than channels           ignores the extra values, no warning
``CHANNELS n`` naming a different number        uses the names, ignores ``n``
a line with fewer values (truncated line)       IndexError deep in the importer
``Frames: 0`` / no motion lines                 IndexError while building the action
not a BVH file / empty file                     "This is not a BVH file" / IndexError
==============================================  ====================================================

:func:`check_structure` turns each into one line naming the file. It only counts tokens (no
values are converted); the motion itself comes from Blender's importer.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


class BvhError(ValueError):
    """A BVH file cannot be used; the message is one line naming the file."""


@dataclass(frozen=True)
class BvhStructure:
    """What :func:`check_structure` counted: total channels, the header's frame count, frame time."""

    channels: int
    frames: int
    frame_time: float


def check_structure(path: str | Path) -> BvhStructure:
    """Check the hierarchy's channel declarations and the motion section's shape.

    Raises:
        BvhError: one line naming ``path`` and what is wrong (module docstring).
    """
    path = Path(path)
    try:
        text = path.read_text(errors="strict")
    except FileNotFoundError:
        raise BvhError(f"{path}: BVH file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BvhError(f"{path}: cannot read the BVH file ({type(exc).__name__}: {exc})") from None
    text = text.removeprefix("\ufeff")  # a Windows editor's byte-order mark (the importer gets a copy without it)
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    first = next((ln.split() for ln in lines if ln.strip()), [])
    if not first or first[0].upper() != "HIERARCHY":
        raise BvhError(f"{path}: not a BVH file (it must start with HIERARCHY)")
    channels, motion_at = 0, None
    for i, line in enumerate(lines):
        tok = line.split()
        if not tok:
            continue
        if tok[0].upper() == "CHANNELS":
            try:
                n = int(tok[1])
            except (IndexError, ValueError):
                raise BvhError(f"{path}: line {i + 1}: CHANNELS without a channel count") from None
            if n != len(tok) - 2:
                raise BvhError(f"{path}: line {i + 1}: CHANNELS declares {n} channels but names {len(tok) - 2}")
            channels += n
        elif tok[0].upper() == "MOTION":
            motion_at = i
            break
    if motion_at is None:
        raise BvhError(f"{path}: no MOTION section (the file ends after the hierarchy)")
    rest = [(i, ln.split()) for i, ln in enumerate(lines[motion_at + 1:], start=motion_at + 2) if ln.strip()]
    if len(rest) < 2 or rest[0][1][:1] != ["Frames:"] or [t.lower() for t in rest[1][1][:2]] != ["frame", "time:"]:
        raise BvhError(f"{path}: MOTION must be followed by 'Frames: N' and 'Frame Time: T' lines")
    try:
        frames = int(rest[0][1][1])
        frame_time = float(rest[1][1][2])
    except (IndexError, ValueError):
        raise BvhError(f"{path}: line {rest[0][0]}: unreadable 'Frames:' or 'Frame Time:' value") from None
    data = rest[2:]
    if frames <= 0 or not data:
        raise BvhError(f"{path}: no motion frames (Frames: {frames}, {len(data)} motion lines)")
    for k, (lineno, tok) in enumerate(data):
        if len(tok) != channels:
            raise BvhError(f"{path}: line {lineno} (frame {k}): {len(tok)} values, the hierarchy declares {channels} channels")
    if len(data) != frames:
        raise BvhError(f"{path}: MOTION has {len(data)} frame lines but 'Frames: {frames}' (truncated file?)")
    return BvhStructure(channels=channels, frames=frames, frame_time=frame_time)
