"""The learned view-relative yaw prior (posecrf.orientnet) and its training script."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from posecrf.crops import extract_crop, relative_yaw
from posecrf.orientnet import (
    DEFAULT_WEIGHTS,
    INPUT_SIZE,
    N_BINS,
    ORIENT_CLASSES,
    build_network,
    head_probabilities,
    load_orientation_net,
    mirror_average,
    orientation_costs,
    prepare_crops,
    save_weights,
)
from posecrf.train_orientation import _soft_targets, read_rgb, train

ROOM = Path(__file__).resolve().parents[1] / "detect" / "data" / "builtin_room"  # seed 4100: never trained on


def _ang(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2.0 * math.pi) - math.pi)


def test_costs_uniform_is_zero_and_peak_is_cheapest():
    assert np.allclose(orientation_costs(np.full(N_BINS, 1.0 / N_BINS), np.linspace(0, 7, 50)), 0.0)
    p = np.full(N_BINS, 0.01)
    p[6] = 1.0
    p /= p.sum()
    yaws = np.arange(360) * math.pi / 180.0
    c = orientation_costs(p, yaws)
    assert abs(yaws[np.argmin(c)] - 6 * 2 * math.pi / N_BINS) < 1e-9
    # linear on the circle between bin centres: half-way costs -log of the mean density
    half = orientation_costs(p, [6.5 * 2 * math.pi / N_BINS])[0]
    assert half == pytest.approx(-math.log(N_BINS * 0.5 * (p[6] + p[7])))
    # wraps: yaw and yaw + 2 pi cost the same
    assert np.allclose(orientation_costs(p, yaws), orientation_costs(p, yaws + 2 * math.pi))


def test_costs_of_several_views_add_on_the_world_yaw():
    rng = np.random.default_rng(1)
    p, q = rng.random((2, N_BINS)) + 0.05
    p, q = p / p.sum(), q / q.sum()
    y = np.linspace(0, 2 * math.pi, 73)
    # one row: the single crop's cost; the same row twice without shifts: twice it
    assert np.allclose(orientation_costs([p], y), orientation_costs(p, y))
    assert np.allclose(orientation_costs([p, p], y, shifts=[0.0, 0.0]), 2 * orientation_costs(p, y))
    # the second crop read at yaw + shift, for each symmetry
    for sym in ("none", "two"):
        two = orientation_costs([p, q], y, sym, shifts=[0.0, 0.7])
        assert np.allclose(two, orientation_costs(p, y, sym) + orientation_costs(q, y + 0.7, sym))
    assert np.all(orientation_costs([p, q], y, "full", shifts=[0.0, 0.7]) == 0.0)
    # the first view sees the object turned round; two less sure views that agree on the world yaw (yaw k in the
    # first view's frame: bin k + s_j in view j's) outvote it
    k = 3
    peak = np.full((3, N_BINS), 0.3 / (N_BINS - 1))
    peak[0] = 0.2 / (N_BINS - 1)
    s = np.array([0, 5, 9])
    for j, b in enumerate([k + N_BINS // 2, k + 5, k + 9]):
        peak[j, b % N_BINS] = 0.8 if j == 0 else 0.7
    c = orientation_costs(peak, y, shifts=2 * math.pi * s / N_BINS)
    assert _ang(y[np.argmin(c)], 2 * math.pi * k / N_BINS) < 1e-9
    # shifts the wrong way round would scatter the agreeing views: the first view's yaw wins
    c = orientation_costs(peak, y, shifts=-2 * math.pi * s / N_BINS)
    assert _ang(y[np.argmin(c)], 2 * math.pi * (k + N_BINS // 2) / N_BINS) < 1e-9
    with pytest.raises(ValueError, match="shifts"):
        orientation_costs([p, q], y, shifts=[0.0])
    with pytest.raises(ValueError, match="probs"):
        orientation_costs(np.zeros((0, N_BINS)), y)


def test_costs_symmetry():
    p = np.random.default_rng(0).random(N_BINS)
    p /= p.sum()
    y = np.linspace(0, 2 * math.pi, 37)
    two = orientation_costs(p, y, "two")
    assert np.allclose(two, orientation_costs(p, y + math.pi, "two"))
    assert np.all(two <= np.maximum(orientation_costs(p, y), orientation_costs(p, y + math.pi)) + 1e-12)
    assert np.all(orientation_costs(p, y, "full") == 0.0)
    with pytest.raises(ValueError, match="symmetry"):
        orientation_costs(p, y, "three")
    with pytest.raises(ValueError, match="probs"):
        orientation_costs([0.5, -0.5, 1.0], y)


def test_prepare_crops_pads_to_square():
    tall = np.zeros((100, 20, 3), np.uint8)
    x = prepare_crops([tall, np.full((8, 8, 3), 255, np.uint8)])
    assert x.shape == (2, 3, INPUT_SIZE, INPUT_SIZE) and x.dtype == np.float32
    assert x[0, :, :, 0].max() == pytest.approx(128 / 255 - 0.5, abs=1e-6)  # grey padding on the sides
    assert x[0, :, INPUT_SIZE // 2, INPUT_SIZE // 2].max() == -0.5  # the black crop in the middle
    assert np.allclose(x[1], 0.5)
    with pytest.raises(ValueError, match=r"crops\[0\]"):
        prepare_crops([np.zeros((4, 4), np.uint8)])


def test_committed_weights_load_and_score():
    net = load_orientation_net()
    assert net.classes == ORIENT_CLASSES and net.n_bins == N_BINS
    record = json.loads(DEFAULT_WEIGHTS.with_suffix(".json").read_text())
    assert record["weights_bytes"] == DEFAULT_WEIGHTS.stat().st_size < 2_000_000
    p = net.probabilities([np.zeros((40, 64, 3), np.uint8)] * 2, ["chair", "tv"])
    assert p.shape == (2, N_BINS) and np.allclose(p.sum(axis=1), 1.0)
    with pytest.raises(ValueError, match="plant"):
        net.probabilities([np.zeros((40, 64, 3), np.uint8)], ["plant"])


def test_committed_weights_on_a_held_out_room():
    """The room of the detector tests (seed 4100, not a training seed): most objects' most likely yaw is right."""
    gt = json.loads((ROOM / "gt.json").read_text())
    pano = read_rgb(ROOM / "pano.jpg")
    net = load_orientation_net()
    errs = []
    for o in gt["objects"]:
        if o["class"] in ORIENT_CLASSES and o["visible_px"] >= 1000:
            crop, view = extract_crop(pano, o["bbox_pano"])
            p = net.probabilities([crop], [o["class"]])[0]
            truth = float(relative_yaw(math.radians(o["yaw_deg"]), view.direction))
            errs.append(_ang(2 * math.pi * int(np.argmax(p)) / N_BINS, truth))
    assert len(errs) == 6
    assert sum(e <= math.radians(45) for e in errs) >= 5, np.degrees(errs).round()


def test_bad_weight_files_name_the_file(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.pt"):
        load_orientation_net(tmp_path / "missing.pt")
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"not a torch file")
    with pytest.raises(ValueError, match="bad.pt"):
        load_orientation_net(bad)


def _saved_random_network(path: Path):
    """A randomly initialised network (seed 0), saved to ``path`` and loaded back: (module, OrientationNet)."""
    import torch

    torch.manual_seed(0)
    net = build_network()
    net.eval()
    save_weights(net, ORIENT_CLASSES, path)
    return net, load_orientation_net(path)


def test_save_and_load_round_trip(tmp_path):
    import torch

    net, loaded = _saved_random_network(tmp_path / "w.pt")
    crop = np.random.default_rng(1).integers(0, 255, (50, 70, 3), dtype=np.uint8)
    with torch.no_grad():
        want = torch.softmax(net(torch.from_numpy(prepare_crops([crop])))[0, 1].double(), 0).numpy()
    assert np.allclose(loaded.probabilities([crop], ["chair"], mirror=False)[0], want)
    with torch.no_grad():
        flipped = torch.from_numpy(np.ascontiguousarray(prepare_crops([crop])[..., ::-1]))
        mirrored = torch.softmax(net(flipped)[0, 1].double(), 0).numpy()
    assert np.allclose(loaded.probabilities([crop], ["chair"])[0], mirror_average(want[None], mirrored[None])[0])


def test_the_mirror_average_sees_a_mirrored_crop_at_the_mirrored_yaw(tmp_path):
    """The test-time mirror makes the network equivariant: a crop mirrored left-right gets the yaws mirrored."""
    _, loaded = _saved_random_network(tmp_path / "w.pt")
    crop = np.random.default_rng(2).integers(0, 255, (64, 64, 3), dtype=np.uint8)  # square: no padding to shift
    p = loaded.probabilities([crop], ["bed"])[0]
    q = loaded.probabilities([np.ascontiguousarray(crop[:, ::-1])], ["bed"])[0]
    k = np.arange(N_BINS)
    assert np.allclose(q, p[(-k) % N_BINS])
    assert not np.allclose(q, p)  # a random network is not symmetric by itself
    assert np.isclose(p.sum(), 1.0)


def test_head_probabilities_batches_and_checks_heads():
    import torch

    torch.manual_seed(0)
    net = build_network()
    net.eval()
    rng = np.random.default_rng(2)
    x = prepare_crops([rng.integers(0, 255, (30 + 7 * k, 60, 3), dtype=np.uint8) for k in range(5)])
    heads = np.array([0, 1, 2, 1, 0])
    whole = head_probabilities(net, x, heads)
    assert whole.shape == (5, N_BINS) and np.allclose(whole.sum(axis=1), 1.0)
    assert np.allclose(head_probabilities(net, x, heads, batch=2), whole)
    # each row is its own head's softmax: another head gives another distribution
    assert not np.allclose(head_probabilities(net, x, np.roll(heads, 1))[1], whole[1])
    with pytest.raises(ValueError, match="heads"):
        head_probabilities(net, x, heads[:3])


def test_soft_targets_peak_at_the_label():
    t = _soft_targets(np.array([0.0, math.pi]), 16.0)
    assert t.shape == (2, N_BINS) and np.allclose(t.sum(axis=1), 1.0)
    assert t[0].argmax() == 0 and t[1].argmax() == N_BINS // 2


def test_training_learns_a_visible_cue():
    """Crops whose bright half says the yaw (left: 90 deg, right: 270 deg); a few epochs learn it."""
    rng = np.random.default_rng(0)
    n = 192
    yaw = np.where(rng.random(n) < 0.5, 0.5 * math.pi, 1.5 * math.pi)
    x = rng.uniform(-0.5, -0.3, (n, 3, INPUT_SIZE, INPUT_SIZE)).astype(np.float32)
    left = yaw < math.pi
    x[left, :, :, : INPUT_SIZE // 2] += 0.7
    x[~left, :, :, INPUT_SIZE // 2:] += 0.7
    cls = np.full(n, ORIENT_CLASSES.index("bed"))
    # mirrored crops are labelled -yaw: 90 <-> 270 deg, consistent with the cue
    net = train(x, cls, yaw, epochs=6, batch=32, lr=3e-3, kappa=16.0, seed=0, log=lambda s: None)
    import torch

    with torch.no_grad():
        pred = net(torch.from_numpy(x))[:, cls[0]].argmax(dim=1).numpy() * (2 * math.pi / N_BINS)
    acc = np.mean([_ang(a, b) < math.radians(45) for a, b in zip(pred, yaw)])
    assert acc > 0.9


def test_main_holds_out_the_last_folders_last_rooms(tmp_path):
    """Several ``--rooms`` folders are read in the order given; the held-out rooms are the last folder's."""
    from posecrf.train_orientation import main

    gt = json.loads((ROOM / "gt.json").read_text())
    png = tmp_path / "pano.png"
    import cv2

    cv2.imwrite(str(png), cv2.imread(str(ROOM / "pano.jpg")))
    # given order z, a: a global sort by path would hold out z's room instead
    for folder, keep in (("z", ("bed", "chair", "sofa", "tv")), ("a", ("tv",))):
        room = tmp_path / folder / "room-0000"
        room.mkdir(parents=True)
        (room / "pano.png").write_bytes(png.read_bytes())
        objs = [o for o in gt["objects"] if o["class"] in keep]
        (room / "gt.json").write_text(json.dumps({**gt, "objects": objs}))
    out = tmp_path / "w" / "net.pt"
    args = ["--rooms", str(tmp_path / "z"), str(tmp_path / "a"), "--out", str(out), "--epochs", "1",
            "--jitter", "1", "--val-fraction", "0.5", "--batch", "4"]
    assert main(args) == 0
    rec = json.loads(out.with_suffix(".json").read_text())
    assert rec["rooms"] == {"folders": [str(tmp_path / "z"), str(tmp_path / "a")], "train": 1, "val": 1}
    assert rec["crops"] == {"train": 5, "val": 1}  # z: bed, 2 chairs, sofa, tv; a (held out): its tv
    assert set(rec["validation"]) == {"tv"}
    assert load_orientation_net(out).module is not None
    assert main(["--rooms", str(tmp_path / "none"), "--out", str(out)]) == 2
    # a fine-tuning run starts from given weights: with no learning it ends where they are
    tuned = tmp_path / "w" / "tuned.pt"
    assert main(args[:3] + ["--out", str(tuned)] + args[5:] + ["--init", str(out), "--lr", "1e-12"]) == 0
    assert json.loads(tuned.with_suffix(".json").read_text())["init"] == str(out)
    a, b = load_orientation_net(out).module.state_dict(), load_orientation_net(tuned).module.state_dict()
    assert all(np.allclose(a[k].numpy(), b[k].numpy(), atol=1e-6) for k in a if a[k].is_floating_point()
               and "running" not in k)
    assert main(args[:3] + ["--out", str(tuned)] + args[5:] + ["--init", str(tmp_path / "none.pt")]) == 2
