"""Silhouette images in the encodings users' tools write (silpose.app.inputs.mask_images), through both readers of
mask images: camera folders of a recording (``--videos DIR --masks``) and ``silpose infer INPUT``'s camera folders.

Each file is written from a known mask by OpenCV or Pillow in that encoding; the foreground read back is compared
with the mask written."""

from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from silpose.app.inputs.mask_images import LABEL_LEVELS, mask_grey
from silpose.app.recordings.silhouettes import MaskBinariser
from silpose.app.recordings.sources import CameraReader, CameraSource

H, W = 120, 160


def _person() -> np.ndarray:
    """(H, W) bool: a body (torso + legs + arm) away from the border."""
    m = np.zeros((H, W), bool)
    m[20:70, 60:95] = True
    m[70:110, 62:75] = True
    m[70:110, 82:94] = True
    m[30:38, 30:60] = True
    return m


def _write(path: Path, kind: str, m: np.ndarray) -> None:
    u8 = m.astype(np.uint8)
    if kind == "0/255":
        cv2.imwrite(str(path), u8 * 255)
    elif kind == "0/1":
        cv2.imwrite(str(path), u8)
    elif kind == "1-bit":
        Image.fromarray(m).save(path)
    elif kind == "palette":  # DAVIS format: index 1 is (128, 0, 0)
        p = Image.fromarray(u8, mode="P")
        p.putpalette([0, 0, 0, 128, 0, 0] + [0] * 762)
        p.save(path)
    elif kind == "labels":  # person ids as grey levels: the left and right halves are persons 1 and 2
        lab = u8.copy()
        lab[:, W // 2 + 5:] *= 2
        cv2.imwrite(str(path), lab)
    elif kind == "rgba":  # a background remover's cut-out: the person's colours, soft alpha edges
        alpha = cv2.GaussianBlur(u8 * 255, (3, 3), 0)
        rgba = np.dstack([np.full((H, W), 40, np.uint8), np.full((H, W), 90, np.uint8),
                          np.full((H, W), 20, np.uint8), alpha])
        cv2.imwrite(str(path), rgba)
    elif kind == "jpeg":
        cv2.imwrite(str(path), u8 * 255, [cv2.IMWRITE_JPEG_QUALITY, 40])
    elif kind == "16-bit":
        cv2.imwrite(str(path), u8.astype(np.uint16) * 65535)
    else:
        raise AssertionError(kind)


KINDS = ["0/255", "0/1", "1-bit", "palette", "labels", "rgba", "jpeg", "16-bit"]


def _iou(a, b):
    return (a & b).sum() / (a | b).sum()


@pytest.mark.parametrize("kind", KINDS)
def test_each_encoding_reads_as_the_mask_written(tmp_path, kind):
    m = _person()
    path = tmp_path / ("mask.jpg" if kind == "jpeg" else "mask.png")
    _write(path, kind, m)
    grey = mask_grey(cv2.imread(str(path), cv2.IMREAD_UNCHANGED))
    assert grey.shape == (H, W) and grey.dtype == np.uint8
    assert _iou(grey > 127, m) > (0.97 if kind in ("jpeg", "rgba") else 0.999)


def test_a_grey_mask_with_soft_edges_is_thresholded_at_mid_grey_not_at_zero():
    ramp = np.tile(np.linspace(0, 255, W).astype(np.uint8), (H, 1))  # 160 grey levels: not a label mask
    assert len(np.unique(ramp)) > LABEL_LEVELS
    grey = mask_grey(ramp)
    assert np.array_equal(grey, ramp)  # thresholded later at 127: half the ramp, not all its non-zero pixels


@pytest.mark.parametrize("kind", ["0/1", "palette", "rgba", "0/255"])
def test_a_recordings_camera_folder_of_masks_reads_them_in_every_encoding(tmp_path, kind):
    """``--videos DIR --masks`` with DIR/<camera>/*.png: the frames the pipeline segments (before: 0/1, palette and
    RGBA masks were read as their luminance, all below mid-grey, and every frame was empty)."""
    m = _person()
    folder = tmp_path / "cam1"
    folder.mkdir()
    paths = []
    for i in range(2):
        paths.append(folder / f"{i:05d}.png")
        _write(paths[-1], kind, m)
    src = CameraSource("cam1", folder, 0.0, len(paths), W, H, images=tuple(paths))
    reader = CameraReader(src, grey=True)
    for _ in paths:
        mask = MaskBinariser()("cam1", reader.read()).astype(bool)
        assert _iou(mask, m) > 0.97  # the 3 x 3 median rounds the body's corners


def test_infer_inputs_camera_folders_read_palette_masks(tiny_model, tmp_path):
    """``silpose infer INPUT`` on camera folders of DAVIS-palette masks: every view is present (before: a palette's
    (128, 0, 0) read as grey 38, below the threshold, and every view was empty)."""
    from silpose.app.inputs.silhouettes import read_png_input

    rig = tiny_model.rig_
    for cam in rig:
        (tmp_path / cam.name).mkdir()
        m = np.zeros((cam.height, cam.width), bool)
        m[cam.height // 4: 3 * cam.height // 4, cam.width // 2 - 20: cam.width // 2 + 20] = True
        _write(tmp_path / cam.name / "000.png", "palette", m)
    names, contours, present, _ = read_png_input(tiny_model, tmp_path)
    assert list(names) == ["000"] and present.all()
    assert np.isfinite(contours).all()
