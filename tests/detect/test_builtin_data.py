"""Builtin detector, training side: tile labels from warped instance masks, target encoding, metrics."""

from __future__ import annotations

import json

import numpy as np
import pytest

from detect.builtin.data import (LabelRules, SynthRoom, TileLabels, TileSampler, encode_targets, load_room,
                                 random_view, render_tile, tile_labels, warp)
from detect.builtin.evaluate import GroundTruth, average_precision, evaluate, load_ground_truth, tune_score_threshold
from detect.detection import Detection
from detect.tiles import box_in_view
from panogeom.coords import lonlat_to_pixel
from panogeom.perspective import PinholeView, equirect_to_perspective

W, H = 1024, 512
CLASSES = ("bed", "chair", "tv", "plant", "sofa", "table", "nightstand", "wardrobe")


def _room(synth, rects):
    """A grey room with lon/lat rectangles painted as objects: rects = [(label, lon0, lon1, lat0, lat1)] (degrees)."""
    rgb = synth.grey_pano(H, seed=3)
    inst = np.zeros((H, W), np.uint16)
    boxes = []
    for k, (label, lon0, lon1, lat0, lat1) in enumerate(rects):
        colour = synth.COLOURS[k % 3]
        m = synth.paint_lonlat(rgb, *np.deg2rad([lon0, lon1, lat0, lat1]), colour)
        inst[m] = k + 1
        boxes.append(_mask_box(m))
    return SynthRoom("room-test", rgb, inst, tuple(r[0] for r in rects), np.array(boxes, np.float64).reshape(-1, 4))


def _mask_box(m):
    from panogeom.boxes import mask_to_pano_box

    return mask_to_pano_box(m)


def _view(lon_deg, pitch_deg=0.0, fov_deg=90.0, size=320):
    # a view at yaw a looks at lon = -a
    return PinholeView(yaw=float(np.deg2rad(-lon_deg)), pitch=float(np.deg2rad(pitch_deg)), roll=0.0,
                       fov=float(np.deg2rad(fov_deg)), width=size, height=size)


def test_warp_matches_panogeom_for_any_yaw(synth):
    pano = synth.grey_pano(H, seed=1)
    synth.paint_lonlat(pano, 0.2, 0.6, -0.3, 0.1, synth.COLOURS[0])
    for yaw in (2 * np.pi * 37 / W, 0.4321):  # a whole number of columns (rolled) and not (direct)
        v = PinholeView(yaw=-yaw, pitch=-0.2, roll=0.0, fov=1.4, width=48, height=48)
        a = warp(pano, v).astype(int)
        b = equirect_to_perspective(pano, v).astype(int)
        assert np.abs(a - b).max() <= 1


def test_tile_box_is_the_tight_box_of_the_projected_object(synth):
    room = _room(synth, [("tv", 10, 40, -20, 5)])
    view = _view(25, pitch_deg=-5, size=320)
    lab = tile_labels(room, view, 160, CLASSES)
    assert lab.classes.tolist() == [CLASSES.index("tv")]
    # the lon/lat rectangle seen in the view (detect.tiles.box_in_view), at the 160 px tile scale
    det = Detection("tv", 1.0, room.boxes[0], W, H)
    expected = box_in_view(det, view, samples=256) / 2.0
    assert np.abs(lab.boxes[0] - expected).max() <= 1.0


def test_cut_tiny_and_foreign_objects_are_ignored(synth):
    room = _room(synth, [("bed", -50, -20, -30, -5), ("chair", 30, 31, -10, -9), ("lamp", 0, 5, -5, 0),
                         ("table", 40, 60, -25, -10)])
    view = _view(0, size=320)  # 90 degrees: lon -45..45; little of the table is inside
    lab = tile_labels(room, view, 160, CLASSES)
    assert lab.classes.tolist() == [CLASSES.index("bed")]
    assert sorted(lab.ignore_classes.tolist()) == sorted([CLASSES.index("chair"), CLASSES.index("table")])
    # a lower min_fraction keeps the cut table; the lamp is not a class of the detector either way
    loose = tile_labels(room, view, 160, CLASSES, LabelRules(min_fraction=0.1))
    assert sorted(loose.classes.tolist()) == sorted([CLASSES.index("bed"), CLASSES.index("table")])


def test_flip_twice_is_identity():
    lab = TileLabels(np.array([[3.0, 4.0, 20.0, 30.0]]), np.array([2]), np.array([[0.0, 1.0, 5.0, 9.0]]),
                     np.array([1]))
    back = lab.flipped(64).flipped(64)
    assert np.allclose(back.boxes, lab.boxes) and np.allclose(back.ignore_boxes, lab.ignore_boxes)
    assert lab.flipped(64).boxes.tolist() == [[44.0, 4.0, 61.0, 30.0]]


def test_encode_then_decode_gives_the_boxes_back():
    torch = pytest.importorskip("torch")
    from detect.builtin.model import decode

    boxes = np.array([[10.3, 20.0, 50.0, 61.5], [80.0, 8.0, 90.5, 30.0], [0.0, 100.0, 128.0, 128.0]])
    lab = TileLabels(boxes, np.array([0, 3, 1]), np.zeros((0, 4)), np.zeros(0, np.int64))
    t = encode_targets(lab, 128, 4)
    logit = torch.from_numpy(np.log(np.clip(t["heat"], 1e-6, 1 - 1e-6) / np.clip(1 - t["heat"], 1e-6, 1)))
    box = torch.from_numpy(t["box"])[None]
    got = decode(logit[None], box[:, :2], box[:, 2:], score_threshold=0.99)[0]
    assert sorted(c for c, _, _ in got) == [0, 1, 3]
    for c, _, b in got:
        k = lab.classes.tolist().index(c)
        assert np.allclose(b, boxes[k], atol=1e-4)


def test_ignored_boxes_switch_off_the_heatmap_loss_there():
    lab = TileLabels(np.array([[0.0, 0.0, 16.0, 16.0]]), np.array([0]), np.array([[32.0, 32.0, 48.0, 48.0]]),
                     np.array([1]))
    t = encode_targets(lab, 64, 2)
    assert t["heat_w"][1, 8:12, 8:12].max() == 0.0 and t["heat_w"][0, 8:12, 8:12].min() == 1.0
    assert t["heat"][0, 2, 2] == 1.0 and t["box_w"].max() == 1.0


def test_sampler_is_reproducible_and_labels_fit_the_tile(synth):
    room = _room(synth, [("bed", -60, -20, -30, -5), ("tv", 100, 120, -5, 10), ("plant", 170, 190, -40, -20)])
    a = TileSampler([room], 64, seed=5)
    b = TileSampler([room], 64, seed=5)
    for _ in range(4):
        (ia, la), (ib, lb) = a.sample(), b.sample()
        assert np.array_equal(ia, ib) and np.array_equal(la.boxes, lb.boxes)
        assert ia.shape == (64, 64, 3)
        if len(la.boxes):
            assert la.boxes.min() >= 0 and la.boxes.max() <= 64
    imgs, targets, labs = a.batch(3)
    assert imgs.shape == (3, 64, 64, 3) and targets["heat"].shape == (3, 8, 16, 16) and len(labs) == 3


def test_random_view_aims_at_objects(synth):
    room = _room(synth, [("tv", 100, 110, -5, 5)])
    rng = np.random.default_rng(0)
    views = [random_view(rng, room, 64, aim=1.0) for _ in range(20)]
    centre = lonlat_to_pixel(np.deg2rad([[105.0, 0.0]]), W, H)[0]
    det = Detection("tv", 1.0, [centre[0] - 1, centre[1] - 1, centre[0] + 1, centre[1] + 1], W, H)
    for v in views:
        b = box_in_view(det, v)
        assert 0 < b[0] < v.width and 0 < b[1] < v.height  # the object's centre is in every view


def test_render_tile_rejects_nothing_and_keeps_size(synth):
    pano = synth.grey_pano(H)
    assert render_tile(pano, _view(0, size=7), 40).shape == (40, 40, 3)


def test_load_room_reads_a_synth_folder(tmp_path, synth):
    import cv2

    room = _room(synth, [("tv", 10, 40, -20, 5)])
    d = tmp_path / "room-0000"
    d.mkdir()
    cv2.imwrite(str(d / "pano.png"), room.rgb[..., ::-1])
    cv2.imwrite(str(d / "instances.png"), room.instances)
    gt = {"image": {"width": W, "height": H}, "objects": [
        {"class": "tv", "bbox_pano": room.boxes[0].tolist(), "visible_px": int((room.instances == 1).sum())}]}
    (d / "gt.json").write_text(json.dumps(gt))
    got = load_room(d, width=512)
    assert got.rgb.shape == (256, 512, 3) and got.instances.dtype == np.uint16
    assert np.allclose(got.boxes, room.boxes / 2) and got.labels == ("tv",)
    truth = load_ground_truth(d, width=2048)
    assert np.allclose(truth.boxes, room.boxes * 2) and truth.difficult.tolist() == [False]


# ----------------------------------------------------------------------------------------------- metrics

def _det(label, score, box):
    return Detection(label, score, box, 2048, 1024)


def test_average_precision_known_values():
    assert average_precision([1.0], [1.0]) == 1.0
    assert average_precision([0.5, 1.0], [1.0, 0.5]) == pytest.approx(0.75)
    assert average_precision([], []) == 0.0


def test_evaluate_perfect_duplicates_difficult_and_seam():
    gt = GroundTruth("r", 2048, 1024, ("chair", "chair", "chair"),
                     [[2000, 500, 60, 600], [300, 500, 360, 600], [900, 500, 905, 504]], [False, False, True])
    perfect = [_det("chair", 0.9, [2001, 500, 60, 600]), _det("chair", 0.8, [300, 501, 360, 600])]
    assert evaluate({"r": perfect}, [gt]).ap("chair") == pytest.approx(1.0)
    # a detection on the difficult object changes nothing; a duplicate is a false positive
    with_diff = perfect + [_det("chair", 0.95, [900, 500, 905, 504])]
    assert evaluate({"r": with_diff}, [gt]).ap("chair") == pytest.approx(1.0)
    dup = [_det("chair", 0.9, [2001, 500, 60, 600]), _det("chair", 0.85, [2000, 500, 60, 601]),
           _det("chair", 0.8, [300, 501, 360, 600])]
    res = evaluate({"r": dup}, [gt])
    assert res.ap("chair") == pytest.approx(0.5 + 0.5 * 2 / 3)
    assert res.classes["chair"].n_gt == 2 and res.classes["chair"].n_difficult == 1
    # the wrong class finds nothing; classes without ground truth have NaN AP
    res = evaluate({"r": [_det("tv", 0.9, [300, 500, 360, 600])]}, [gt], ["chair", "tv"])
    assert res.ap("chair") == 0.0 and np.isnan(res.ap("tv"))


def test_evaluate_checks_its_inputs():
    gt = GroundTruth("r", 2048, 1024, ("tv",), [[0, 0, 10, 10]], [False])
    with pytest.raises(ValueError, match="expected room names of the ground truth, got unknown"):
        evaluate({"other": []}, [gt])
    with pytest.raises(ValueError, match="expected detections in a 2048x1024 panorama, got 1024x512"):
        evaluate({"r": [Detection("tv", 0.5, [0, 0, 10, 10], 1024, 512)]}, [gt])
    with pytest.raises(ValueError, match=r"iou_threshold: expected a number in \(0, 1\]"):
        evaluate({}, [gt], iou_threshold=0.0)


def test_tuned_threshold_drops_the_false_positives_below_the_true_ones():
    gt = GroundTruth("r", 2048, 1024, ("tv", "bed"), [[100, 400, 200, 500], [800, 500, 1000, 700]], [False, False])
    dets = [_det("tv", 0.8, [100, 400, 200, 500]), _det("bed", 0.6, [800, 500, 1000, 700]),
            _det("tv", 0.4, [1500, 400, 1600, 500]), _det("bed", 0.2, [1200, 500, 1300, 700])]
    t = tune_score_threshold({"r": dets}, [gt], ["tv", "bed"])
    assert 0.4 < t <= 0.6
