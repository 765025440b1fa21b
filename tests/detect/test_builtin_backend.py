"""Builtin detector, running side: committed weights, the Detector protocol, spec, a stored room, training CLI."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from detect.backends import ModelFileError, get_detector  # noqa: E402
from detect.builtin import DEFAULT_WEIGHTS, BuiltinDetector, NetConfig, build_network, builtin_views, from_spec  # noqa: E402
from detect.builtin.backend import load_record, save_weights  # noqa: E402
from detect.builtin.evaluate import evaluate, load_ground_truth  # noqa: E402
from detect.detection import BatchDetector, ImageDetection  # noqa: E402
from detect.tiles import detect_panorama  # noqa: E402

ROOM = Path(__file__).resolve().parent / "data" / "builtin_room"


@pytest.fixture(scope="module")
def det():
    return BuiltinDetector()


def test_committed_weights_and_record(det):
    assert DEFAULT_WEIGHTS.stat().st_size < 5 * 2 ** 20
    rec = load_record()
    assert rec["weights"] == "builtin.pt" and rec["classes"] == list(det.classes)
    assert rec["network"]["parameters"] == sum(p.numel() for p in det._net.parameters())
    assert rec["data"]["train_seed"] >= 3000 and rec["data"]["val_seed"] >= 3000  # never the seed-0 evaluation set
    assert rec["training"]["tiles_seen"] == rec["training"]["iterations"] * rec["training"]["batch"]
    assert 0.0 < rec["score_threshold"] < 1.0 and det.score_threshold == rec["score_threshold"]
    assert isinstance(det, BatchDetector)


def test_batch_equals_single_and_boxes_stay_in_the_image(det):
    rng = np.random.default_rng(0)
    a = rng.integers(0, 255, (160, 160, 3)).astype(np.uint8)
    b = np.ascontiguousarray(np.repeat(np.repeat(a[:100, :120], 2, 0), 2, 1))  # 200 x 240, another size
    low = BuiltinDetector(score_threshold=0.01)
    batch = low.detect_batch([a, b])
    single = [low.detect(a), low.detect(b)]
    for got, ref, img in zip(batch, single, (a, b)):
        assert [d.label for d in got] == [d.label for d in ref]
        assert np.allclose([d.score for d in got], [d.score for d in ref], atol=1e-4)
        for d in got:
            assert isinstance(d, ImageDetection)
            assert 0 <= d.box[0] < d.box[2] <= img.shape[1] and 0 <= d.box[1] < d.box[3] <= img.shape[0]
    assert low.detect_batch([]) == []


def test_plain_grey_tile_has_no_objects(det):
    assert det.detect(np.full((160, 160, 3), 140, np.uint8)) == []


def test_inputs_and_files_are_checked(tmp_path, det):
    with pytest.raises(ValueError, match=r"images\[0\]: expected an \(h, w, 3\) uint8 RGB image, got shape"):
        det.detect(np.zeros((160, 160, 3), np.float32))
    with pytest.raises(ModelFileError, match="builtin detector weights not found"):
        BuiltinDetector(tmp_path / "none.pt")
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a torch file")
    with pytest.raises(ModelFileError, match="junk.pt: not builtin detector weights"):
        BuiltinDetector(junk)
    with pytest.raises(ValueError, match=r"score_threshold: expected a number in \[0, 1\], got 2"):
        BuiltinDetector(score_threshold=2)


def test_spec_options():
    d = from_spec(None, {"score": "0.6", "max_detections": "3"})
    assert d.score_threshold == 0.6 and d.max_detections == 3
    with pytest.raises(ValueError, match=r"builtin detector: unknown option\(s\) \['iou'\]"):
        from_spec(None, {"iou": "0.5"})
    assert isinstance(get_detector("builtin?score=0.5"), BuiltinDetector)
    assert get_detector(f"builtin:{DEFAULT_WEIGHTS}").weights == DEFAULT_WEIGHTS


def test_save_and_load_round_trip(tmp_path):
    torch.manual_seed(0)
    cfg = NetConfig(("tv", "bed"), (4, 4, 8, 8, 8), 8, 64)
    net = build_network(cfg).eval()
    path = save_weights(net, cfg, tmp_path / "w.pt")
    d = BuiltinDetector(path, score_threshold=0.0, max_detections=5)
    assert d.classes == ("tv", "bed") and d.input_size == 64 and d.record == {}
    x = torch.rand(2, 3, 64, 64)
    with torch.no_grad():
        for a, b in zip(net(x), d._net(x)):
            assert torch.allclose(a, b)
    assert len(d.detect(np.zeros((64, 64, 3), np.uint8))) == 5


def test_edges_near_the_tile_border_are_snapped_onto_it(tmp_path):
    torch.manual_seed(1)
    cfg = NetConfig(("tv", "bed"), (4, 4, 8, 8, 8), 8, 64)
    path = save_weights(build_network(cfg).eval(), cfg, tmp_path / "w.pt")
    img = np.random.default_rng(0).integers(0, 255, (100, 120, 3)).astype(np.uint8)
    for snap in (0.0, 0.1):
        dets = BuiltinDetector(path, score_threshold=0.0, max_detections=40, border_snap=snap).detect(img)
        edges = np.array([[d.box[0], d.box[1], 120 - d.box[2], 100 - d.box[3]] for d in dets])
        near = (edges > 0) & (edges < snap * np.array([120, 100, 120, 100]))
        assert len(dets) and not near.any() and edges.min() >= 0
    with pytest.raises(ValueError, match=r"border_snap: expected a fraction in \[0, 0.5\), got 0.7"):
        BuiltinDetector(path, border_snap=0.7)


def test_flip_averaging_is_mirror_symmetric():
    """With flip, a mirrored tile gives the mirrored boxes (the offsets of the mirror are turned round)."""
    import cv2

    from detect.tiles import render_tiles

    pano = cv2.cvtColor(cv2.imread(str(ROOM / "pano.jpg")), cv2.COLOR_BGR2RGB)
    _, tiles = render_tiles(pano, builtin_views(320)[:12:3])
    det = BuiltinDetector(flip=True, score_threshold=0.2, input_size=160)
    found = 0
    for tile in tiles:
        a = det.detect(tile)
        found += len(a)
        b = det.detect(np.ascontiguousarray(tile[:, ::-1]))
        mirrored = sorted((d.label, round(d.score, 3), tuple(np.round([320 - d.box[2], d.box[1], 320 - d.box[0],
                                                                       d.box[3]], 2))) for d in b)
        assert sorted((d.label, round(d.score, 3), tuple(np.round(d.box, 2))) for d in a) == mirrored
    assert found >= 2


def test_views():
    v = builtin_views(160)
    assert len(v) == 24 and all((x.width, x.height) == (160, 160) for x in v)
    assert np.rad2deg(max(x.fov for x in v)) == pytest.approx(130.0)


def test_stored_room_is_found(det):
    """A held-back synthetic room (seed 4100, never trained on): its clearly visible objects are found."""
    import cv2

    pano = cv2.cvtColor(cv2.imread(str(ROOM / "pano.jpg")), cv2.COLOR_BGR2RGB)
    truth = load_ground_truth(ROOM)
    dets = detect_panorama(pano, det, views=det.views())
    res = evaluate({truth.name: dets}, [truth])
    found = [c for c, r in res.classes.items() if r.n_gt and r.tp_at_best_f1 == r.n_gt]
    assert res.mean_ap >= 0.6, res
    assert len(found) >= 0.5 * sum(1 for r in res.classes.values() if r.n_gt), res


def test_training_cli_writes_weights_and_record(tmp_path, synth):
    from detect.builtin.train import main

    data = synth.fake_rooms(tmp_path / "train", 3000, 2)
    val = synth.fake_rooms(tmp_path / "val", 3500)
    out = tmp_path / "w"
    assert main(["--data", str(data), "--val", str(val), "--out", str(out), "--iterations", "2",
                 "--batch", "2", "--size", "64"]) == 0
    rec = json.loads((out / "builtin.json").read_text())
    assert rec["training"]["iterations"] == 2 and rec["data"]["train_rooms"] == 2
    assert rec["data"]["train_seed"] == 3000 and set(rec["validation"]["ap"]) == set(rec["classes"])
    assert BuiltinDetector(out / "builtin.pt").input_size == 64
    seed0 = synth.fake_rooms(tmp_path / "seed0", 0)
    assert main(["--data", str(seed0), "--val", str(val), "--out", str(out), "--iterations", "1"]) == 2


def test_training_continues_from_weights_on_another_tile_size(tmp_path, synth):
    from detect.builtin.train import main

    data = synth.fake_rooms(tmp_path / "train", 3000, 2)
    val = synth.fake_rooms(tmp_path / "val", 3500)
    first, second = tmp_path / "w1", tmp_path / "w2"
    assert main(["--data", str(data), "--val", str(val), "--out", str(first), "--iterations", "1",
                 "--batch", "2", "--size", "64"]) == 0
    assert main(["--data", str(data), "--val", str(val), "--out", str(second), "--iterations", "1",
                 "--batch", "2", "--size", "96", "--init", str(first / "builtin.pt")]) == 0
    rec = json.loads((second / "builtin.json").read_text())
    assert rec["network"]["input_size"] == 96
    assert [s["iterations"] for s in rec["training"]["earlier"]] == [1]
    assert rec["training"]["init"] == str(first / "builtin.pt")
