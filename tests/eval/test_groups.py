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


def test_group_headline_matches_hand_computed_means():
    from silpose.eval.groups import group_headline

    groups = {0: "walk", 1: "walk", 2: "dance"}
    rows = []
    for sid, err in zip(range(3), (2.0, 4.0, 9.0)):
        rows.append({"experiment": "E2", "method": "mppca", "n_input_views": 4, "noise": "standard", "sample_id": sid,
                     "pose_cm": err})
        rows.append({"experiment": "E2", "method": "mppca", "n_input_views": 1, "noise": "standard", "sample_id": sid,
                     "pose_cm": 3 * err})
        rows.append({"experiment": "E3", "method": "mppca robust", "n_input_views": 4, "noise": "standard",
                     "sample_id": sid, "pose_cm": err - 1})
        rows.append({"experiment": "E3", "method": "mppca robust", "n_input_views": 4, "noise": "clean",
                     "sample_id": sid, "pose_cm": 100.0})  # another noise: must not count
        rows.append({"experiment": "E4", "method": "knn", "n_input_views": 4, "noise": "standard", "sample_id": sid,
                     "pose_cm": err + 10})
    h = group_headline(pd.DataFrame(rows), groups)
    assert list(h) == ["walk", "dance"]
    assert h["walk"]["n_test"] == 2 and h["dance"]["n_test"] == 1
    assert h["walk"]["pose_cm_by_n_views"] == {4: 3.0, 1: 9.0}
    assert h["dance"]["pose_cm_by_n_views"] == {4: 9.0, 1: 27.0}
    assert h["walk"]["robust_cm_all_views"] == 2.0
    assert h["walk"]["baselines_cm_all_views"] == {"knn": 13.0}
