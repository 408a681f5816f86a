"""Fixtures of the rig-import tests: a known rig with distortion, its calibration in a lab-like frame
(millimetres, z into the floor, the origin at a floor corner), and writers of OpenCV files in the
spellings people use."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from silpose.app.rig.calibration import CalibratedCamera, rotation_to_rvec
from silpose.app.rig.examples import board_frame, to_calibration_frame
from silpose.shared.camera import Camera, Rig, default_rig

DIST = np.array([-0.21, 0.08, 0.0013, -0.0009, -0.012])

#: Per-camera OpenCV spellings: field -> key (None: not written). Cases and underscores vary on purpose.
SPELLINGS = {
    "opencv_sample": {"K": "camera_matrix", "dist": "distortion_coefficients", "rvec": "rvec", "t": "tvec",
                      "width": "image_width", "height": "image_height"},
    "calibrate_camera": {"K": "cameraMatrix", "dist": "distCoeffs", "rvec": "rotation_vectors",
                         "t": "translation_vectors", "size": "imageSize"},
    "capitalised": {"K": "CameraMatrix", "dist": "DistortionCoeffs", "R": "Rotation", "rvec": "RVector",
                    "t": "TVector", "width": "Image_Width", "height": "Image_Height"},
    "short": {"K": "K", "dist": "D", "R": "R", "t": "T", "size": "image_size"},
    "intrinsics": {"K": "Intrinsics", "dist": "dist", "R": "rotation_matrix", "t": "Translation", "size": "Size"},
    # course scripts (per-camera config.xml): a "Camera" prefix and "Vecs" / "Values" endings
    "course_vecs": {"K": "CameraIntrinsicMatrix", "dist": "DistortionCoeffs", "rvec": "CameraRotationVecs",
                    "t": "CameraTranslationVecs", "size": "ImageSize"},
    "course_values": {"K": "CameraMatrix", "dist": "DistortionCoeffs", "rvec": "RotationValues",
                      "t": "TranslationValues", "width": "Width", "height": "Height"},
}


def write_spelled(path, cam: CalibratedCamera, spelling: dict, size=True) -> None:
    """Write ``cam`` with ``cv2.FileStorage`` using the keys of ``spelling``."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write(spelling["K"], np.asarray(cam.K, np.float64))
    fs.write(spelling["dist"], np.asarray(cam.dist, np.float64).reshape(1, -1))
    if "rvec" in spelling:
        fs.write(spelling["rvec"], rotation_to_rvec(cam.R).reshape(3, 1))
    if "R" in spelling:
        fs.write(spelling["R"], np.asarray(cam.R, np.float64))
    fs.write(spelling["t"], np.asarray(cam.t, np.float64).reshape(3, 1))
    if size and cam.size is not None:
        if "size" in spelling:
            fs.write(spelling["size"], np.array([[cam.size[0], cam.size[1]]], np.float64))
        else:
            fs.write(spelling["width"], int(cam.size[0]))
            fs.write(spelling["height"], int(cam.size[1]))
    fs.release()


def distorted_default_rig() -> Rig:
    """The default rig with a different non-zero distortion on every camera."""
    return Rig(tuple(Camera(c.name, c.K, c.R, c.t, c.width, c.height, dist=DIST * (1 + 0.1 * i))
                     for i, c in enumerate(default_rig())))


@pytest.fixture(scope="session")
def lab_frame():
    """Calibration -> silpose: mm, z into the floor, the board corner at silpose (-3, 4) on the floor."""
    return board_frame(corner=(-3.0, 4.0))


@pytest.fixture(scope="session")
def known_rig():
    return distorted_default_rig()


@pytest.fixture(scope="session")
def known_calibration(known_rig, lab_frame):
    """The known rig's cameras in the lab frame (millimetres, z down), sizes included."""
    return to_calibration_frame(known_rig, lab_frame, sizes=True)


def reference_pixels(cam: CalibratedCamera, points_calib: np.ndarray) -> np.ndarray:
    """``cv2.projectPoints`` of calibration-frame points with the original calibration (camera coordinates
    first, so no Rodrigues round trip of the reference rotation)."""
    xc = points_calib @ np.asarray(cam.R).T + cam.t
    uv, _ = cv2.projectPoints(np.ascontiguousarray(xc), np.zeros(3), np.zeros(3), cam.K, cam.dist)
    return uv.reshape(-1, 2)


@pytest.fixture(scope="session")
def check_same_projections(lab_frame):
    """``check(rig, calibration)``: same names, and every camera projects calibration-frame points (through
    the rig's stored transform) within 1e-9 px of cv2.projectPoints on the original calibration."""

    def check(rig: Rig, calibration: list[CalibratedCamera]):
        assert rig.names == tuple(c.name for c in calibration)
        X = np.random.default_rng(0).uniform([-1.5, -1.5, 0.0], [1.5, 1.5, 2.0], size=(200, 3))
        P = lab_frame.to_calibration(X)  # points in the calibration frame, mm
        worst = 0.0
        for cam, ref in zip(rig, calibration):
            got = cam.project(rig.transform.to_silpose(P))
            worst = max(worst, float(np.abs(got - reference_pixels(ref, P)).max()))
        assert worst <= 1e-9, worst
        return worst

    return check


@pytest.fixture(scope="session")
def spelled_writer():
    """``write(path, camera, spelling_name)``: an OpenCV file in one of :data:`SPELLINGS`."""
    return lambda path, cam, name, size=True: write_spelled(path, cam, SPELLINGS[name], size)
