"""Clips of joint keypoints: TRC marker files (OpenSim's format; Pose2Sim's triangulated keypoints, silpose's own
``silpose export --to trc``) and C3D files of such points (Pose2Sim, ``silpose export --to c3d``), read without
Blender.

A keypoint clip holds the 3D positions of named joints per frame, not a skeleton of rotations. silpose's motion
library stores bone *directions* between its roles (:mod:`.library`), so keypoints at the joint centres are all a
clip needs: each role present in the file becomes a bone named after the role whose head is that keypoint, with
the role tree's parents (:data:`PARENTS`), and the built-in joint map ``keypoints`` maps every role to itself.

**TRC** (OpenSim's ``TRCFileAdapter``): ``PathFileType 4 (X/Y/Z) <file>``; a line of header keys (``DataRate
CameraRate NumFrames NumMarkers Units OrigDataRate ...``) and a line of their values; ``Frame# Time`` and the
marker names (each followed by two empty cells); ``X1 Y1 Z1 X2 ...``; then one row per frame: frame number,
time (s), the markers' coordinates, an empty cell for a marker not seen. Units from ``Units`` (m, cm, mm); the
rate from ``DataRate``. TRC states no axes; OpenSim and Pose2Sim write Y up, so the file is read as Y up and
turned Z up as Blender's BVH importer turns a BVH file, ``(x, y, z) -> (x, -z, y)``; a clip written Z up is
stood up like a BVH clip (:func:`.joint_maps.upright_turn`, from the clip's median pose).

**C3D** (through the ``c3d`` library): the POINT data, labels from ``POINT:LABELS``, units from ``POINT:UNITS``,
the rate from ``POINT:RATE``; a point with a negative residual is not seen. Its axes from ``POINT:X_SCREEN`` and
``POINT:Y_SCREEN`` (the axes pointing right and up on screen: the up axis is turned to z, the right one to x);
without them the file is taken as Z up (mocap systems' usual frame), and stood up like any clip if it lies.

**Names** (case, ``_``, ``-``, ``.`` and spaces ignored; ``Left``/``Right`` prefixes read as ``L``/``R``):
silpose's own joint names (``pelvis``, ``l_shoulder`` ...), Pose2Sim's and OpenPose's (``Hip``, ``Neck``,
``Head``, ``Nose``, ``LShoulder``, ``LElbow``, ``LWrist``, ``LHip``, ``LKnee``, ``LAnkle``, ``LBigToe`` ...),
COCO's (``left_shoulder`` ... ``left_ankle``, ``left_ear``). A pelvis not in the file is the midpoint of the
hips, a neck the midpoint of the shoulders, a head the midpoint of the ears or else the nose. Other markers
(heels, small toes, eyes, anatomical markers) are ignored. A marker not seen in some frames is interpolated
linearly in time between the frames that see it (held at the ends); a role none of whose markers is ever
seen is missing.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np

from .joint_maps import REQUIRED_ROLES, ROLES

__all__ = ["KeypointClipError", "PARENTS", "KEYPOINT_SUFFIXES", "read_trc", "read_c3d", "read_keypoint_clip",
           "check_keypoint_clip", "IMPORTER"]

#: File suffixes of keypoint clips.
KEYPOINT_SUFFIXES = (".trc", ".c3d")

IMPORTER = "silpose-trc"
#: Each role's parent in the role tree (the pelvis is the root).
PARENTS: dict[str, str | None] = {
    "pelvis": None, "neck": "pelvis", "head": "neck", "head_top": "head",
    **{f"{s}_{j}": p for s in ("l", "r") for j, p in (("shoulder", "neck"), ("elbow", f"{s}_shoulder"),
                                                         ("wrist", f"{s}_elbow"), ("hip", "pelvis"),
                                                         ("knee", f"{s}_hip"), ("ankle", f"{s}_knee"),
                                                         ("toe", f"{s}_ankle"))},
}
#: Normalised marker names (:func:`_normal`) that stand for each role, first match wins.
ALIASES: dict[str, tuple[str, ...]] = {
    "pelvis": ("pelvis", "hip", "midhip", "hips", "root", "pelv"),
    "neck": ("neck",),
    "head": ("head",),
    "head_top": ("headtop", "top", "headend"),
    **{f"{s}_{j}": tuple(f"{s}{n}" for n in names) for s in ("l", "r") for j, names in (
        ("shoulder", ("shoulder",)), ("elbow", ("elbow",)), ("wrist", ("wrist", "hand")), ("hip", ("hip",)),
        ("knee", ("knee",)), ("ankle", ("ankle",)), ("toe", ("toe", "bigtoe", "toes", "toebase")))},
}
#: Length units of the ``Units`` field, metres per unit.
UNITS = {"m": 1.0, "meters": 1.0, "metres": 1.0, "meter": 1.0, "cm": 0.01, "mm": 0.001, "millimeters": 0.001,
         "millimetres": 0.001}
#: Blender's axes from a Y-up file's (Blender's BVH importer): (x, y, z) -> (x, -z, y).
Z_UP_FROM_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
#: A leaf bone's tail continues its parent's bone by this share (the head bone without a head top: by half).
LEAF_SHARE = 0.3


class KeypointClipError(ValueError):
    """A keypoint clip cannot be read; the message is one line naming the file (and the line or field)."""


def _normal(name: str) -> str:
    n = re.sub(r"[\s_\-.]", "", name.strip().lower())
    for word, short in (("left", "l"), ("right", "r")):
        if n.startswith(word):
            n = short + n[len(word):]
    return n


def _header_fields(lines: list[str], path: Path) -> dict[str, str]:
    if len(lines) < 5 or not lines[0].startswith("PathFileType"):
        raise KeypointClipError(f"{path}: line 1: not a TRC file (it starts with 'PathFileType')")
    keys = [k.strip() for k in lines[1].split("\t")]
    values = [v.strip() for v in lines[2].split("\t")]
    return {k: v for k, v in zip(keys, values) if k}


def read_trc(path: str | Path) -> tuple[float, list[str], np.ndarray]:
    """(frames per second, marker names (M,), positions (F, M, 3) metres in the file's axes; NaN: not seen)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise KeypointClipError(f"{path}: clip file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise KeypointClipError(f"{path}: not a readable text file ({type(exc).__name__})") from None
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    fields = _header_fields(lines, path)
    unit_text = fields.get("Units", "").lower()
    if unit_text not in UNITS:
        raise KeypointClipError(f"{path}: line 3: field Units: {fields.get('Units', '')!r} is not one of "
                                f"{', '.join(sorted(set(UNITS)))}")
    try:
        rate = float(fields.get("DataRate", "nan"))
    except ValueError:
        rate = float("nan")
    if not np.isfinite(rate) or rate <= 0:
        raise KeypointClipError(f"{path}: line 3: field DataRate: expected a positive frame rate, got "
                                f"{fields.get('DataRate', '')!r}")
    head = lines[3].split("\t")
    if len(head) < 3 or head[0].strip() != "Frame#":
        raise KeypointClipError(f"{path}: line 4: expected 'Frame#', 'Time' and the marker names")
    names = [c.strip() for c in head[2:] if c.strip()]
    declared = fields.get("NumMarkers")
    if declared is not None and declared.isdigit() and int(declared) != len(names):
        raise KeypointClipError(f"{path}: line 4: {len(names)} marker names, but field NumMarkers says {declared}")
    if not names:
        raise KeypointClipError(f"{path}: line 4: no marker names")
    rows = []
    for i, line in enumerate(lines[5:], start=6):
        if not line.strip():
            continue
        cells = line.split("\t")
        values = cells[2:2 + 3 * len(names)]
        values += [""] * (3 * len(names) - len(values))
        try:
            rows.append([float(v) if v.strip() else np.nan for v in values])
        except ValueError:
            bad = next(v for v in values if v.strip() and not _is_number(v))
            raise KeypointClipError(f"{path}: line {i}: {bad.strip()!r} is not a number") from None
    if not rows:
        raise KeypointClipError(f"{path}: no frame rows after the header")
    xyz = np.asarray(rows, dtype=np.float64).reshape(len(rows), len(names), 3) * UNITS[unit_text]
    return rate, names, xyz


def _is_number(v: str) -> bool:
    try:
        float(v)
        return True
    except ValueError:
        return False


def _filled(track: np.ndarray) -> np.ndarray | None:
    """(F, 3): one marker's track with unseen frames interpolated linearly in time (held at the ends), None when
    no frame sees it."""
    seen = np.isfinite(track).all(axis=1)
    if not seen.any():
        return None
    if seen.all():
        return track
    t = np.arange(len(track))
    return np.stack([np.interp(t, t[seen], track[seen, a]) for a in range(3)], axis=1)


def role_tracks(names: list[str], xyz: np.ndarray, path: Path) -> dict[str, np.ndarray]:
    """Each role's (F, 3) track from the markers (module doc: names, fallbacks, gaps)."""
    used = {a for names_ in ALIASES.values() for a in names_} | {"lear", "rear", "nose"}
    seen_names: dict[str, str] = {}
    tracks: dict[str, np.ndarray] = {}
    for i, raw in enumerate(names):
        n = _normal(raw)
        if n not in used:
            continue  # heels, eyes, anatomical or unlabelled markers: not read
        if n in seen_names:
            raise KeypointClipError(f"{path}: markers {seen_names[n]!r} and {raw!r} have the same name")
        seen_names[n] = raw
        track = _filled(xyz[:, i])
        if track is not None:
            tracks[n] = track
    out: dict[str, np.ndarray] = {}
    for role in ROLES:
        found = next((tracks[a] for a in ALIASES[role] if a in tracks), None)
        if found is not None:
            out[role] = found
    pairs = {"pelvis": ("l_hip", "r_hip"), "neck": ("l_shoulder", "r_shoulder")}
    for role, (a, b) in pairs.items():
        if role not in out and a in out and b in out:
            out[role] = 0.5 * (out[a] + out[b])
    if "head" not in out:
        if "lear" in tracks and "rear" in tracks:
            out["head"] = 0.5 * (tracks["lear"] + tracks["rear"])
        elif "nose" in tracks:
            out["head"] = tracks["nose"]
    missing = [r for r in REQUIRED_ROLES if r not in out]
    if missing:
        listed = ", ".join(names[:12]) + (f" and {len(names) - 12} more" if len(names) > 12 else "")
        raise KeypointClipError(f"{path}: no marker for {', '.join(missing)} (markers: {listed}); joint centres "
                                "are read by name (docs/motion-capture.md, TRC and C3D)")
    return out


def check_keypoint_clip(path: str | Path) -> None:
    """The checks before importing a keypoint clip (it reads, and its markers name the joints); KeypointClipError
    otherwise."""
    read_keypoint_clip(path)


def _axis(text: str) -> np.ndarray | None:
    t = str(text).strip().upper()
    if len(t) != 2 or t[0] not in "+-" or t[1] not in "XYZ":
        return None
    v = np.zeros(3)
    v["XYZ".index(t[1])] = 1.0 if t[0] == "+" else -1.0
    return v


def z_up_from_screen(x_screen: str, y_screen: str) -> np.ndarray:
    """(3, 3) the rotation taking a C3D file's axes to silpose's: ``POINT:Y_SCREEN`` (up on screen) to +z and
    ``POINT:X_SCREEN`` (right on screen) to +x; the identity when they are missing or not two different axes."""
    right, up = _axis(x_screen), _axis(y_screen)
    if right is None or up is None or abs(float(right @ up)) > 0.5:
        return np.eye(3)
    return np.stack([right, np.cross(up, right), up])


def read_c3d(path: str | Path) -> tuple[float, list[str], np.ndarray]:
    """(frames per second, point labels (M,), positions (F, M, 3) metres, silpose's axes (z up); NaN: not seen)."""
    import c3d  # the C3D format's maintained reader

    path = Path(path)
    if not path.is_file():
        raise KeypointClipError(f"{path}: clip file not found")
    try:
        with open(path, "rb") as handle, warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="No analog data")  # point data is all a clip needs
            reader = c3d.Reader(handle)
            labels = [str(n).strip() for n in reader.point_labels]
            rate = float(reader.point_rate)
            units = reader.get("POINT:UNITS")
            unit_text = units.string_value.strip().lower() if units is not None else "m"
            screen = reader.get_screen_axis() or ("", "")
            frames = []
            for _, points, _ in reader.read_frames():
                p = np.array(points[:, :3], dtype=np.float64)
                p[points[:, 3] < 0] = np.nan
                frames.append(p)
    except KeypointClipError:
        raise
    except Exception as exc:  # the library raises ValueError, struct.error, AssertionError ... on a bad file
        raise KeypointClipError(f"{path}: not a readable C3D file ({type(exc).__name__}: {str(exc).strip()[:120]})") from None
    if unit_text not in UNITS:
        raise KeypointClipError(f"{path}: field POINT:UNITS: {unit_text!r} is not one of {', '.join(sorted(set(UNITS)))}")
    if not np.isfinite(rate) or rate <= 0:
        raise KeypointClipError(f"{path}: field POINT:RATE: expected a positive frame rate, got {rate}")
    if not frames or not labels:
        raise KeypointClipError(f"{path}: no point data")
    xyz = np.stack(frames)[:, :len(labels)] * UNITS[unit_text]
    return rate, labels[:xyz.shape[1]], xyz @ z_up_from_screen(*screen).T


def read_keypoint_clip(path: str | Path) -> tuple[dict, np.ndarray, np.ndarray]:
    """Read a TRC or C3D file as a clip of role bones.

    Returns:
        meta: as :func:`silpose.datagen.blender.bvh.import_clip`'s (``names`` (the roles present), ``parents``,
            ``frames``, ``frame_time`` = 1 / DataRate, ``rest_heads`` / ``rest_tails`` (B, 3): the clip's median
            pose about its pelvis, ``importer``) plus ``markers`` (the file's marker names).
        heads, tails: (F, B, 3) float32 bone ends per frame, metres, Blender's axes (Z up): a role's bone starts
            at its keypoint and ends at its first child's (a leaf's continues its parent bone by
            :data:`LEAF_SHARE`; the head's by half, or ends at the head top).
    Raises:
        KeypointClipError: one line naming the file.
    """
    path = Path(path)
    if path.suffix.lower() == ".c3d":
        rate, markers, xyz = read_c3d(path)
    else:
        rate, markers, xyz = read_trc(path)
        xyz = xyz @ Z_UP_FROM_Y_UP.T
    tracks = role_tracks(markers, xyz, path)
    names = [r for r in ROLES if r in tracks]
    order = sorted(names, key=lambda r: _depth(r))  # parents before children
    index = {r: i for i, r in enumerate(order)}
    parents = [-1 if PARENTS[r] is None else index[PARENTS[r]] for r in order]
    heads = np.stack([tracks[r] for r in order], axis=1)  # (F, B, 3)
    tails = np.empty_like(heads)
    for r in order:
        b = index[r]
        children = [c for c in order if PARENTS[c] == r]  # the pelvis ends at the neck, the neck at the head
        child = next((c for c in ("neck", "head", "head_top") if c in children), children[0] if children else None)
        if child is not None:
            tails[:, b] = heads[:, index[child]]
        else:
            p = heads[:, index[PARENTS[r]]] if PARENTS[r] is not None else heads[:, b] - [0.0, 0.0, 0.1]
            tails[:, b] = heads[:, b] + (0.5 if r == "head" else LEAF_SHARE) * (heads[:, b] - p)
    root = heads[:, index["pelvis"]][:, None, :]
    rest_heads = np.median(heads - root, axis=0)
    rest_tails = np.median(tails - root, axis=0)
    meta = {"names": order, "parents": parents, "frames": int(len(heads)), "frame_time": 1.0 / rate,
            "rest_heads": rest_heads.tolist(), "rest_tails": rest_tails.tolist(), "importer": IMPORTER,
            "markers": list(markers)}
    return meta, heads.astype(np.float32), tails.astype(np.float32)


def _depth(role: str) -> int:
    d = 0
    while PARENTS[role] is not None:
        role, d = PARENTS[role], d + 1
    return d
