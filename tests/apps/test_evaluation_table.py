"""The Table-2 summary of `pano2cad eval` (apps.evaluation): the paper's mean +- std, and the robust rows beside it."""

import json
import math

from apps.evaluation import FLIP_DEG, TABLE_CLASSES, RoomScore, jsonable, markdown_table2, summarize


def _room(name, chair_orient, chair_pos):
    objs = {"chair": {"n_gt": len(chair_orient) + 1, "n_pred": len(chair_orient), "matched": len(chair_orient),
                      "pos": chair_pos, "orient": chair_orient},
            "bed": {"n_gt": 1, "n_pred": 0, "matched": 0, "pos": [], "orient": []}}
    layout = {"iou_2d": 0.9, "iou_3d": 0.85, "corners_ok": True, "wall_height_err": 0.05}
    return RoomScore(name, True, None, layout, objs, objs)


def test_medians_and_flips_are_reported_beside_the_mean_and_every_row_has_one_cell_per_column():
    # five chairs: four within a degree, one turned round; the mean is the flip's, the median is not
    scores = [_room("room-0000", [0.2, 0.4, 179.0], [0.05, 0.10, 0.30]), _room("room-0001", [0.6, 1.0], [0.02, 0.04])]
    summary = summarize(scores)
    chair = summary["with_context"]
    assert math.isclose(chair["orient_deg"]["chair"][0], (0.2 + 0.4 + 179.0 + 0.6 + 1.0) / 5)
    assert math.isclose(chair["orient_median_deg"]["chair"], 0.6)
    assert math.isclose(chair["orient_over_deg"]["chair"], 1 / 5) and FLIP_DEG == 45.0
    assert math.isclose(chair["pos_median_cm"]["chair"], 5.0)
    assert math.isnan(chair["orient_median_deg"]["bed"]) and math.isnan(chair["orient_over_deg"]["bed"])
    table = markdown_table2(summary)
    lines = [ln for ln in table.splitlines() if ln.startswith("|")]
    assert all(ln.count("|") == 2 * len(TABLE_CLASSES) + 2 for ln in lines)  # the header's columns, every row
    header = [c.strip() for c in lines[0].split("|")[2:-1]]
    row = next(ln for ln in lines if ln.startswith("| matched / ground truth, with context"))
    cells = dict(zip(header, (c.strip() for c in row.split("|")[2:-1])))
    assert cells["chair (ours)"] == "5/7" and cells["chair (paper)"] == "" and cells["bed (ours)"] == "0/2"
    row = next(ln for ln in lines if ln.startswith("| orientation error (deg), median; share over 45 deg, with"))
    cells = dict(zip(header, (c.strip() for c in row.split("|")[2:-1])))
    assert cells["chair (ours)"] == "0.6; 20.0%" and cells["bed (ours)"] == "n/a; n/a" and cells["plant (ours)"] == "n/a"
    # a summary read back from eval.json (non-finite values written as null) still renders
    back = json.loads(json.dumps(jsonable(summary)))
    assert markdown_table2(back).splitlines()[2:] == table.splitlines()[2:]
