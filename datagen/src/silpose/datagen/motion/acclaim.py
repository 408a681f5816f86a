"""Acclaim ASF/AMC motion capture (the CMU database's own format): read a clip and evaluate every
frame's bone positions, in pure numpy (no bpy).

An ASF file is the skeleton: ``:units`` (``length L``: lengths are in 1/L inch; ``angle deg|rad``),
``:root`` (``order`` of its AMC values, ``axis`` order, ``position``, ``orientation``),
``:bonedata`` (per bone: ``name``, ``direction`` (unit vector, world axes at rest), ``length``,
``axis ax ay az ORDER``, ``dof`` among ``rx ry rz``) and ``:hierarchy`` (``parent child ...``
lines). An AMC file is the motion: ``:FULLY-SPECIFIED``, ``:DEGREES`` (or ``:RADIANS``), then per
frame its number and one line per bone with degrees of freedom, ``name v1 v2 ...`` in the bone's
``dof`` order (the root's in its ``order``). An AMC file does not state its frame rate: the CMU
database's is 120 fps (:data:`CMU_FPS`).

Forward kinematics, as in the CMU Graphics Lab's own viewer (Acclaim's ASF/AMC specification)::

    C_b   = R_{o3}(a3) R_{o2}(a2) R_{o1}(a1)        axis angles in the axis ORDER o1 o2 o3 (first applied first)
    M_b   = R_{d_k}(v_k) ... R_{d_1}(v_1)           the frame's dof values in dof order (first applied first)
    R_b   = R_parent C_b M_b C_b^-1                 (root: C_root M_root C_root^-1, C_root from orientation)
    head_b = tail_parent     (the root's position for bones that start at the root)
    tail_b = head_b + length_b R_b direction_b

Results are turned to Blender's axes as its BVH importer does (ASF Y up: (x, y, z) -> (x, -z, y))
and given in metres (``L`` units = 0.0254 / L m each: the CMU files' ``length 0.45`` gives
0.056444 m, the unit of the CMU BVH conversions), so an ASF/AMC clip's ``scale`` is 1.

:func:`read_clip` returns what Blender's BVH import returns (:func:`silpose.datagen.blender.bvh.import_clip`):
bone names, parents, rest pose and per-frame heads and tails, a ``root`` bone first (head at the
root's position, tail 0.1 m above it at rest). The skeleton of ``NN_MM.amc`` is ``NN.asf`` in the
same folder, else the folder's only ``.asf`` file (:func:`skeleton_of`).
"""

from __future__ import annotations

import hashlib
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: AMC files do not state their frame rate; the CMU database records at 120 fps.
CMU_FPS = 120.0
#: Metres per inch: an ASF ``length L`` unit is 1/L inch.
INCH_M = 0.0254
#: ``importer`` of the cache entries this module writes.
IMPORTER = "silpose acclaim 1"
_ROOT_TAIL_M = 0.1
_TO_BLENDER = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_ROT_DOFS = ("rx", "ry", "rz")


class AcclaimError(ValueError):
    """An ASF or AMC file cannot be used; the message is one line naming the file."""


@dataclass(frozen=True)
class Bone:
    """One ASF bone: unit ``direction`` (3,), ``length`` (file units), axis ``angles`` (3,) radians
    in ``axis_order``, rotational ``dof`` names (a subset of rx ry rz, in AMC value order)."""

    name: str
    direction: np.ndarray
    length: float
    angles: np.ndarray
    axis_order: str
    dof: tuple[str, ...]


@dataclass(frozen=True)
class Skeleton:
    """A parsed ASF file: ``length_unit`` L, ``angle_scale`` (radians per ASF angle unit), the root's
    AMC ``root_order`` (tokens like ``tx``/``rx``), ``root_axis`` order, ``position`` (3,) and
    ``orientation`` (3,) radians, ``bones`` by name, ``children`` by parent name (``root`` included)."""

    path: Path
    length_unit: float
    angle_scale: float
    root_order: tuple[str, ...]
    root_axis: str
    position: np.ndarray
    orientation: np.ndarray
    bones: dict[str, Bone]
    children: dict[str, list[str]]

    def order(self) -> list[str]:
        """Bone names depth first from the root (``root`` first): every parent before its children."""
        out, stack = [], ["root"]
        while stack:
            name = stack.pop()
            out.append(name)
            stack.extend(reversed(self.children.get(name, [])))
        return out


def _axis_rotation(axis: str, angle: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotations by ``angle`` (radians, any shape) about world axis ``x``, ``y`` or ``z``."""
    c, s = np.cos(angle), np.sin(angle)
    one, zero = np.ones_like(c), np.zeros_like(c)
    rows = {"x": ((one, zero, zero), (zero, c, -s), (zero, s, c)),
            "y": ((c, zero, s), (zero, one, zero), (-s, zero, c)),
            "z": ((c, -s, zero), (s, c, zero), (zero, zero, one))}[axis]
    return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)


def euler(axes: str, angles: np.ndarray) -> np.ndarray:
    """``R_{axes[-1]} ... R_{axes[0]}`` (first axis applied first): (..., 3, 3) from ``angles``
    (..., len(axes)) radians."""
    angles = np.asarray(angles, np.float64)
    out = np.broadcast_to(np.eye(3), angles.shape[:-1] + (3, 3)).copy()
    for k, a in enumerate(axes.lower()):
        out = _axis_rotation(a, angles[..., k]) @ out
    return out


def skeleton_of(amc: Path) -> Path:
    """The ASF file of ``amc``: ``NN.asf`` beside ``NN_MM.amc``, else the folder's only ``.asf``."""
    amc = Path(amc)
    subject = amc.stem.split("_")[0]
    named = [p for p in amc.parent.glob("*") if p.suffix.lower() == ".asf" and p.stem.lower() == subject.lower()]
    if named:
        return named[0]
    found = sorted(p for p in amc.parent.glob("*") if p.suffix.lower() == ".asf")
    if len(found) == 1:
        return found[0]
    if not found:
        raise AcclaimError(f"{amc}: no skeleton: put its .asf file beside it (CMU: {subject}.asf)")
    raise AcclaimError(f"{amc}: {len(found)} .asf files beside it and none named {subject}.asf; "
                       f"put the clip's skeleton in a folder of its own")


def clip_sha256(path: Path) -> str:
    """Identity of a clip file for the import cache: a BVH file's sha256; an AMC file's covers its
    skeleton too (the same motion on another skeleton is another clip)."""
    path = Path(path)
    h = hashlib.sha256()
    files = [path] + ([skeleton_of(path)] if path.suffix.lower() == ".amc" else [])
    for f in files:
        with open(f, "rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                h.update(block)
    return h.hexdigest()


def _floats(words: list[str], n: int, where: str) -> np.ndarray:
    if len(words) < n:
        raise AcclaimError(f"{where}: expected {n} numbers, found {len(words)}")
    try:
        return np.array([float(w) for w in words[:n]], np.float64)
    except ValueError:
        raise AcclaimError(f"{where}: expected {n} numbers, found {' '.join(words[:n])!r}") from None


def _sections(text: str, path: Path) -> dict[str, list[tuple[int, list[str]]]]:
    """``{section: [(line number, words), ...]}`` of an ASF file (``:name value`` lines too)."""
    out: dict[str, list[tuple[int, list[str]]]] = {}
    current = None
    for no, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            words = line[1:].split()
            current = words[0].lower() if words else ""
            out.setdefault(current, []).append((no, words[1:]))
            continue
        if current is None:
            raise AcclaimError(f"{path}: line {no}: not an ASF file (text before the first ':' section)")
        out[current].append((no, line.split()))
    return out


def _read_text(path: Path, kind: str) -> str:
    """The text of an ASF or AMC file (past a Windows editor's byte-order mark)."""
    try:
        return path.read_text(encoding="utf-8-sig", errors="strict")
    except FileNotFoundError:
        raise AcclaimError(f"{path}: {kind} file not found") from None
    except UnicodeDecodeError:
        raise AcclaimError(f"{path}: not an {kind} file (not text)") from None


def read_skeleton(path: str | Path) -> Skeleton:
    """Parse an ASF file (module docstring). Raises AcclaimError naming the file, line and field."""
    path = Path(path)
    text = _read_text(path, "ASF")
    sec = _sections(text, path)
    for need in ("root", "bonedata", "hierarchy"):
        if need not in sec:
            raise AcclaimError(f"{path}: not an ASF file (no :{need} section)")
    length_unit, angle_scale = 1.0, np.pi / 180.0
    for no, words in sec.get("units", [])[1:]:
        key = words[0].lower()
        if key == "length":
            length_unit = float(_floats(words[1:], 1, f"{path}: line {no}: :units length")[0])
            if not length_unit > 0:
                raise AcclaimError(f"{path}: line {no}: :units length must be positive, got {length_unit}")
        elif key == "angle":
            unit = words[1].lower() if len(words) > 1 else ""
            if unit not in ("deg", "rad"):
                raise AcclaimError(f"{path}: line {no}: :units angle must be deg or rad, got {unit!r}")
            angle_scale = np.pi / 180.0 if unit == "deg" else 1.0
    root = {w[0].lower(): (no, w[1:]) for no, w in sec["root"][1:] if w}
    order_words = root.get("order", (0, ["TX", "TY", "TZ", "RX", "RY", "RZ"]))[1]
    root_order = tuple(w.lower() for w in order_words)
    bad = [w for w in root_order if w not in ("tx", "ty", "tz", "rx", "ry", "rz")]
    if bad or len(set(root_order)) != len(root_order):
        raise AcclaimError(f"{path}: :root order {' '.join(order_words)!r}: expected distinct TX TY TZ RX RY RZ")
    root_axis = root.get("axis", (0, ["XYZ"]))[1][0].lower()
    position = _floats(root.get("position", (0, ["0", "0", "0"]))[1], 3, f"{path}: :root position")
    orientation = _floats(root.get("orientation", (0, ["0", "0", "0"]))[1], 3, f"{path}: :root orientation") * angle_scale
    if sorted(root_axis) != ["x", "y", "z"]:
        raise AcclaimError(f"{path}: :root axis {root_axis.upper()!r}: expected an order of X, Y and Z")
    bones: dict[str, Bone] = {}
    block: dict[str, tuple[int, list[str]]] | None = None
    for no, words in sec["bonedata"][1:]:
        key = words[0].lower()
        if key == "begin":
            block = {}
        elif key == "end":
            if block is None:
                raise AcclaimError(f"{path}: line {no}: 'end' without 'begin' in :bonedata")
            bone = _bone(block, path, angle_scale, no)
            bones[bone.name] = bone
            block = None
        elif block is not None:
            block[key] = (no, words[1:])
    children: dict[str, list[str]] = {}
    seen = {"root"}
    for no, words in sec["hierarchy"][1:]:
        if words[0].lower() in ("begin", "end"):
            continue
        parent, kids = words[0], words[1:]
        if parent not in seen:
            raise AcclaimError(f"{path}: line {no}: :hierarchy names {parent!r} before it is a child of another bone")
        for k in kids:
            if k not in bones:
                raise AcclaimError(f"{path}: line {no}: :hierarchy bone {k!r} is not in :bonedata")
            if k in seen:
                raise AcclaimError(f"{path}: line {no}: :hierarchy bone {k!r} has two parents")
            seen.add(k)
        children.setdefault(parent, []).extend(kids)
    if not children.get("root"):
        raise AcclaimError(f"{path}: :hierarchy has no 'root ...' line")
    return Skeleton(path=path, length_unit=length_unit, angle_scale=angle_scale, root_order=root_order,
                    root_axis=root_axis, position=position, orientation=orientation, bones=bones, children=children)


def _bone(block: dict[str, tuple[int, list[str]]], path: Path, angle_scale: float, end_line: int) -> Bone:
    if "name" not in block or not block["name"][1]:
        raise AcclaimError(f"{path}: line {end_line}: a :bonedata bone has no name")
    name = block["name"][1][0]
    where = f"{path}: bone {name!r}"
    for need in ("direction", "length"):
        if need not in block:
            raise AcclaimError(f"{where}: field {need!r} missing")
    direction = _floats(block["direction"][1], 3, f"{where}: direction")
    norm = float(np.linalg.norm(direction))
    length = float(_floats(block["length"][1], 1, f"{where}: length")[0])
    if length < 0 or (length > 0 and norm < 1e-9):
        raise AcclaimError(f"{where}: a length of {length} along direction {direction.tolist()} is not a bone")
    axis = block.get("axis", (0, ["0", "0", "0", "XYZ"]))[1]
    angles = _floats(axis, 3, f"{where}: axis") * angle_scale
    order = (axis[3] if len(axis) > 3 else "XYZ").lower()
    if sorted(order) != ["x", "y", "z"]:
        raise AcclaimError(f"{where}: axis order {order.upper()!r}: expected an order of X, Y and Z")
    dof = tuple(w.lower() for w in block.get("dof", (0, []))[1])
    bad = [d for d in dof if d not in _ROT_DOFS]
    if bad:
        raise AcclaimError(f"{where}: dof {bad[0]!r} is not supported (only rotations rx ry rz)")
    return Bone(name=name, direction=direction / norm if norm > 0 else direction, length=length, angles=angles,
                axis_order=order, dof=dof)


def read_motion(path: str | Path, skeleton: Skeleton) -> dict[str, np.ndarray]:
    """Parse an AMC file against ``skeleton``: ``{bone: (F, n_dof) values}`` (``root``: (F, 6)
    in its ``order``), angles in radians, lengths in file units.

    Raises AcclaimError naming the file, the frame and the bone (a frame that lacks a bone, a line
    with the wrong number of values, a bone the skeleton does not have).
    """
    path = Path(path)
    text = _read_text(path, "AMC")
    angle = skeleton.angle_scale
    width = {"root": len(skeleton.root_order)}
    width.update({n: len(b.dof) for n, b in skeleton.bones.items()})
    moving = [n for n, w in width.items() if w > 0]
    frames: list[dict[str, list[str]]] = []
    numbers: list[int] = []
    for no, raw in enumerate(text.splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            key = line[1:].split()[0].lower() if line[1:].split() else ""
            if key == "degrees":
                angle = np.pi / 180.0
            elif key == "radians":
                angle = 1.0
            continue
        words = line.split()
        if len(words) == 1 and re.fullmatch(r"\d+", words[0]):
            frames.append({})
            numbers.append(int(words[0]))
            continue
        if not frames:
            raise AcclaimError(f"{path}: line {no}: not an AMC file (values before the first frame number)")
        name = words[0]
        if name not in width:
            raise AcclaimError(f"{path}: line {no}: bone {name!r} is not in the skeleton {skeleton.path.name}")
        if len(words) - 1 != width[name]:
            raise AcclaimError(f"{path}: line {no}: frame {numbers[-1]}: bone {name!r} has {len(words) - 1} values, "
                               f"its dof in {skeleton.path.name} has {width[name]}")
        frames[-1][name] = words[1:]
    if not frames:
        raise AcclaimError(f"{path}: no frame (not an AMC file?)")
    out: dict[str, np.ndarray] = {}
    for name in moving:
        rows = []
        for number, frame in zip(numbers, frames):
            if name not in frame:
                raise AcclaimError(f"{path}: frame {number} has no line for bone {name!r} (is the file cut short?)")
            rows.append(frame[name])
        try:
            out[name] = np.array(rows, np.float64)
        except ValueError:
            raise AcclaimError(f"{path}: bone {name!r}: a value is not a number") from None
        if not np.all(np.isfinite(out[name])):
            raise AcclaimError(f"{path}: bone {name!r}: a value is NaN or infinite")
    for name, order in [("root", skeleton.root_order)] + [(n, b.dof) for n, b in skeleton.bones.items()]:
        if name in out:
            rot = np.array([t.startswith("r") for t in order])
            out[name][:, rot] *= angle
    out["_frames"] = np.array(numbers, np.int64)
    return out


def _rotations(values: np.ndarray, tokens: tuple[str, ...]) -> np.ndarray:
    """M (F, 3, 3) of one bone's AMC values (F, len(tokens)) (module docstring), translations skipped."""
    rot = [(k, t[1]) for k, t in enumerate(tokens) if t.startswith("r")]
    if not rot:
        return np.broadcast_to(np.eye(3), (len(values), 3, 3))
    return euler("".join(a for _, a in rot), values[:, [k for k, _ in rot]])


def forward_kinematics(skeleton: Skeleton, motion: dict[str, np.ndarray]) -> tuple[list[str], list[int], np.ndarray, np.ndarray]:
    """Bone names, parents and (F, B, 3) heads and tails in the ASF's own axes and units (module
    docstring); ``root`` first, its tail ``0.1 m`` above its head at rest."""
    names = skeleton.order()
    index = {n: i for i, n in enumerate(names)}
    parent_of = {k: p for p, kids in skeleton.children.items() for k in kids}
    parents = [index[parent_of[n]] if n in parent_of else -1 for n in names]
    F = len(motion["_frames"])
    B = len(names)
    heads = np.zeros((F, B, 3))
    tails = np.zeros((F, B, 3))
    R = np.zeros((F, B, 3, 3))
    root_vals = motion.get("root", np.zeros((F, len(skeleton.root_order))))
    C = euler(skeleton.root_axis, skeleton.orientation)
    M = _rotations(root_vals, skeleton.root_order)
    R[:, 0] = C @ M @ C.T
    head = np.broadcast_to(skeleton.position, (F, 3)).copy()
    for k, axis in ((0, "tx"), (1, "ty"), (2, "tz")):
        if axis in skeleton.root_order:
            head[:, k] = root_vals[:, skeleton.root_order.index(axis)]
    heads[:, 0] = head
    up = np.array([0.0, _ROOT_TAIL_M / (INCH_M / skeleton.length_unit), 0.0])
    tails[:, 0] = head + R[:, 0] @ up
    for i, name in enumerate(names[1:], 1):
        bone, p = skeleton.bones[name], parents[i]
        C = euler(bone.axis_order, bone.angles)
        M = _rotations(motion[name], bone.dof) if bone.dof else np.eye(3)
        R[:, i] = R[:, p] @ (C @ M @ C.T)
        heads[:, i] = heads[:, p] if p == 0 else tails[:, p]
        tails[:, i] = heads[:, i] + R[:, i] @ (bone.direction * bone.length)
    return names, parents, heads, tails


def read_clip(path: str | Path, fps: float = CMU_FPS) -> tuple[dict, np.ndarray, np.ndarray]:
    """Read an AMC file and its ASF skeleton (:func:`skeleton_of`) and evaluate every frame.

    Returns:
        meta: as :func:`silpose.datagen.blender.bvh.import_clip`'s (``names``, ``parents``,
            ``frames``, ``frame_time`` = 1 / ``fps``, ``rest_heads`` / ``rest_tails`` (B, 3),
            ``importer``) plus ``skeleton`` (the ASF file) and ``unit_m`` (metres per ASF unit).
        heads, tails: (F, B, 3) float32 bone ends per frame, metres, Blender's axes (Z up).
    Raises:
        AcclaimError: one line naming the file.
    """
    path = Path(path)
    skeleton = read_skeleton(skeleton_of(path))
    motion = read_motion(path, skeleton)
    names, parents, heads, tails = forward_kinematics(skeleton, motion)
    rest = {"_frames": np.zeros(1, np.int64)}
    rest.update({n: np.zeros((1, len(b.dof))) for n, b in skeleton.bones.items() if b.dof})
    rest["root"] = np.zeros((1, len(skeleton.root_order)))
    for k, axis in enumerate(("tx", "ty", "tz")):
        if axis in skeleton.root_order:
            rest["root"][0, skeleton.root_order.index(axis)] = skeleton.position[k]
    _, _, rest_heads, rest_tails = forward_kinematics(skeleton, rest)
    unit = INCH_M / skeleton.length_unit
    to_world = _TO_BLENDER * unit
    meta = {
        "names": names, "parents": parents, "frames": int(len(heads)), "frame_time": 1.0 / float(fps),
        "rest_heads": (rest_heads[0] @ to_world.T).tolist(), "rest_tails": (rest_tails[0] @ to_world.T).tolist(),
        "importer": IMPORTER, "skeleton": str(skeleton.path), "unit_m": unit,
    }
    return meta, (heads @ to_world.T).astype(np.float32), (tails @ to_world.T).astype(np.float32)
