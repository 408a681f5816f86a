"""FBX and glTF motion clips (:mod:`silpose.datagen.blender.scene_clip`), read through the import cache.

Reference: the same motion as a BVH file (``silpose.datagen.testing.write_synthetic_bvh``), imported
by Blender's BVH importer; the FBX and glTF files are written from it by Blender's own exporters
(``silpose.datagen.testing.export_bvh_as``, in a subprocess: this process never imports bpy)."""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from silpose.datagen.motion.clips import ClipError, ensure_cached, read_entry
from silpose.datagen.motion.library import MANIFEST_NAME
from silpose.datagen.testing import (SYNTH_ROT_ORDER, SYNTH_SKELETON, synthetic_clip_motion, synthetic_clip_positions,
                                     write_synthetic_bvh)

pytestmark = pytest.mark.blender

N_FRAMES = 6


def export(bvh, out, **kw):
    args = ", ".join(f"{k}={v!r}" for k, v in kw.items())
    code = f"from silpose.datagen.testing import export_bvh_as; export_bvh_as({str(bvh)!r}, {str(out)!r}{', ' + args if args else ''})"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and out.is_file(), r.stderr[-2000:]
    return out


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scene_clips")
    bvh = write_synthetic_bvh(folder / "walk.bvh", n_frames=N_FRAMES)
    fbx = export(bvh, folder / "walk.fbx", scale=0.5, offset=(1.0, 2.0, 0.0))
    glb = export(bvh, folder / "walk.glb", scale=0.5, offset=(1.0, 2.0, 0.0))
    cube = export(bvh, folder / "cube.fbx", empty=True)
    return folder, bvh, fbx, glb, cube


def test_fbx_and_gltf_give_the_bvh_imports_positions_in_the_world(clips, tmp_path):
    folder, bvh, fbx, glb, _ = clips
    entries = ensure_cached([bvh, fbx, glb], tmp_path / "cache", workers=2)
    ref = read_entry(entries[bvh][1])
    expect = np.asarray(ref.heads, np.float64) * 0.5 + [1.0, 2.0, 0.0]  # the armature object scaled and moved
    for clip, importer in ((fbx, "io_scene_fbx"), (glb, "io_scene_gltf2")):
        got = read_entry(entries[clip][1])
        order = [got.meta["names"].index(n) for n in ref.meta["names"]]
        assert got.meta["frames"] == N_FRAMES, clip
        assert np.abs(np.asarray(got.heads, np.float64)[:, order] - expect).max() < 1e-5, clip
        assert [got.meta["names"][got.meta["parents"][i]] if got.meta["parents"][i] >= 0 else None for i in order] == \
            [ref.meta["names"][p] if p >= 0 else None for p in ref.meta["parents"]]
        assert got.meta["importer"].startswith(importer)
        assert got.meta["frame_time"] == pytest.approx(1 / 30, rel=1e-4)  # FBX states it; glTF sampled at 30 fps
    still = np.asarray(ref.heads[0], np.float64) * 0.5 + [1.0, 2.0, 0.0]
    assert np.abs(expect[1] - still).max() > 0.05  # the reference moves: frames are not all the rest pose


def write_node_gltf(path, n_frames: int = N_FRAMES, fps: float = 30.0, lying_first: bool = False):
    """The synthetic motion as an animation-only glTF (nodes, no skin), written from the glTF 2.0
    specification: node translations are the BVH offsets (glTF is Y up, metres, as the BVH), rotations
    the BVH channels as quaternions (scipy), the root's translation animated, End Sites leaf nodes."""
    pos, rot = synthetic_clip_motion(n_frames)
    if lying_first:  # the first frame lies on its front: the root turned 90 degrees about x
        rot[0, 0] = (90.0, 0.0, 0.0)
    axes = {"X": 0, "Y": 1, "Z": 2}
    J = len(SYNTH_SKELETON)
    nodes, blobs, accessors, views = [], [], [], []

    def add(arr: np.ndarray, kind: str, minmax: bool = False) -> int:
        data = np.ascontiguousarray(arr, np.float32).tobytes()
        offset = sum(len(b) for b in blobs)
        blobs.append(data)
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(data)})
        acc = {"bufferView": len(views) - 1, "componentType": 5126, "count": int(arr.shape[0]), "type": kind}
        if minmax:
            acc.update(min=[float(arr.min())], max=[float(arr.max())])
        accessors.append(acc)
        return len(accessors) - 1

    for j, (name, _, parent, off, end) in enumerate(SYNTH_SKELETON):
        nodes.append({"name": name, "translation": [float(v) for v in (pos[0] if parent < 0 else off)], "children": []})
    for j, (_, _, parent, _, _) in enumerate(SYNTH_SKELETON):
        if parent >= 0:
            nodes[parent]["children"].append(j)
    for j, (name, _, _, _, end) in enumerate(SYNTH_SKELETON):
        if end is not None:
            nodes.append({"name": name + "_end", "translation": [float(v) for v in end]})
            nodes[j]["children"].append(len(nodes) - 1)
    for n in nodes:
        if not n.get("children"):
            n.pop("children", None)
    times = add(np.arange(n_frames) / fps, "SCALAR", minmax=True)
    samplers, channels = [], []
    for j in range(J):
        angles = rot[:, j, [axes[a] for a in SYNTH_ROT_ORDER]]
        quats = Rotation.from_euler(SYNTH_ROT_ORDER, angles, degrees=True).as_quat()  # x, y, z, w
        samplers.append({"input": times, "output": add(quats, "VEC4"), "interpolation": "LINEAR"})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": j, "path": "rotation"}})
    samplers.append({"input": times, "output": add(pos, "VEC3"), "interpolation": "LINEAR"})
    channels.append({"sampler": len(samplers) - 1, "target": {"node": 0, "path": "translation"}})
    data = b"".join(blobs)
    doc = {"asset": {"version": "2.0", "generator": "silpose test"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": nodes, "animations": [{"name": "walk", "samplers": samplers, "channels": channels}],
           "accessors": accessors, "bufferViews": views,
           "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}]}
    path.write_text(json.dumps(doc))
    return path


def test_an_animation_only_gltf_reads_its_nodes_as_bones(tmp_path):
    """A glTF of animated nodes and no skin (a Mixamo clip exported without its mesh): the heads are
    the nodes' world positions, against the BVH definition's own forward kinematics."""
    clip = write_node_gltf(tmp_path / "nodes.gltf")
    got = read_entry(ensure_cached([clip], tmp_path / "cache", workers=1)[clip][1])
    expect, ends = synthetic_clip_positions(N_FRAMES)
    names = [row[0] for row in SYNTH_SKELETON]
    order = [got.meta["names"].index(n) for n in names]
    assert got.meta["frames"] == N_FRAMES and got.meta["frame_time"] == pytest.approx(1 / 30)
    assert np.abs(np.asarray(got.heads, np.float64)[:, order] - expect).max() < 1e-5
    h = names.index("Head")  # a node with one child (its End Site): the tail is that child
    assert np.abs(np.asarray(got.tails, np.float64)[:, order[h]] - ends[:, h]).max() < 1e-5
    assert [got.meta["names"][got.meta["parents"][i]] if got.meta["parents"][i] >= 0 else None for i in order] == \
        [names[row[2]] if row[2] >= 0 else None for row in SYNTH_SKELETON]


def test_a_gltf_whose_first_frame_lies_is_not_turned(tmp_path):
    """glTF states Y up, so its clips are not stood up from their rest pose -- which, for nodes, is the first
    frame: a clip that starts lying (someone getting up) keeps it (a BVH would be judged by its OFFSETs)."""
    from silpose.datagen.motion.build import ClipSource, import_clips
    from silpose.datagen.motion.library import load_library

    clip = write_node_gltf(tmp_path / "getting_up.gltf", lying_first=True)
    import_clips([ClipSource(path=clip, id="up")], tmp_path / "lib", fps=30.0, workers=1, cache=tmp_path / "cache")
    lib = load_library(tmp_path / "lib")
    assert "rest_up" not in lib.clips[0]
    dirs = lib.dirs[lib.rows(0)]
    spine = dirs[:, 0]  # pelvis -> spine, frame by frame
    assert abs(spine[0, 2]) < 0.3 and spine[1:, 2].min() > 0.5  # the first frame lies, the others stand


def test_a_file_without_an_animated_armature_or_not_fbx_is_a_one_line_error(clips, tmp_path):
    folder, *_, cube = clips
    with pytest.raises(ClipError, match=r"cube\.fbx: no animated armature in the file \(0 armatures"):
        ensure_cached([cube], tmp_path / "cache", workers=1)
    junk = tmp_path / "junk.fbx"
    junk.write_text("not an fbx file\n")
    with pytest.raises(ClipError, match=r"junk\.fbx: Blender's FBX importer failed \(") as info:
        ensure_cached([junk], tmp_path / "cache", workers=1)
    assert "\n" not in str(info.value)


def test_motions_import_takes_fbx_and_glb_and_keeps_one_id_per_file(clips, tmp_path):
    folder, *_ = clips
    lib = tmp_path / "lib"
    env = {**os.environ, "SILPOSE_CACHE_DIR": str(tmp_path / "cache")}
    r = subprocess.run([sys.executable, "-m", "silpose.shared.cli", "motions", "import", str(folder), "--library",
                        str(lib), "-j", "2"], capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, r.stderr
    skipped = [ln for ln in r.stderr.splitlines() if ln.startswith("skipped: ")]
    assert len(skipped) == 1 and "cube.fbx: no animated armature" in skipped[0], r.stderr
    clips_ = {c["id"]: c for c in json.loads((lib / MANIFEST_NAME).read_text())["clips"]}
    assert sorted(clips_) == ["walk.bvh", "walk.fbx", "walk.glb"]  # one stem, three files: three ids
    assert {c["joint_map"] for c in clips_.values()} == {"cmu"}
    assert clips_["walk.fbx"]["extent_m"] == pytest.approx(0.5 * clips_["walk.bvh"]["extent_m"], rel=1e-4)
