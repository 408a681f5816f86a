"""Mirror symmetries of camera rigs (silpose.shared.rig_symmetry)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from silpose.shared.camera import Camera, Rig, default_rig, ring_rig
from silpose.shared.rig_symmetry import RigMirror, rig_mirrors


def _max_reprojection_gap(rig: Rig, mirror: RigMirror, points: np.ndarray) -> float:
    """max over cameras a of |project_a(S X) - flip(project_{view_map[a]}(X))| in px."""
    gaps = []
    for a, cam in enumerate(rig):
        b = rig[mirror.view_map[a]]
        flipped = b.project(points)
        flipped[:, 0] = (b.width - 1) - flipped[:, 0]
        gaps.append(np.abs(cam.project(mirror.reflect(points)) - flipped).max())
    return float(max(gaps))


def _brute_force_planes_through_origin(rig: Rig, step_deg: float = 0.25) -> list[float]:
    """Normal angles (degrees in [0, 180)) of the vertical planes through the z axis that map the rig onto
    itself, by trying every angle on a grid and every camera pairing (no candidate construction)."""
    rng = np.random.default_rng(0)
    points = np.c_[rng.uniform(-1.5, 1.5, (40, 2)), rng.uniform(0, 2, 40)]
    found = []
    for angle in np.arange(0.0, 180.0, step_deg):
        n = np.array([np.cos(np.deg2rad(angle)), np.sin(np.deg2rad(angle)), 0.0])
        reflected = points - 2 * (points @ n)[:, None] * n
        ok = True
        for cam in rig:
            seen = cam.project(reflected)
            gaps = []
            for other in rig:
                f = other.project(points)
                f[:, 0] = (other.width - 1) - f[:, 0]
                gaps.append(np.abs(seen - f).max())
            ok &= min(gaps) < 1e-6
        if ok:
            found.append(float(angle))
    return found


def test_default_rig_has_the_plane_between_cameras_0_and_3():
    rig = default_rig()
    mirrors = rig_mirrors(rig)
    assert len(mirrors) == 1
    (m,) = mirrors
    assert m.view_map == (3, 2, 1, 0)
    # the plane is at azimuth 67.5 degrees (between the cameras at 0 and 135): its normal at -22.5
    assert np.degrees(np.arctan2(m.normal[1], m.normal[0])) % 180 == pytest.approx(157.5, abs=1e-9)
    # and it holds far from the test grid too
    rng = np.random.default_rng(1)
    assert _max_reprojection_gap(rig, m, rng.uniform(-3, 3, (200, 3))) < 1e-9


def test_agrees_with_a_brute_force_search_over_angles():
    for rig in (default_rig(), ring_rig(n_cameras=6, azimuth_step_deg=60.0), ring_rig(n_cameras=3, azimuth_step_deg=50.0)):
        brute = _brute_force_planes_through_origin(rig)
        ours = sorted(round(float(np.degrees(np.arctan2(m.normal[1], m.normal[0]))), 6) % 180 for m in rig_mirrors(rig))
        # the ring rigs look at (0, 0, 0.9): every symmetry plane contains the z axis
        assert all(abs(m.offset) < 1e-9 for m in rig_mirrors(rig))
        np.testing.assert_allclose(ours, brute, atol=1e-6)


def test_a_full_ring_of_k_cameras_has_k_mirrors():
    rig = ring_rig(n_cameras=8, azimuth_step_deg=45.0)
    mirrors = rig_mirrors(rig)
    assert len(mirrors) == 8
    fixed = [sum(a == b for a, b in enumerate(m.view_map)) for m in mirrors]
    assert sorted(fixed) == [0, 0, 0, 0, 2, 2, 2, 2]  # 4 planes through two cameras, 4 between cameras
    for m in mirrors:
        assert _max_reprojection_gap(rig, m, np.random.default_rng(2).uniform(-2, 2, (50, 3))) < 1e-9


def test_an_off_centre_symmetric_rig_is_found():
    base = default_rig()
    shift = np.array([4.0, -2.5, 0.0])  # the whole rig and its workspace 4.7 m off the origin
    cams = [dataclasses.replace(c, t=c.t - c.R @ shift) for c in base]
    rig = Rig(tuple(cams), workspace=dataclasses.replace(base.workspace, center=shift[:2]))
    (m,) = rig_mirrors(rig)
    assert m.view_map == (3, 2, 1, 0) and abs(m.offset) > 1.0


def _moved(rig: Rig, index: int, **changes) -> Rig:
    cams = list(rig.cameras)
    cams[index] = dataclasses.replace(cams[index], **changes)
    return Rig(tuple(cams), workspace=rig.workspace)


def test_real_looking_rigs_have_none():
    rig = default_rig()
    cam = rig[2]
    assert rig_mirrors(_moved(rig, 2, t=cam.t + np.array([0.005, 0.0, 0.0]))) == []  # 5 mm
    small_turn = np.array([[1, 0, 0], [0, np.cos(0.002), -np.sin(0.002)], [0, np.sin(0.002), np.cos(0.002)]])
    assert rig_mirrors(_moved(rig, 1, R=small_turn @ cam.R)) == []
    K = cam.K.copy()
    K[0, 2] += 0.5  # principal point off the image centre: the flipped image is not camera 1's
    assert rig_mirrors(_moved(rig, 2, K=K)) == []
    assert rig_mirrors(_moved(rig, 3, width=322, K=np.array([[470, 0, 160.5], [0, 470, 119.5], [0, 0, 1.0]]))) == []
    assert rig_mirrors(_moved(rig, 0, dist=np.array([0.01, 0.0, 0.001, 0.0, 0.0]))) == []  # decentring distortion


def test_to_dict_round_trip_and_malformed_entries():
    (m,) = rig_mirrors(default_rig())
    assert RigMirror.from_dict(m.to_dict()) == m
    with pytest.raises(ValueError, match="normal"):
        RigMirror.from_dict({**m.to_dict(), "normal": [0.0, 0.0, 1.0]})
    with pytest.raises(ValueError, match="view_map"):
        RigMirror.from_dict({**m.to_dict(), "view_map": [0, 0, 1, 2]})
    with pytest.raises(ValueError, match="needs normal"):
        RigMirror.from_dict({"normal": [1, 0, 0]})


def test_camera_helper_is_the_pinhole_camera():
    assert isinstance(default_rig()[0], Camera)
