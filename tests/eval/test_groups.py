"""Per-activity-group pose tables (silpose.eval.groups) against means computed by hand."""

from __future__ import annotations

import numpy as np
import pandas as pd

from silpose.eval.groups import group_tables


def test_group_tables_match_hand_computed_means():
    groups = {0: "walk", 1: "walk", 2: "dance", 3: "sports"}
    rows = []
    for method, offset in (("mppca", 0.0), ("knn", 10.0)):
        for sid, err in zip(range(4), (1.0, 3.0, 5.0, 7.0)):
            rows.append({"experiment": "E4", "method": method, "input_views": "0,1,2,3", "sample_id": sid,
                         "pose_cm": err + offset})
    rows.append({"experiment": "E2", "method": "mppca", "input_views": "0", "sample_id": 2, "pose_cm": 9.0})
    md = group_tables(pd.DataFrame(rows), groups)
    assert "walk 2, dance 1, sports 1" in md
    e4 = md.split("### E4")[1]
    assert "| mppca | 4.00 | 2.00 | 5.00 | 7.00 |" in e4  # columns: all, walk, dance, sports
    assert "| knn | 14.00 | 12.00 | 15.00 | 17.00 |" in e4
    e2 = md.split("### E2")[1].split("###")[0]
    assert "| E2 | 9.00 | – | 9.00 | – |" in e2  # no walk or sports sample in this experiment
    assert np.isclose(np.mean([1.0, 3.0, 5.0, 7.0]), 4.0)
