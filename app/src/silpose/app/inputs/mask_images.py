"""Silhouette images as users' tools write them, read as one grey image whose foreground is bright.

Every camera input that reads masks from image files (``silpose infer INPUT`` on camera folders of silhouettes,
``silpose infer --videos DIR --masks`` on camera folders of frames) passes each image through :func:`mask_grey` and
then keeps the grey levels above mid-grey (127). The encodings met in practice, and what each becomes:

==========================================  =========================================================================
image                                       read as
==========================================  =========================================================================
grey 0/255 (OpenCV, MATLAB, 1-bit PNG)      itself
grey 0/1 (a NumPy boolean saved as PNG)     0/255: an image of at most :data:`LABEL_LEVELS` grey levels that never
                                            reaches white (255) is a label mask, every non-zero level foreground
palette PNG (DAVIS format: SAM 2, XMem,      the same rule on the brightest channel: object 1 is (128, 0, 0), object
Cutie; one colour per object)               2 (0, 128, 0), ... -- every object is foreground
label map (person ids 1, 2, ... as grey)    the same rule: every person is foreground
RGBA cut-out (rembg and other background    the alpha channel, when it is not opaque everywhere
removers: the person's colours + alpha)
JPEG, soft edges (many grey levels, or a    the brightest channel, thresholded at mid-grey as before
mask that reaches white)
16-bit                                      the top 8 bits (or the values themselves when all are below 256)
==========================================  =========================================================================

Background is black (0) in every one of them; an inverted mask (a black person on white) is not recognised.
"""

from __future__ import annotations

import numpy as np

__all__ = ["LABEL_LEVELS", "mask_grey"]

#: an image with at most this many distinct grey levels (0 included) that never reaches white is a label mask: 0/1, a
#: palette or person ids; more levels, or white, make a grey mask whose soft or smeared edges are thresholded at
#: mid-grey (a 0/255 mask reads the same either way)
LABEL_LEVELS = 16


def mask_grey(img: np.ndarray) -> np.ndarray:
    """(H, W) uint8 grey image, foreground bright, of a silhouette image as read by ``cv2.imread(path,
    cv2.IMREAD_UNCHANGED)``: (H, W), (H, W, 3) BGR or (H, W, 4) BGRA, uint8 or uint16 (module doc)."""
    a = np.asarray(img)
    if a.ndim == 3 and a.shape[2] == 4:
        alpha = a[..., 3]
        a = alpha if alpha.min(initial=255) < alpha.max(initial=0) else a[..., :3]
    if a.ndim == 3:
        a = a.max(axis=2)  # the brightest channel: a palette's pure colours keep their level
    if a.dtype == np.uint16:
        a = (a >> 8) if a.max(initial=0) > 255 else a
    a = np.ascontiguousarray(a, dtype=np.uint8)
    counts = np.bincount(a.ravel(), minlength=256)
    if counts[255] == 0 and np.count_nonzero(counts) <= LABEL_LEVELS:
        return np.where(a > 0, np.uint8(255), np.uint8(0))
    return a
