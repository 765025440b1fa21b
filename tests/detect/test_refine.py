"""Box-edge refiner: the window it reads, the edge moves, border edges, the committed weights on a held-back room,
and the training command."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from detect.builtin.refine import (DEFAULT_REFINE_WEIGHTS, BoxRefiner, RefineConfig, apply_moves,  # noqa: E402
                                   box_window, build_refiner, decode_moves, inout_targets, save_refiner,
                                   window_box)
from detect.detection import Detection, TileBox  # noqa: E402
from panogeom.perspective import PinholeView, equirect_to_perspective  # noqa: E402

ROOM = Path(__file__).resolve().parent / "data" / "builtin_room"


def _pano(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 255, (32, 64, 3)).astype(np.uint8)
    import cv2

    return cv2.resize(small, (512, 256), interpolation=cv2.INTER_CUBIC)


def test_box_window_is_the_tile_plane_around_the_box():
    pano = _pano()
    view = PinholeView(np.deg2rad(40), np.deg2rad(-10), 0.0, np.pi / 2, 128, 128)
    tile = equirect_to_perspective(pano, view)
    box = np.array([40.0, 32.0, 80.0, 96.0])
    assert window_box(box, 0.25).tolist() == [30.0, 16.0, 90.0, 112.0]
    win = box_window(pano, TileBox(view, box), size=32, margin=0.25, supersample=1)
    # window pixel (i, j) samples tile point (30 + (j + 0.5) * 60 / 32, 16 + (i + 0.5) * 96 / 32)
    import cv2

    u = 30 + (np.arange(32) + 0.5) * 60 / 32 - 0.5
    v = 16 + (np.arange(32) + 0.5) * 96 / 32 - 0.5
    mx, my = (a.astype(np.float32) for a in np.meshgrid(u, v))
    ref = cv2.remap(tile, mx, my, interpolation=cv2.INTER_LINEAR).astype(np.float32)
    # the tile is resampled once more than the window: a little extra blur
    assert np.abs(win.astype(np.float32) - ref).mean() < 6.0
    assert np.abs(win.astype(np.float32) - np.roll(win, 6, axis=1).astype(np.float32)).mean() > 12.0


def test_apply_moves_inverts_the_training_target():
    true = np.array([12.0, 30.0, 55.0, 90.0])
    noisy = np.array([10.0, 33.0, 60.0, 85.0])
    w, h = noisy[2] - noisy[0], noisy[3] - noisy[1]
    target = (true - noisy) / np.array([w, h, w, h])
    assert np.allclose(apply_moves(noisy, target), true)


def _refiner(tmp_path: Path, moves: list[float]) -> BoxRefiner:
    """A refiner (untrained weights) whose network is replaced by fixed edge moves."""
    config = RefineConfig(("bed", "chair"), size=32)
    r = BoxRefiner(save_refiner(build_refiner(config), config, tmp_path / "r.pt"), passes=1)
    r.moves = lambda windows, labels: np.tile(moves, (len(labels), 1))
    return r


def test_inout_targets_and_decoding_round_trip():
    rng = np.random.default_rng(0)
    moves = rng.uniform(-0.2, 0.2, (50, 4))
    t = inout_targets(moves, 64, 0.25)
    assert t.shape == (50, 2, 64) and t.min() >= 0.0 and t.max() <= 1.0
    assert np.allclose(decode_moves(t, 0.25), moves, atol=1e-6)
    # a stray outside column inside the box moves the edge of its half by its mass only
    t[:, 0, 20] = 0.0
    assert np.allclose(decode_moves(t, 0.25)[:, 0], moves[:, 0] + 1.5 / 64, atol=1e-6)


def test_untrained_network_has_the_window_shape():
    config = RefineConfig(("bed", "chair"), size=32)
    net = build_refiner(config)
    out = net(torch.rand(3, 3, 32, 32), torch.eye(2)[[0, 1, 1]])
    assert tuple(out.shape) == (3, 2, 32)


def test_refine_moves_every_tile_box_but_not_edges_at_the_tile_border(tmp_path):
    pano = _pano(1)
    r = _refiner(tmp_path, [0.1, -0.1, 0.1, 0.5])   # the last move is beyond max_move (0.3): clipped
    v1 = PinholeView(0.0, 0.0, 0.0, np.pi / 2, 100, 100)
    v2 = PinholeView(np.deg2rad(20), 0.0, 0.0, np.pi / 2, 100, 100)
    t1, t2 = TileBox(v1, [20.0, 40.0, 60.0, 99.5]), TileBox(v2, [40.0, 40.0, 80.0, 80.0])
    det = Detection("chair", 0.9, [240.0, 100.0, 300.0, 180.0], 512, 256, tile=t1, views=(t1, t2))
    out = r.refine(pano, det)
    assert out.tile is out.views[0] and len(out.views) == 2 and np.array_equal(out.box, det.box)
    # t1's bottom edge is at the tile border: kept; the others move by the fractions of the box's side
    assert np.allclose(out.views[0].box, [24.0, 34.05, 64.0, 99.5])
    assert np.allclose(out.views[1].box, [44.0, 36.0, 84.0, 92.0])
    # one view alone: no views; boxes from a file (no tile): returned as they are
    single = r.refine(pano, replace(det, views=()))
    assert single.views == () and np.allclose(single.tile.box, [24.0, 34.05, 64.0, 99.5])
    plain = Detection("chair", 0.9, [240.0, 100.0, 300.0, 180.0], 512, 256)
    assert r.refine(pano, plain) is plain


def test_bad_weights_and_options_are_refused(tmp_path):
    from detect.backends import ModelFileError

    with pytest.raises(ModelFileError, match="not found"):
        BoxRefiner(tmp_path / "missing.pt")
    (tmp_path / "junk.pt").write_bytes(b"not a model")
    with pytest.raises(ModelFileError, match="not box refiner weights"):
        BoxRefiner(tmp_path / "junk.pt")
    from detect.builtin.backend import DEFAULT_WEIGHTS

    with pytest.raises(ModelFileError, match="not box refiner weights.*builtin-detector"):
        BoxRefiner(DEFAULT_WEIGHTS)   # the detector's weights file: another format tag
    with pytest.raises(ValueError, match="passes"):
        BoxRefiner(passes=0)


def _matched_errors(pano, dets, truth) -> tuple[np.ndarray, np.ndarray]:
    """Per detection matched to a gt box (same class): |edge error| of its tile box as a panorama box, px."""
    from detect.nms import pano_box_iou
    from panogeom.perspective import box_to_pano

    H, W = pano.shape[:2]
    errs = []
    for d in dets:
        same = [o for o in truth if o["class"] == d.label and o["bbox_pano"] is not None]
        if not same or d.tile is None or d.tile.border_edges().any():
            continue
        iou = pano_box_iou(np.array([d.box]), np.array([o["bbox_pano"] for o in same], float), W, H)[0]
        if iou.max() < 0.5:
            continue
        g = np.array(same[int(np.argmax(iou))]["bbox_pano"], float)
        b = box_to_pano(d.tile.box, d.tile.view, W, H).extent
        if g[0] < g[2] and b[0] < b[2]:   # neither wraps the seam
            errs.append(np.abs(b - g))
    return np.array(errs)


def test_committed_refiner_brings_detector_boxes_closer_on_a_held_back_room():
    """Seed 4100, never trained on: the refined tile boxes are closer to the true boxes than the detector's."""
    import cv2

    from detect.builtin import BuiltinDetector
    from detect.tiles import detect_panorama

    assert DEFAULT_REFINE_WEIGHTS.stat().st_size < 3 * 2 ** 20
    rec = BoxRefiner().record
    assert rec["weights"] == "refine.pt" and "seed" in rec["training"]
    pano = cv2.cvtColor(cv2.imread(str(ROOM / "pano.jpg")), cv2.COLOR_BGR2RGB)
    truth = json.loads((ROOM / "gt.json").read_text())["objects"]
    det = BuiltinDetector()
    dets = [d for d in detect_panorama(pano, det, views=det.views()) if d.tile is not None]
    before = _matched_errors(pano, dets, truth)
    refiner = BoxRefiner()
    one_by_one = [refiner.refine(pano, d) for d in dets]
    after = _matched_errors(pano, one_by_one, truth)
    assert len(before) >= 3 and len(after) == len(before)
    assert after.mean() < 0.8 * before.mean(), (before.mean(), after.mean())
    # all detections in one batch: the same boxes
    batched = refiner.refine_detections(pano, dets)
    assert len(batched) == len(dets)
    for a, b in zip(one_by_one, batched):
        assert len(a.views) == len(b.views) and np.allclose(a.tile.box, b.tile.box, atol=1e-3)
        assert all(np.allclose(x.box, y.box, atol=1e-3) for x, y in zip(a.views, b.views))


def test_training_cli_writes_weights_and_record(tmp_path, synth):
    from detect.builtin.train_refine import main

    data = synth.fake_rooms(tmp_path / "train", 3000, 2)
    val = synth.fake_rooms(tmp_path / "val", 3500)
    out = tmp_path / "w"
    assert main(["--data", str(data), "--val", str(val), "--out", str(out), "--rooms", "2", "--iterations", "3",
                 "--batch", "4", "--workers", "1", "--views", "2", "--jitters", "1"]) == 0
    rec = json.loads((out / "refine.json").read_text())
    assert rec["training"]["iterations"] == 3 and rec["data"]["train_rooms"] == 2
    assert set(rec["validation"]) == {"input boxes", "one pass"}
    assert BoxRefiner(out / "refine.pt").config.size == 64
    seed0 = synth.fake_rooms(tmp_path / "seed0", 0)
    assert main(["--data", str(seed0), "--val", str(val), "--out", str(out), "--iterations", "1"]) == 2


def _tiny_training(tmp_path, synth):
    """train_refine's main and options on two fake rooms, after a first run of 2 iterations into tmp_path / "a"."""
    from detect.builtin.train_refine import main

    data = synth.fake_rooms(tmp_path / "train", 3000, 2)
    val = synth.fake_rooms(tmp_path / "val", 3500)
    args = ["--data", str(data), "--val", str(val), "--rooms", "2", "--batch", "4", "--workers", "1", "--views",
            "2", "--jitters", "1"]
    assert main(args + ["--out", str(tmp_path / "a"), "--iterations", "2", "--seed", "1"]) == 0
    return main, args


def test_training_further_never_returns_worse_weights(tmp_path, synth):
    main, args = _tiny_training(tmp_path, synth)
    # a rate that wrecks the weights in three steps: the given ones and the last state are both validated
    assert main(args + ["--out", str(tmp_path / "b"), "--iterations", "3", "--lr", "50", "--init",
                        str(tmp_path / "a" / "refine.pt")]) == 0
    rec = json.loads((tmp_path / "b" / "refine.json").read_text())
    hist = rec["training"]["history"]
    assert [h["iteration"] for h in hist] == [0, 3]
    kept = rec["training"]["kept_iteration"]
    assert kept == (0 if hist[0]["val_mean_abs_deg"] <= hist[1]["val_mean_abs_deg"] else 3)
    score = hist[0 if kept == 0 else 1]["val_mean_abs_deg"]
    # the file written is the state kept: its validation after one pass is that state's score
    assert np.mean(rec["validation"]["one pass"]["mean_abs_deg"]) == pytest.approx(score, abs=2e-3)


def test_training_goes_on_from_given_weights(tmp_path, synth):
    main, args = _tiny_training(tmp_path, synth)
    # no iteration from the first weights: the second file reads every window as the first does
    assert main(args + ["--out", str(tmp_path / "b"), "--iterations", "0", "--init", str(tmp_path / "a" / "refine.pt")]) == 0
    rec = json.loads((tmp_path / "b" / "refine.json").read_text())
    assert rec["init"]["weights"].endswith("refine.pt") and rec["init"]["record"]["training"]["iterations"] == 2
    rng = np.random.default_rng(0)
    wins = rng.integers(0, 256, (3, 64, 64, 3), dtype=np.uint8)
    a = BoxRefiner(tmp_path / "a" / "refine.pt").moves(wins, ["bed", "chair", "tv"])
    b = BoxRefiner(tmp_path / "b" / "refine.pt").moves(wins, ["bed", "chair", "tv"])
    assert np.allclose(a, b)
    assert main(args + ["--out", str(tmp_path / "r"), "--iterations", "0"]) == 0  # random weights read otherwise
    assert not np.allclose(a, BoxRefiner(tmp_path / "r" / "refine.pt").moves(wins, ["bed", "chair", "tv"]))
    assert main(args + ["--out", str(tmp_path / "c"), "--iterations", "1", "--init", str(tmp_path / "nope.pt")]) == 2
