import json
from pathlib import Path

import numpy as np
import pytest

from layout.objectmetrics import ObjectRecord, match_objects, yaw_error

SHARED = Path(__file__).resolve().parents[2].parent / "shared"


def test_unmatched_ground_truth_is_counted():
    gt = [ObjectRecord("chair", (0.0, 1.0), 0.0), ObjectRecord("chair", (3.0, 1.0), 0.0)]
    pred = [ObjectRecord("chair", (0.2, 1.0), 0.1), ObjectRecord("chair", (9.0, 9.0), 0.0)]
    e = match_objects(pred, gt)["chair"]
    assert (e.n_gt, e.n_pred, e.matched) == (2, 2, 1)
    np.testing.assert_allclose(e.position, [0.2])


def test_plants_have_no_orientation_and_tables_fold():
    gt = [ObjectRecord("plant", (1.0, 1.0), 0.0), ObjectRecord("table", (2.0, 0.0), 0.0)]
    pred = [ObjectRecord("plant", (1.0, 1.0), 2.0), ObjectRecord("table", (2.0, 0.0), np.pi)]
    res = match_objects(pred, gt)
    assert res["plant"].orientation.size == 0
    np.testing.assert_allclose(res["table"].orientation, [0.0], atol=1e-12)


def test_yaw_error_is_symmetric_and_bounded():
    rng = np.random.default_rng(0)
    a, b = rng.uniform(-10, 10, 200), rng.uniform(-10, 10, 200)
    e = yaw_error(a, b)
    np.testing.assert_allclose(e, yaw_error(b, a))
    assert e.min() >= 0 and e.max() <= np.pi + 1e-12


def test_bad_gate():
    with pytest.raises(ValueError, match="gate"):
        match_objects([], [], gate=0.0)


def test_agrees_with_the_external_scorer(tmp_path):
    if not (SHARED / "tools" / "score_scene.py").is_file():
        pytest.skip("../shared/tools/score_scene.py not present")
    import importlib.util

    spec = importlib.util.spec_from_file_location("score_scene", SHARED / "tools" / "score_scene.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    rng = np.random.default_rng(1)
    objs = lambda n, cls: [{"class": cls, "center": [float(x), float(y), 0.4], "yaw_deg": float(rng.uniform(0, 360))}
                           for x, y in rng.uniform(-3, 3, (n, 2))]
    gt = {"objects": objs(4, "chair") + objs(2, "bed")}
    scene = {"objects": objs(3, "chair") + objs(2, "bed")}
    theirs = mod.score_objects(scene, gt)
    ours = match_objects([ObjectRecord.from_json(o) for o in scene["objects"]],
                         [ObjectRecord.from_json(o) for o in gt["objects"]])
    for cls in ("chair", "bed"):
        np.testing.assert_allclose(sorted(theirs[cls]["pos"]), sorted(ours[cls].position))
        np.testing.assert_allclose(sorted(theirs[cls]["orient"]), sorted(np.rad2deg(ours[cls].orientation)))
