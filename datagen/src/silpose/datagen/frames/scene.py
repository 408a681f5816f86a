"""What the textured camera frames show, as data (pure numpy, no bpy): room, props, lights,
per-subject clothing colours and which body triangle wears which garment.

The Blender side (:mod:`silpose.datagen.frames.blender_room`) only turns these numbers into objects, so the layout can
be checked without Blender (props never hide the workspace from any camera; see
:func:`check_props_do_not_occlude`).

Colours are linear RGB in [0, 1] (Cycles' scene-referred values, "Standard" view transform).
"""

from __future__ import annotations

import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.seeds import APPEARANCE_STREAM, SPLIT_CODE, derive_rng
from silpose.shared.skeleton import JOINT_INDEX, JOINT_NAMES, PARENTS

#: Bumped whenever the rendered scene changes (part of a frames folder's identity: a rerun does not
#: resume a folder rendered from another scene).
SCENE_VERSION = 4

#: Volume a person can occupy (metres): the rig's workspace grown by an arm's reach
#: (``PERSON_VOLUME_MARGIN``), from the floor up to ``PERSON_VOLUME_TOP``.
PERSON_VOLUME_MARGIN = 0.4
PERSON_VOLUME_TOP = 2.1


def person_volume(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """(lo (3,), hi (3,)) metres: the box a person of ``rig``'s workspace can occupy."""
    (x0, x1), (y0, y1) = rig.workspace.bounds
    m = PERSON_VOLUME_MARGIN
    return np.array([x0 - m, y0 - m, 0.0]), np.array([x1 + m, y1 + m, PERSON_VOLUME_TOP])

#: Garment names; index = Blender material index of the body mesh.
PARTS = ("shirt", "trousers", "skin", "hair", "shoes")

# Room surfaces (linear RGB). Pale warm walls, a mid-grey-brown textured floor.
WALL_COLOUR = (0.55, 0.52, 0.45)
FLOOR_COLOURS = ((0.34, 0.25, 0.16), (0.12, 0.09, 0.07))  # two wood-like tones mixed by a noise texture
#: Fine floor grain: Voronoi cells, ``scale`` per metre (a few pixels at 7 m), each scaling the
#: colour by a random factor in 1 +- ``amount``. Without it the floor is flat within the shadow test's 7x7 windows and the
#: NCC test (silpose.segment) cannot tell a shadow from a person.
FLOOR_GRAIN = {"scale": 12.0, "amount": 0.4}
PROP_COLOURS = {"box": (0.45, 0.30, 0.12), "table": (0.10, 0.18, 0.30)}

#: Sun (the shadow caster): elevation and azimuth in degrees, strength in W/m^2, angular size.
SUN = {"elevation_deg": 50.0, "azimuth_deg": 200.0, "strength": 2.6, "angle_deg": 0.5}
#: Uniform grey world light (ambient: what lights the shadows), strength.
AMBIENT = 0.35

# Palettes (linear RGB). Shirts avoid the wall colour; trousers are dark or saturated. No white or
# mid-grey garments: the segmentation works on graylevels, and a white/blue striped shirt or grey
# trousers had the graylevel of the grey walls (smoke sample 2: person IoU 0.47 in one view).
SHIRTS = ((0.60, 0.05, 0.05), (0.05, 0.25, 0.60), (0.05, 0.40, 0.10), (0.65, 0.45, 0.02), (0.03, 0.03, 0.03),
          (0.40, 0.05, 0.40), (0.02, 0.35, 0.35))
TROUSERS = ((0.02, 0.03, 0.08), (0.04, 0.04, 0.04), (0.10, 0.12, 0.25), (0.20, 0.12, 0.05))
SKINS = ((0.60, 0.38, 0.28), (0.45, 0.26, 0.16), (0.25, 0.13, 0.07), (0.12, 0.06, 0.03))
HAIRS = ((0.02, 0.015, 0.01), (0.10, 0.05, 0.02), (0.35, 0.22, 0.08), (0.30, 0.30, 0.30))
SHOES = ((0.02, 0.02, 0.02), (0.60, 0.60, 0.60), (0.20, 0.08, 0.03))


def appearance_rng(seed: int, index: int) -> np.random.Generator:
    """Generator of test sample ``index``'s clothing, independent of its body and gait draws:
    ``derive_rng(APPEARANCE_STREAM, seed, SPLIT_CODE["test"], index)`` (docs/conventions.md, "Seeds")."""
    return derive_rng(APPEARANCE_STREAM, seed, SPLIT_CODE["test"], index)


def draw_appearance(seed: int, index: int) -> dict:
    """Clothing of test sample ``index``: linear RGB colours per part (:data:`PARTS`), the shirt's
    stripe colour and stripe period (metres; 0 = plain) and sleeve length (``"short"``/``"long"``)."""
    rng = appearance_rng(seed, index)

    def pick(palette):
        c = np.asarray(palette[rng.integers(len(palette))], float)
        return tuple(float(v) for v in np.clip(c * rng.uniform(0.85, 1.15), 0.0, 1.0))

    out = {"shirt": pick(SHIRTS), "trousers": pick(TROUSERS), "skin": pick(SKINS), "hair": pick(HAIRS),
           "shoes": pick(SHOES)}
    out["stripe"] = pick(SHIRTS)
    out["stripe_period"] = float(rng.choice([0.0, 0.0, 0.08, 0.12]))
    out["sleeves"] = "long" if rng.uniform() < 0.5 else "short"
    return out


#: Garment of the body around each bone (bone = its child joint).
_BONE_PART = {
    "spine": "shirt", "neck": "shirt", "head": "skin", "head_top": "skin",
    "l_shoulder": "shirt", "r_shoulder": "shirt", "l_elbow": "shirt", "r_elbow": "shirt",
    "l_wrist": "shirt", "r_wrist": "shirt",  # forearms: skin with short sleeves (see part_labels)
    "l_hip": "trousers", "r_hip": "trousers", "l_knee": "trousers", "r_knee": "trousers",
    "l_ankle": "trousers", "r_ankle": "trousers", "l_toe": "shoes", "r_toe": "shoes",
}


def _nearest_bone(points: np.ndarray, joints: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bone (index into JOINT_NAMES of its child joint) whose skin surface is nearest each point,
    and the parameter t in [0, 1] along that bone.

    Distance to a bone = distance to its segment minus the skin radius there (``radii`` (19,)
    metres per joint, interpolated along the bone), so a torso point next to a hanging arm still
    belongs to the torso."""
    child = np.array([c for c in range(1, len(JOINT_NAMES))])
    parent = np.array([PARENTS[c] for c in child])
    a, b = joints[parent], joints[child]  # (B, 3)
    ab = b - a
    t = np.einsum("pbk,bk->pb", points[:, None, :] - a[None], ab) / np.maximum((ab * ab).sum(1), 1e-12)
    t = np.clip(t, 0.0, 1.0)
    d = np.linalg.norm(points[:, None, :] - (a[None] + t[..., None] * ab[None]), axis=2)
    d = d - ((1 - t) * radii[parent][None] + t * radii[child][None])
    j = np.argmin(d, axis=1)
    return child[j], t[np.arange(len(points)), j]


def part_labels(
    vertices: np.ndarray, triangles: np.ndarray, joints: np.ndarray, radii: np.ndarray, appearance: dict
) -> np.ndarray:
    """Garment index (into :data:`PARTS`) of every body triangle.

    Args:
        vertices: (V, 3) posed body vertices, world metres; triangles: (T, 3) vertex indices.
        joints: (19, 3) posed joints, world metres.
        radii: (19,) skin radius at each joint, metres (``subjects.joint_radius_array``).
        appearance: :func:`draw_appearance`'s dict (sleeve length).
    Returns:
        (T,) int32. Each triangle takes the garment of its nearest bone; hands (the last 35 % of
        the forearm) and short-sleeved forearms are skin; head triangles behind the face or above
        the crown are hair.
    """
    centres = vertices[triangles].mean(axis=1)
    bone, t = _nearest_bone(centres, joints, radii)
    index = {p: i for i, p in enumerate(PARTS)}
    labels = np.array([index[_BONE_PART[JOINT_NAMES[b]]] for b in bone], np.int32)
    forearm = np.isin(bone, [JOINT_INDEX["l_wrist"], JOINT_INDEX["r_wrist"]])
    skin_from = 0.0 if appearance["sleeves"] == "short" else 0.65
    labels[forearm & (t >= skin_from)] = index["skin"]
    # facing direction: mean foot direction (ankle -> toe), horizontal
    fwd = (joints[JOINT_INDEX["l_toe"]] - joints[JOINT_INDEX["l_ankle"]]) + (
        joints[JOINT_INDEX["r_toe"]] - joints[JOINT_INDEX["r_ankle"]])
    fwd[2] = 0.0
    fwd /= max(np.linalg.norm(fwd), 1e-9)
    head = np.isin(bone, [JOINT_INDEX["head"], JOINT_INDEX["head_top"]])
    rel = centres - joints[JOINT_INDEX["head"]]
    hair = head & ((rel @ fwd < -0.02) | (rel[:, 2] > 0.06))
    labels[hair] = index["hair"]
    return labels


def room_centre(rig: Rig) -> np.ndarray:
    """(2,) metres: the floor point the square room is centred on, the centre of the rig's workspace (a lab
    calibrated with its origin in a room corner gets its room around where people walk, not around (0, 0))."""
    return np.asarray(rig.workspace.center, dtype=np.float64)


def room_half_size(rig: Rig) -> float:
    """Half side (metres) of the square room around :func:`room_centre`: the cameras stand 1 m inside its walls."""
    centre = room_centre(rig)
    return float(max(np.abs(cam.center[:2] - centre).max() for cam in rig) + 1.0)


ROOM_HEIGHT = 3.5

#: Props as axis-aligned boxes (centre x, y, z; size x, y, z) in metres, before placement; the
#: table is a top and four legs. Candidate places are tried in order (see :func:`place_props`).
PROP_SHAPES = {
    "box": [((0.0, 0.0, 0.3), (0.6, 0.6, 0.6))],
    "table": [((0.0, 0.0, 0.73), (1.2, 0.7, 0.04))]
    + [((sx * 0.55, sy * 0.3, 0.355), (0.05, 0.05, 0.71)) for sx in (-1, 1) for sy in (-1, 1)],
}
_PROP_RADII = (2.8, 3.4, 4.0, 4.6)


def _box_points(centre, size, n: int = 5) -> np.ndarray:
    g = np.linspace(-0.5, 0.5, n)
    p = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    return np.asarray(centre) + p * np.asarray(size)


def occludes(points: np.ndarray, rig: Rig) -> bool:
    """True if any point lies between some camera and the person volume (it could hide the person).

    A point P hides part of the volume from camera C when the ray from C through P, continued
    beyond P, enters the volume box :func:`person_volume` (slab test).
    """
    lo, hi = person_volume(rig)
    for cam in rig:
        d = points - cam.center
        with np.errstate(divide="ignore", invalid="ignore"):
            t1, t2 = (lo - cam.center) / d, (hi - cam.center) / d
        tmin = np.nanmax(np.where(d != 0, np.minimum(t1, t2), -np.inf), axis=1)
        tmax = np.nanmin(np.where(d != 0, np.maximum(t1, t2), np.inf), axis=1)
        inside_slabs = np.all((d != 0) | ((cam.center >= lo) & (cam.center <= hi)), axis=1)
        if np.any(inside_slabs & (tmax >= np.maximum(tmin, 1.0))):  # t >= 1: beyond the point
            return True
    return False


def place_props(rig: Rig) -> list[dict]:
    """Static props placed where they never hide the person volume from any camera.

    Candidates sit on rings of :data:`_PROP_RADII` around :func:`room_centre` every 15 degrees, in a fixed
    order; each prop takes the first candidate that is inside the room, clear of the other props
    and passes :func:`occludes` (so the layout is a pure function of the rig). A prop with no free
    place is left out.

    Returns:
        list of ``{"name", "boxes": [(centre (3,), size (3,)), ...], "colour"}``.
    """
    half, centre = room_half_size(rig), room_centre(rig)
    placed: list[dict] = []
    used: list[np.ndarray] = []
    candidates = [(r, a) for a in np.deg2rad(np.arange(180.0, 540.0, 15.0)) for r in _PROP_RADII]
    for name, shape in PROP_SHAPES.items():
        for r, a in candidates:
            c = np.array([centre[0] + r * np.cos(a), centre[1] + r * np.sin(a), 0.0])
            if np.abs(c[:2] - centre).max() > half - 1.0 or any(np.linalg.norm(c[:2] - u) < 1.8 for u in used):
                continue
            if any(np.linalg.norm(c[:2] - cam.center[:2]) < 1.5 for cam in rig):
                continue
            boxes = [(c + np.asarray(bc), np.asarray(bs, float)) for bc, bs in shape]
            if occludes(np.concatenate([_box_points(bc, bs) for bc, bs in boxes]), rig):
                continue
            placed.append({"name": name, "boxes": boxes, "colour": PROP_COLOURS[name]})
            used.append(c[:2])
            break
    return placed


def check_props_do_not_occlude(rig: Rig, props: list[dict]) -> None:
    """Raise ValueError if a prop could hide the person from a camera (dense sampling)."""
    for p in props:
        pts = np.concatenate([_box_points(bc, bs, n=11) for bc, bs in p["boxes"]])
        if occludes(pts, rig):
            raise ValueError(f"prop {p['name']!r} hides part of the workspace from a camera")


def sun_direction() -> np.ndarray:
    """(3,) unit vector from the scene towards the sun."""
    el, az = np.deg2rad(SUN["elevation_deg"]), np.deg2rad(SUN["azimuth_deg"])
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
