"""Test helpers that must live in the installed package (spawned workers import them by name).

Mostly a synthetic stand-in renderer for unit tests of the pipeline (NOT a person, NOT Blender):
``synthetic_render_samples`` has the signature and record layout of
``silpose.datagen.worker.render_samples`` but draws a stick figure with thick OpenCV lines
instead of rendering a body, so IO, sharding, resume and executor logic can be tested in
milliseconds. Every sample is a pure function of ``(config["seed"], split, index)``.
:func:`render_scenes_with` renders the same scenes with several registered renderers (Blender,
in a spawned worker) to compare them through the renderer protocol.
"""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import cv2
import numpy as np

from silpose.shared.camera import Rig
from silpose.shared.contours import extract_contours, normalise
from silpose.shared.seeds import SPLIT_CODE, derive_rng
from silpose.shared.skeleton import BONES, N_JOINTS

from .config import GenConfig, load_config
from .render import rendering
from .renderers import renderer_from_config
from .scene import draw_scene, joints_visible

#: ``render=`` value of ``pipeline.generate`` that uses :func:`synthetic_render_samples`
SYNTH_RENDER = "silpose.datagen.testing:synthetic_render_samples"


def tiny_config_toml(seed: int = 7, shard_size: int = 4, train: int = 8, test: int = 4) -> str:
    """The TOML text of a tiny raster-renderer config (default rig) for pipeline tests."""
    return (f'name = "tiny"\nseed = {seed}\nrenderer = "raster"\nblender_engine = "workbench"\n'
            f"shard_size = {shard_size}\nn_points = 200\nmax_redraws = 50\n[splits]\ntrain = {train}\ntest = {test}\n")


def tiny_config(folder, text: str | None = None) -> GenConfig:
    """A validated GenConfig written to ``folder/tiny.toml`` (``text`` default: :func:`tiny_config_toml`)."""
    path = Path(folder) / "tiny.toml"
    path.write_text(tiny_config_toml() if text is None else text)
    return load_config(path)


SUBJECT_FIELDS = ("height", "shoulder_width", "hip_width")
GAIT_FIELDS = ("phase", "stride", "arm_swing", "knee_flex", "heading", "x", "y")
#: Split key of an unknown split (the stand-in renders any split name).
OTHER_SPLIT_CODE = 9

# A rough standing pose (metres), pelvis at 0.95 m, facing +x.
_REST = np.array(
    [
        [0, 0, 0.95], [0, 0, 1.2], [0, 0, 1.45], [0, 0, 1.58], [0, 0, 1.72],
        [0, 0.18, 1.42], [0, 0.22, 1.15], [0, 0.24, 0.9],
        [0, -0.18, 1.42], [0, -0.22, 1.15], [0, -0.24, 0.9],
        [0, 0.1, 0.92], [0, 0.11, 0.5], [0, 0.11, 0.08], [0.15, 0.11, 0.02],
        [0, -0.1, 0.92], [0, -0.11, 0.5], [0, -0.11, 0.08], [0.15, -0.11, 0.02],
    ],
    dtype=np.float64,
)


def synthetic_record(config: dict, split: str, index: int) -> dict:
    """One synthetic record (see ``silpose.datagen.worker.render_samples`` for the fields).

    Draws from ``derive_rng(seed, SPLIT_CODE[split], index)`` (:data:`OTHER_SPLIT_CODE` for other
    split names): three keys, so never the stream of a real sample draw (four keys).
    """
    rng = derive_rng(config["seed"], SPLIT_CODE.get(split, OTHER_SPLIT_CODE), index)
    rig = Rig.from_dict(config["rig"])
    width, height = rig.image_size
    heading = rng.uniform(-np.pi, np.pi)
    x, y = rng.uniform(-1.0, 1.0, size=2)
    scale = rng.uniform(0.9, 1.1)
    c, s = np.cos(heading), np.sin(heading)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    joints = (_REST * scale + rng.normal(0, 0.02, size=(N_JOINTS, 3))) @ rot.T + [x, y, 0]
    uv = rig.project(joints)  # (K, 19, 2)
    masks = np.zeros((len(rig), height, width), np.uint8)
    for k in range(len(rig)):
        pts = np.round(uv[k] * 16).astype(np.int32)
        for a, b in BONES:
            cv2.line(masks[k], tuple(pts[a]), tuple(pts[b]), 1, thickness=9, lineType=cv2.LINE_8, shift=4)
        cv2.circle(masks[k], tuple(pts[3]), 9 * 16, 1, thickness=-1, shift=4)
    n = int(config["n_points"])
    cont = extract_contours(masks, n)
    _, centroid, scale_px = normalise(cont["points"])
    return {
        "sample_id": int(index),
        "split": split,
        "seed": int(config["seed"]),
        "redraws": int(rng.integers(0, 2)),
        "subject": {"height": float(1.72 * scale), "shoulder_width": 0.36 * scale, "hip_width": 0.2 * scale},
        "gait": {
            "phase": float(rng.uniform()), "stride": 0.7, "arm_swing": 0.3, "knee_flex": 0.5,
            "heading": float(heading), "x": float(x), "y": float(y),
        },
        "joints": joints.astype(np.float32),
        "masks": masks,
        "contours": cont["points"],
        "contour_centroid": centroid.astype(np.float32),
        "contour_scale": scale_px.astype(np.float32),
        "touches_border": cont["touches_border"],
        "n_blobs": cont["n_blobs"],
        "contour_length": cont["length"],
        "area": cont["area"],
    }


def write_synthetic_dataset(root, shard_rows=(30, 25, 30, 15), n_points: int = 16, n_test: int = 5,
                            name: str = "sharded", seed: int = 5, clip_of=None) -> Path:
    """A dataset folder of :func:`synthetic_record` rows written with the dataset writer: train shards of
    ``shard_rows`` rows each (uneven by default), one test shard of ``n_test`` rows, a manifest; default rig.
    ``clip_of``: row index -> motion-capture clip (0 = the procedural walk), written to every row's ``gait``
    as a clip-posed dataset's are (``clip``, ``frame`` = index mod 8, ``mirror`` 0); None: no clips.
    Returns ``root`` (created; must not exist)."""
    import json

    from silpose.shared.camera import default_rig
    from silpose.shared.dataset import write_shard
    from silpose.shared.dataset_schema import build_metadata

    root = Path(root)
    root.mkdir(parents=True)
    rig = default_rig()
    config = {"name": name, "seed": seed, "rig": rig.to_dict(), "n_points": n_points}
    meta = build_metadata(rig.to_dict()["cameras"], config, n_points, generator_version="test")
    def record(split: str, i: int) -> dict:
        r = synthetic_record(config, split, i)
        if clip_of is not None:
            r["gait"] = {"clip": float(clip_of(i)), "frame": float(i % 8), "mirror": 0.0, **r["gait"]}
        return r

    start = 0
    for s, n in enumerate(shard_rows):
        records = [record("train", i) for i in range(start, start + n)]
        write_shard(root / f"train-{s:05d}-of-{len(shard_rows):05d}.parquet", records, meta)
        start += n
    write_shard(root / "test-00000-of-00001.parquet", [record("test", i) for i in range(n_test)], meta)
    (root / "manifest.json").write_text(json.dumps({"name": name}))
    return root


def synthetic_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in for ``render_samples``: one synthetic record per index."""
    return [synthetic_record(config, split, i) for i in indices]


def failing_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in that renders ``train`` and fails on every other split (tests worker failures)."""
    if split != "train":
        raise RuntimeError(f"synthetic failure on split {split}")
    return synthetic_render_samples(config, split, indices)


def wrong_ids_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in returning the right records under shifted sample ids (tests the driver's check)."""
    records = synthetic_render_samples(config, split, indices)
    for r in records:
        r["sample_id"] += 1
    return records


def crashing_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in whose worker process dies abruptly on every split but ``train`` (tests the watchdog)."""
    if split != "train":
        os._exit(3)
    return synthetic_render_samples(config, split, indices)


def kill_process_group(pid: int) -> None:
    """SIGKILL the process group led by ``pid`` (a driver started with ``start_new_session=True`` and its
    workers), if any of it is left; the cleanup of the fault drills."""
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass


def exit_or_square(message: tuple[int, int]) -> tuple[int, int]:
    """A :func:`silpose.datagen.executor.spawned_map` call for tests: ``(code, x)`` exits the worker
    process with ``code`` when it is not 0, else returns ``(x * x, pid)``."""
    code, x = message
    if code:
        os._exit(code)
    return x * x, os.getpid()


#: ``killing_render_samples`` reads ``"<split>:<index>:<marker file>"`` from this variable.
KILL_ENV = "SILPOSE_TEST_KILL_AT"
#: ``slow_render_samples`` sleeps this many seconds per sample (a float).
DELAY_ENV = "SILPOSE_TEST_RENDER_DELAY"
#: ``slow_render_samples`` creates ``<this folder>/<worker pid>`` when it starts a shard (if set).
STARTED_ENV = "SILPOSE_TEST_RENDER_STARTED"


def killing_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """Stand-in whose worker SIGKILLs itself once, mid-shard, on a chosen sample (fault drills).

    ``$SILPOSE_TEST_KILL_AT = "<split>:<index>:<marker>"``: on reaching sample ``index`` of ``split``,
    after rendering the shard's earlier samples, the worker creates ``marker`` and kills itself with
    SIGKILL -- unless ``marker`` already exists (so a rerun goes through). Otherwise it is
    ``synthetic_render_samples``.
    """
    spec = os.environ.get(KILL_ENV, "")
    records = []
    for i in indices:
        if spec:
            kill_split, kill_index, marker = spec.split(":", 2)
            if split == kill_split and int(kill_index) == int(i):
                try:
                    os.close(os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
                except FileExistsError:
                    pass
                else:
                    os.kill(os.getpid(), signal.SIGKILL)
        records.append(synthetic_record(config, split, i))
    return records


def slow_render_samples(config: dict, split: str, indices: list[int]) -> list[dict]:
    """``synthetic_render_samples`` sleeping ``$SILPOSE_TEST_RENDER_DELAY`` s per sample (overlapping runs);
    announces each shard it starts in the folder ``$SILPOSE_TEST_RENDER_STARTED`` when that is set."""
    delay = float(os.environ.get(DELAY_ENV, "0.1"))
    if os.environ.get(STARTED_ENV):
        Path(os.environ[STARTED_ENV], str(os.getpid())).touch()
    records = []
    for i in indices:
        time.sleep(delay)
        records.append(synthetic_record(config, split, i))
    return records


def render_scenes_with(config: dict, names: list[str], split: str, indices: list[int]) -> dict[str, list[dict]]:
    """Render the same scenes with each renderer of ``names``, through the Renderer protocol only.

    Call in a spawned worker (Blender). Scene i is the first draw of sample ``indices[i]`` whose
    joints and (for the first renderer) posed mesh are inside every image.

    Returns:
        ``{name: [{"redraw", "joints" (19, 3), "masks" (K, H, W)} per index]}``.
    """
    rig = Rig.from_dict(config["rig"])
    renderers = [renderer_from_config(config, n) for n in names]
    scenes = []
    with rendering(renderers[0], rig) as first:
        out = {names[0]: []}
        for index in indices:
            for redraw in range(int(config["max_redraws"]) + 1):
                scene = draw_scene(int(config["seed"]), split, index, redraw, rig)
                if not joints_visible(scene):
                    continue
                result = first.render(scene)
                if result.masks is not None:
                    break
            else:
                raise RuntimeError(f"{split} sample {index}: no visible draw")
            scenes.append(scene)
            out[names[0]].append({"redraw": redraw, "joints": result.joints, "masks": result.masks})
    for name, renderer in zip(names[1:], renderers[1:]):
        with rendering(renderer, rig):
            out[name] = []
            for scene in scenes:
                r = renderer.render(scene)
                out[name].append({"redraw": scene.redraw, "joints": r.joints, "masks": r.masks})
    return out


# ----------------------------------------------------------------------------- synthetic BVH clips
#
# A small known skeleton for the motion-capture tests, written as BVH text in two naming schemes
# (``cmu`` and ``hip-knee``) and two units, with an independent forward kinematics of the file's
# own definition (BVH: Y up, a joint's frame is its parent's frame translated by OFFSET then
# rotated by its channels in the order listed) to check Blender's import and the retargeting.

#: (cmu name, hip-knee name, parent index, OFFSET in metres (BVH axes: x left, y up, z forward),
#: End Site offset or None). Left is +x for a character facing +z.
SYNTH_SKELETON: tuple = (
    ("Hips", "Hips", -1, (0.0, 0.0, 0.0), None),
    ("Spine", "Spine", 0, (0.0, 0.12, 0.0), None),
    ("Spine1", "Chest", 1, (0.0, 0.15, 0.0), None),
    ("Neck", "Neck", 2, (0.0, 0.18, 0.0), None),
    ("Head", "Head", 3, (0.0, 0.10, 0.01), (0.0, 0.17, 0.0)),
    ("LeftShoulder", "LeftCollar", 2, (0.03, 0.16, 0.0), None),
    ("LeftArm", "LeftShoulder", 5, (0.15, 0.01, 0.0), None),
    ("LeftForeArm", "LeftElbow", 6, (0.28, 0.0, 0.0), None),
    ("LeftHand", "LeftWrist", 7, (0.25, 0.0, 0.0), (0.07, 0.0, 0.0)),
    ("RightShoulder", "RightCollar", 2, (-0.03, 0.16, 0.0), None),
    ("RightArm", "RightShoulder", 9, (-0.15, 0.01, 0.0), None),
    ("RightForeArm", "RightElbow", 10, (-0.28, 0.0, 0.0), None),
    ("RightHand", "RightWrist", 11, (-0.25, 0.0, 0.0), (-0.07, 0.0, 0.0)),
    ("LeftUpLeg", "LeftHip", 0, (0.09, -0.06, 0.0), None),
    ("LeftLeg", "LeftKnee", 13, (0.0, -0.42, 0.0), None),
    ("LeftFoot", "LeftAnkle", 14, (0.0, -0.41, 0.0), None),
    ("LeftToeBase", "LeftToe", 15, (0.0, -0.05, 0.13), (0.0, 0.0, 0.05)),
    ("RightUpLeg", "RightHip", 0, (-0.09, -0.06, 0.0), None),
    ("RightLeg", "RightKnee", 17, (0.0, -0.42, 0.0), None),
    ("RightFoot", "RightAnkle", 18, (0.0, -0.41, 0.0), None),
    ("RightToeBase", "RightToe", 19, (0.0, -0.05, 0.13), (0.0, 0.0, 0.05)),
)
#: Rotation channel order of every joint (the root adds X/Y/Z position first).
SYNTH_ROT_ORDER = "ZXY"


def synthetic_clip_motion(n_frames: int = 4, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Known motion of :data:`SYNTH_SKELETON`: root positions (F, 3) metres (BVH axes) and
    rotations (F, J, 3) degrees in :data:`SYNTH_ROT_ORDER`; frame 0 is the rest pose lifted to
    0.95 m, later frames turn every joint by up to 35 degrees about each axis (the root: any
    yaw about y, up to 15 degrees about x and z)."""
    rng = np.random.default_rng(seed)
    J = len(SYNTH_SKELETON)
    pos = np.tile([0.0, 0.95, 0.0], (n_frames, 1))
    rot = np.zeros((n_frames, J, 3))
    for f in range(1, n_frames):
        pos[f] += (rng.uniform(-0.5, 0.5), rng.uniform(-0.1, 0.05), rng.uniform(-0.5, 0.5))
        rot[f] = rng.uniform(-35.0, 35.0, size=(J, 3))
        rot[f, 0] = (rng.uniform(-15.0, 15.0), rng.uniform(-180.0, 180.0), rng.uniform(-15.0, 15.0))  # root: any yaw (Y)
    return pos, rot


def write_synthetic_bvh(path, scheme: str = "cmu", unit: float = 1.0, n_frames: int = 4, seed: int = 0,
                        up: str = "y") -> Path:
    """Write :data:`SYNTH_SKELETON` with :func:`synthetic_clip_motion` as a BVH file.

    Args:
        scheme: ``"cmu"`` or ``"hip-knee"`` joint names.
        unit: metres per file unit (0.01 writes centimetres).
        up: ``"y"`` (the BVH convention) or ``"z"``: the same motion written Z up, as some exporters
            do (every vector p -> A p with A = R_x(90 deg): (x, y, z) -> (x, -z, y); each rotation
            Rz(a) Rx(b) Ry(c) -> A R A^T = Ry(-a) Rx(b) Rz(c), channels Y X Z).
    """
    col = {"cmu": 0, "hip-knee": 1}[scheme]
    pos, rot = synthetic_clip_motion(n_frames, seed)
    axes = {"X": 0, "Y": 1, "Z": 2}
    lines = ["HIERARCHY"]
    order_ch = SYNTH_ROT_ORDER
    if up == "z":
        def turn(v):
            return (v[0], -v[2], v[1])
        pos = np.array([turn(p) for p in pos])
        z_up = np.stack([-rot[..., 2], rot[..., 0], rot[..., 1]], axis=-1)  # Y, X, Z channel values
        order_ch, rot = "YXZ", np.zeros_like(rot)
        rot[..., 1], rot[..., 0], rot[..., 2] = z_up[..., 0], z_up[..., 1], z_up[..., 2]
    elif up != "y":
        raise ValueError(f"up must be 'y' or 'z', got {up!r}")
    assert SYNTH_ROT_ORDER == "ZXY"  # the channel algebra above

    def emit(j: int, depth: int) -> None:
        name, off, end = SYNTH_SKELETON[j][col], SYNTH_SKELETON[j][3], SYNTH_SKELETON[j][4]
        if up == "z":
            off, end = turn(off), (None if end is None else turn(end))
        pad = "\t" * depth
        lines.append(f"{pad}{'ROOT' if j == 0 else 'JOINT'} {name}")
        lines.append(f"{pad}{{")
        lines.append(f"{pad}\tOFFSET " + " ".join(f"{v / unit:.6f}" for v in off))
        chans = [f"{a}rotation" for a in order_ch]
        if j == 0:
            chans = ["Xposition", "Yposition", "Zposition"] + chans
        lines.append(f"{pad}\tCHANNELS {len(chans)} " + " ".join(chans))
        for k, row in enumerate(SYNTH_SKELETON):
            if row[2] == j:
                emit(k, depth + 1)
        if end is not None:
            lines.extend([f"{pad}\tEnd Site", f"{pad}\t{{", f"{pad}\t\tOFFSET " + " ".join(f"{v / unit:.6f}" for v in end),
                          f"{pad}\t}}"])
        lines.append(f"{pad}}}")

    emit(0, 0)
    order: list[int] = []

    def walk(j: int) -> None:
        order.append(j)
        for k, row in enumerate(SYNTH_SKELETON):
            if row[2] == j:
                walk(k)

    walk(0)
    lines += ["MOTION", f"Frames: {n_frames}", "Frame Time: 0.0333333"]
    for f in range(n_frames):
        vals = [v / unit for v in pos[f]]
        for j in order:
            vals += [rot[f, j, axes[a]] for a in order_ch]
        lines.append(" ".join(f"{v:.6f}" for v in vals))
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def _axis_rot(axis: str, deg: float) -> np.ndarray:
    a = np.deg2rad(deg)
    c, s = np.cos(a), np.sin(a)
    return {"X": np.array([[1, 0, 0], [0, c, -s], [0, s, c]]), "Y": np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]),
            "Z": np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])}[axis]


def synthetic_clip_positions(n_frames: int = 4, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Independent forward kinematics of the file :func:`write_synthetic_bvh` writes, in metres, in
    Blender's axes after its BVH import (x, y, z)_Blender = (x, -z, y)_BVH.

    Returns:
        joints (F, J, 3) and end sites (F, J, 3) (NaN where a joint has no End Site).
    """
    pos, rot = synthetic_clip_motion(n_frames, seed)
    axes = {"X": 0, "Y": 1, "Z": 2}
    J = len(SYNTH_SKELETON)
    out = np.zeros((n_frames, J, 3))
    ends = np.full((n_frames, J, 3), np.nan)
    to_blender = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    for f in range(n_frames):
        R = np.zeros((J, 3, 3))
        P = np.zeros((J, 3))
        for j, (_, _, parent, off, end) in enumerate(SYNTH_SKELETON):
            local = np.eye(3)
            for a in SYNTH_ROT_ORDER:  # channels listed Z X Y: R = Rz Rx Ry
                local = local @ _axis_rot(a, rot[f, j, axes[a]])
            if parent < 0:
                R[j], P[j] = local, pos[f]
            else:
                R[j] = R[parent] @ local
                P[j] = P[parent] + R[parent] @ np.asarray(off)
            if end is not None:
                ends[f, j] = P[j] + R[j] @ np.asarray(end)
        out[f] = P @ to_blender.T
        ends[f] = ends[f] @ to_blender.T
    return out, ends


def export_bvh_as(bvh: str, out: str, scale: float = 1.0, offset: tuple = (0.0, 0.0, 0.0), empty: bool = False) -> None:
    """Tests only, in a process that may import bpy: import ``bvh`` with Blender's BVH importer (as
    :func:`silpose.datagen.blender.bvh.import_clip` does) and write it with Blender's FBX or glTF
    exporter (by ``out``'s suffix), the armature object scaled by ``scale`` and moved by ``offset``
    (metres) first; ``empty`` writes a cube and no armature instead."""
    import bpy
    import addon_utils

    bpy.ops.wm.read_factory_settings(use_empty=True)
    for module in ("io_anim_bvh", "io_scene_fbx", "io_scene_gltf2"):
        addon_utils.enable(module, default_set=False)
    if empty:
        bpy.ops.mesh.primitive_cube_add()
    else:
        bpy.ops.import_anim.bvh(filepath=str(bvh), global_scale=1.0, frame_start=1, use_fps_scale=False,
                                update_scene_fps=True, update_scene_duration=True, rotate_mode="NATIVE",
                                axis_forward="-Z", axis_up="Y")
        arm = next(o for o in bpy.data.objects if o.type == "ARMATURE")
        arm.scale = (scale, scale, scale)
        arm.location = offset
    if str(out).lower().endswith(".fbx"):
        bpy.ops.export_scene.fbx(filepath=str(out), add_leaf_bones=False, bake_anim=True, bake_anim_simplify_factor=0.0)
    else:
        bpy.ops.export_scene.gltf(filepath=str(out), export_format="GLB", export_animations=True)
