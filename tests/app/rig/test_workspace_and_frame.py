"""The automatic frame (up axis, origin, floor) and workspace (largest fully visible floor rectangle)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from silpose.app.rig.examples import LAB_IMAGE_SIZE, one_wall_lab, one_wall_lab_room, to_calibration_frame
from silpose.app.rig.frame import AXES, auto_up, frame_rotation, parse_unit
from silpose.app.rig.importer import ImportOptions, import_rig
from silpose.app.rig.opencv import write_opencv_camera
from silpose.app.rig.workspace import (
    auto_workspace,
    largest_histogram_rectangle,
    largest_rectangle,
    project_fast,
    visibility_grid,
)
from silpose.shared.camera import Camera, default_rig, ring_rig
from silpose.shared.rig_frame import PERSON_HEIGHT_M, WorldTransform

# ------------------------------------------------------------------------------ maximal rectangle


def brute_force_rectangle(mask: np.ndarray) -> int:
    """Largest all-True rectangle area by trying every rectangle."""
    ny, nx = mask.shape
    best = 0
    for r0, c0 in itertools.product(range(ny), range(nx)):
        for r1, c1 in itertools.product(range(r0, ny), range(c0, nx)):
            if mask[r0:r1 + 1, c0:c1 + 1].all():
                best = max(best, (r1 - r0 + 1) * (c1 - c0 + 1))
    return best


@pytest.mark.parametrize("seed", range(40))
def test_largest_rectangle_matches_brute_force_on_small_grids(seed):
    rng = np.random.default_rng(seed)
    ny, nx = rng.integers(1, 8, size=2)
    mask = rng.uniform(size=(ny, nx)) < rng.uniform(0.3, 0.95)
    rect = largest_rectangle(mask)
    best = brute_force_rectangle(mask)
    if best == 0:
        assert rect is None
        return
    r0, r1, c0, c1 = rect
    assert mask[r0:r1 + 1, c0:c1 + 1].all()
    assert (r1 - r0 + 1) * (c1 - c0 + 1) == best


def test_histogram_rectangle_by_hand():
    assert largest_histogram_rectangle([2, 1, 5, 6, 2, 3]) == (10, 2, 3, 5)
    assert largest_histogram_rectangle([0, 0]) == (0, 0, -1, 0)
    assert largest_rectangle(np.zeros((3, 3), bool)) is None


# ------------------------------------------------------------------------------ projection, visibility


@pytest.mark.parametrize("n", [4, 5, 8, 12, 14])
def test_fast_projection_matches_opencv(n):
    c = default_rig()[1]
    dist = np.array([-0.2, 0.07, 0.001, -0.0007, -0.01, 0.02, -0.01, 0.003, 1e-3, -2e-3, 5e-4, 1e-3, 0.01, -0.02])[:n]
    cam = Camera(c.name, c.K, c.R, c.t, c.width, c.height, dist)
    X = np.random.default_rng(3).uniform([-2, -2, 0], [2, 2, 2], size=(300, 3))
    np.testing.assert_allclose(project_fast(cam, X), cam.project(X), atol=1e-9, rtol=0)


def test_visibility_grid_agrees_with_projecting_a_person_by_hand():
    rig = default_rig()
    grid = visibility_grid(rig, step=0.25)
    rng = np.random.default_rng(4)
    for r, c in zip(rng.integers(0, len(grid.ys), 60), rng.integers(0, len(grid.xs), 60)):
        x, y, h = grid.xs[c], grid.ys[r], grid.step / 2
        corners = np.array([[x + sx * h, y + sy * h, z] for sx in (-1, 1) for sy in (-1, 1) for z in (0, PERSON_HEIGHT_M)])
        for k, cam in enumerate(rig):
            seen = bool(np.all(cam.to_camera(corners)[:, 2] > 0) and np.all(cam.in_image(cam.project(corners))))
            tall = np.linalg.norm(np.diff(cam.project(np.array([[x, y, 0], [x, y, PERSON_HEIGHT_M]])), axis=0)) >= 60
            assert grid.per_camera[k, r, c] == (seen and tall), (k, x, y)


def test_auto_workspace_of_the_default_rig_holds_its_3_by_3_square():
    ws, grid = auto_workspace(default_rig())
    assert ws.size.min() >= 3.0, ws.describe()
    (x0, x1), (y0, y1) = ws.bounds
    assert x0 <= -1.5 + 0.15 and x1 >= 1.5 - 0.15 and y0 <= -1.5 + 0.2 and y1 >= 1.5 - 0.2  # around the centre
    assert grid.visible.sum() * grid.step**2 < 25  # bounded: the four views meet around the centre only


def test_one_wall_lab_auto_workspace_is_at_least_2_by_2_and_walkers_drawn_in_it_are_in_view():
    """The issue's lab: 4 cameras along one wall of a 6 m x 8 m room at 2 m height."""
    from silpose.datagen.scene import draw_scene, joints_visible

    calib, _ = one_wall_lab()
    result = import_rig_from(calib)
    rig = result.rig
    assert rig.workspace.size.min() >= 2.0, rig.workspace.describe()
    rig.check_sees_workspace(height=PERSON_HEIGHT_M)
    # the generator's own draws on this rig: pelvis uniform in the workspace; nearly every first draw
    # is fully inside every image (a rejected draw is redrawn), and every kept draw is.
    first = [draw_scene(3, "train", i, 0, rig) for i in range(300)]
    xy = np.array([[s.motion["x"], s.motion["y"]] for s in first])
    assert rig.workspace.contains(xy).all()
    visible = np.array([joints_visible(s) for s in first])
    assert visible.mean() >= 0.95, visible.mean()
    for s in (s for s, v in zip(first, visible) if v):
        for cam in rig:
            assert cam.in_image(cam.project(s.pose.joints), margin=1.0).all()


def import_rig_from(calib, **kw):
    """Import in-memory calibrations by writing them as OpenCV files into a temporary folder."""
    import tempfile
    from pathlib import Path

    with tempfile.TemporaryDirectory(prefix="w10rig") as d:
        paths = []
        for c in calib:
            p = Path(d) / f"{c.name}.yml"
            write_opencv_camera(p, c)
            paths.append(p)
        size = "x".join(map(str, LAB_IMAGE_SIZE)) if calib[0].size is None else None
        return import_rig(paths, ImportOptions(unit=kw.pop("unit", "mm"), image_size=size, **kw))


# ------------------------------------------------------------------------------ up axis and origin


@pytest.mark.parametrize("up", ["+z", "-z", "+y", "-y", "+x"])
@pytest.mark.parametrize("scale", [0.001, 1.0])
def test_auto_up_and_origin_find_a_symmetric_ring_in_any_world(up, scale):
    """A 4-camera ring centred at silpose (0, 0), written in a world with that up axis, a horizontal
    rotation, another unit and its origin elsewhere on the floor: the import finds the up axis, puts the
    floor at z = 0, and the origin back at the ring's centre (within a cell)."""
    rig = ring_rig(n_cameras=4, azimuth_step_deg=90.0, azimuth_start_deg=10.0, distance_m=6.0)
    spin = Rotation.from_euler("z", 30, degrees=True).as_matrix()
    A = spin @ frame_rotation(AXES[up])  # calibration axes -> silpose axes, up -> +z
    true = WorldTransform(A, scale, spin @ np.array([-2.5, 3.0, 0.0]))
    calib = to_calibration_frame(rig, true, sizes=True)
    result = import_rig_from(calib, unit=str(scale), step=0.1)
    got = result.rig.transform
    np.testing.assert_array_equal(got.up_in_calibration, AXES[up])
    centre = got.to_silpose(true.to_calibration(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])))
    assert np.abs(centre[0, :2]).max() <= 0.15, centre
    np.testing.assert_allclose(centre[:, 2], [0.0, 1.0], atol=1e-9)
    assert result.rig.workspace.size.min() >= 2.0


@pytest.mark.parametrize("up", list(AXES))
def test_auto_up_on_the_tilted_lab_in_every_orientation(up):
    calib = to_calibration_frame(one_wall_lab_room(), WorldTransform(frame_rotation(AXES[up])), sizes=True)
    axis, agreement = auto_up(calib)
    np.testing.assert_array_equal(axis, AXES[up])
    assert agreement > 0.9  # the lab's cameras look 14-18 deg down


def test_frame_rotation_is_proper_and_keeps_z_up_calibrations_unchanged():
    for name, u in AXES.items():
        A = frame_rotation(u)
        np.testing.assert_allclose(A @ A.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(A) == pytest.approx(1.0)
        np.testing.assert_array_equal(A @ u, [0, 0, 1])
    np.testing.assert_array_equal(frame_rotation(AXES["+z"]), np.eye(3))
    assert parse_unit("mm") == 0.001 and parse_unit("0.0254") == 0.0254


def test_origin_and_floor_offset_and_explicit_workspace():
    calib, board = one_wall_lab()
    # The board lay on a 750 mm table: its frame's origin is 750 mm above the floor, so the floor is at
    # z = +750 of that z-down frame, i.e. -750 along up (--floor-offset -750). Poses in that frame:
    # X_table = X_floor + (0, 0, 750), so t_table = t - R (0, 0, 750).
    lifted = [type(c)(c.name, c.K, c.dist, c.R, c.t - c.R @ np.array([0.0, 0.0, 750.0]), c.size, c.source)
              for c in calib]
    res = import_rig_from(lifted, origin="1500,-2300,0", floor_offset=-750.0, workspace="2.5x2@0,0.2")
    rig = res.rig
    assert rig.workspace.describe() == "2.50 m x 2.00 m centred at (0.00, 0.20) m"
    heights = [c.center[2] for c in rig]
    np.testing.assert_allclose(heights, 2.0, atol=1e-9)  # cameras 2 m above the real floor
    np.testing.assert_allclose(rig.transform.to_calibration(np.zeros(3)), [1500, -2300, 750], atol=1e-9)
