"""silpose.app.contours: a view's contour and its status (empty, too small, ok) on hand-made masks."""

from __future__ import annotations

import numpy as np

from silpose.app.contours import view_contour
from silpose.app.view_status import VIEW_EMPTY as STATUS_EMPTY, VIEW_OK as STATUS_OK, VIEW_TOO_SMALL as STATUS_SMALL
from silpose.shared.contours import extract_contour


def test_view_contour_statuses():
    mask = np.zeros((40, 30), bool)
    assert view_contour(mask, 16, min_area=5) == (None, STATUS_EMPTY, 0)
    mask[10:13, 10:13] = True  # a 3 x 3 blob
    area = extract_contour(mask, 16).area
    assert view_contour(mask, 16, min_area=int(area) + 1)[1:] == (STATUS_SMALL, area)
    points, status, got = view_contour(mask, 16)  # no minimum: any blob is used
    assert status == STATUS_OK and got == area and points.shape == (16, 2)
    mask[5:35, 5:25] = True
    points, status, _ = view_contour(mask, 16, min_area=50)
    assert status == STATUS_OK
    np.testing.assert_array_equal(points, extract_contour(mask, 16).points)
