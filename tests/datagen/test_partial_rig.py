"""Rigs whose cameras do not all see the whole workspace (``silpose rig import --min-views``): ``silpose gen``
places its walkers on the part every camera sees, and the dataset keeps the rig's whole workspace."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.datagen.config import ConfigError, load_config
from silpose.datagen.render import RenderResult
from silpose.datagen.testing import tiny_config_toml
from silpose.datagen.worker import SampleError, check_worker_config, motion_from_config, placement_area, render_sample
from silpose.shared.camera import RigError, ring_rig
from silpose.shared.rig_frame import PERSON_HEIGHT_M, Workspace
from silpose.shared.skeleton import BONES

BASE = tiny_config_toml() + '[rig]\nfile = "rig.json"\n'


class StickRenderer:
    """Stand-in renderer (not Blender): the posed joints' bones drawn 7 px thick, so a draw whose body leaves
    an image touches its border and is redrawn, as with the real renderers."""

    def open(self, rig) -> None:
        self.rig = rig

    def close(self) -> None:
        pass

    def render(self, scene) -> RenderResult:
        J = scene.pose.joints
        masks = np.zeros((len(self.rig), self.rig[0].height, self.rig[0].width), np.uint8)
        for k, cam in enumerate(self.rig):
            uv = np.round(cam.project(J)).astype(np.int32)
            for a, b in BONES:
                cv2.line(masks[k], tuple(map(int, uv[a])), tuple(map(int, uv[b])), 1, thickness=7)
        return RenderResult(joints=J, masks=masks)


@pytest.fixture
def partial(tmp_path):
    """A 4-camera ring whose longer lens sees a 2.4 m x 2.35 m part of the 3 m x 3 m workspace."""
    rig = ring_rig(focal_px=600.0)
    (tmp_path / "rig.json").write_text(rig.to_json())
    (tmp_path / "cfg.toml").write_text(BASE)
    return rig, tmp_path / "cfg.toml"


def test_gen_accepts_a_rig_file_whose_workspace_some_camera_misses(partial):
    rig, path = partial
    with pytest.raises(RigError, match="does not see the workspace corner"):
        rig.check_sees_workspace(height=PERSON_HEIGHT_M)  # the rig really misses part of its workspace
    cfg = load_config(path)  # refused before: "camera 'cam0' does not see the workspace corner"
    p = cfg.placement
    assert p is not None and np.all(p.size < 3.0) and np.all(p.size > 2.0)
    cfg.rig.check_sees_workspace(height=PERSON_HEIGHT_M, workspace=p)  # every camera sees the placement area
    assert cfg.rig.workspace.to_dict() == Workspace().to_dict()  # the dataset keeps the whole workspace
    wc = cfg.worker_config()
    assert wc["placement"] == p.to_dict() and "workspace" not in wc["rig"]
    assert cfg.to_dict()["placement"] == p.to_dict()
    # and about the largest such part: 0.1 m more on every side is not seen
    grown = Workspace(p.center, p.size + 0.2)
    with pytest.raises(RigError, match="does not see"):
        cfg.rig.check_sees_workspace(height=PERSON_HEIGHT_M, workspace=grown)


def test_walkers_land_where_every_camera_sees_them(partial):
    """Samples drawn on the placement area need few redraws and all stand inside it; drawn on the rig's whole
    workspace (what a rig file's workspace meant before), many more draws are rejected."""
    _, path = partial
    wc = load_config(path).worker_config()
    seed, rig, n_points, max_redraws = check_worker_config(wc)
    area = placement_area(wc, rig)
    renderer = StickRenderer()
    renderer.open(rig)
    records = [render_sample(renderer, seed, "train", i, rig, 32, max_redraws, motion_from_config(wc, area))
               for i in range(16)]
    xy = np.array([[r["gait"]["x"], r["gait"]["y"]] for r in records])
    assert np.all(area.contains(xy))
    assert not any(r["touches_border"].any() for r in records)
    whole = [render_sample(renderer, seed, "train", i, rig, 32, max_redraws, motion_from_config(wc, rig.workspace))
             for i in range(16)]
    assert sum(r["redraws"] for r in records) < sum(r["redraws"] for r in whole)


def test_a_rig_no_part_of_whose_workspace_every_camera_sees_is_still_refused(tmp_path):
    (tmp_path / "rig.json").write_text(ring_rig(focal_px=2000.0).to_json())  # a 2 m person never fits
    (tmp_path / "cfg.toml").write_text(BASE)
    with pytest.raises(ConfigError, match="no part of the workspace is seen by every camera") as err:
        load_config(tmp_path / "cfg.toml")
    assert str(err.value).startswith(f"{tmp_path / 'rig.json'}: camera 'cam0' does not see the workspace corner")


def test_a_sample_does_not_depend_on_max_redraws(partial):
    """Why ``max_redraws`` may change on a resume (``silpose.datagen.shards.RESUME_NEUTRAL``): a sample found
    within 50 draws is the same record with 1000 allowed, and with fewer than it needed it fails."""
    _, path = partial
    wc = load_config(path).worker_config()
    seed, rig, _, _ = check_worker_config(wc)
    renderer = StickRenderer()
    renderer.open(rig)
    motion = motion_from_config(wc, rig.workspace)  # the whole workspace: many draws are rejected
    checked = 0
    for i in range(12):
        a = render_sample(renderer, seed, "test", i, rig, 32, 50, motion)
        if a["redraws"] == 0:
            continue
        b = render_sample(renderer, seed, "test", i, rig, 32, 1000, motion)
        assert a.keys() == b.keys()
        for k in a:
            np.testing.assert_array_equal(np.asarray(a[k] if k not in ("subject", "gait") else list(a[k].items())),
                                          np.asarray(b[k] if k not in ("subject", "gait") else list(b[k].items())))
        with pytest.raises(SampleError, match="max_redraws"):
            render_sample(renderer, seed, "test", i, rig, 32, a["redraws"] - 1, motion)
        checked += 1
    assert checked >= 3
