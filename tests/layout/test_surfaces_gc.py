"""Tests of layout.surfaces.gc_net and .train_gc: the network, its committed weights and record, the training script."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from layout.surfaces.gc_net import (  # noqa: E402
    DEFAULT_WEIGHTS,
    GC_CLASSES,
    GeometricContext,
    build_gc_net,
    gc_probabilities,
    gc_targets,
    load_gc_net,
    resize_wrapped,
)
from layout.surfaces.train_gc import AUGMENTATION, SynthSet, augment, load_synth_folder, main, train_gc  # noqa: E402


def test_network_is_small_and_wraps_around_the_seam():
    torch.manual_seed(0)
    net = build_gc_net().eval()
    assert sum(p.numel() for p in net.parameters()) < 300_000
    x = torch.rand(1, 3, 64, 128)
    with torch.inference_mode():
        y = net(x)
        y_rolled = net(torch.roll(x, 32, dims=3))
    assert tuple(y.shape) == (1, 4, 64, 128)
    # circular padding: rolling the input by a multiple of the total stride rolls the output
    assert torch.allclose(torch.roll(y, 32, dims=3), y_rolled, atol=1e-4)
    with pytest.raises(ValueError, match="4 positive integers"):
        build_gc_net((8, 8, 8))


def test_resize_wrapped_is_exact_for_constant_and_periodic_images():
    img = np.full((8, 16, 4), 0.25, np.float32)
    assert np.allclose(resize_wrapped(img, 64, 32), 0.25)
    u = (np.arange(16) + 0.5) / 16
    ramp = np.cos(2 * np.pi * u)[None, :].repeat(8, 0).astype(np.float32)
    big = resize_wrapped(ramp, 64, 32)
    uu = (np.arange(64) + 0.5) / 64
    assert np.abs(big[10] - np.cos(2 * np.pi * uu)).max() < 0.03  # smooth across the seam too


def test_gc_targets_maps_labels_and_rejects_bad_ids():
    assert gc_targets(np.array([[1, 2], [4, 5]], np.uint8)).tolist() == [[0, 1], [2, 3]]
    with pytest.raises(ValueError, match="label ids in 0..5"):
        gc_targets(np.array([[7]], np.uint8))


def test_committed_weights_and_their_record():
    assert DEFAULT_WEIGHTS.is_file()
    assert DEFAULT_WEIGHTS.stat().st_size < 3_000_000
    rec = json.loads(DEFAULT_WEIGHTS.with_suffix(".json").read_text())
    for key in ("train", "val", "epochs_done", "augmentation", "val_pixel_accuracy", "date", "torch", "params"):
        assert key in rec, key
    seeds = {s for src in rec["train"]["sources"] for s in src["seeds"]}
    val_seeds = {s for src in rec["val"]["sources"] for s in src["seeds"]}
    assert seeds and 0 not in seeds and not (seeds & val_seeds)
    assert rec["train"]["rooms"] >= 100
    gc = load_gc_net()
    assert gc is load_gc_net()  # cached
    assert rec["params"] == sum(p.numel() for p in gc.net.parameters())
    assert rec["classes"] == list(GC_CLASSES)
    assert rec["val_pixel_accuracy"] > 0.9


def test_probabilities_have_the_panorama_size_and_sum_to_one():
    rng = np.random.default_rng(0)
    pano = rng.integers(0, 255, (100, 200, 3), dtype=np.uint8)
    p = gc_probabilities(pano)
    assert p.shape == (100, 200, 4) and p.dtype == np.float32
    assert np.allclose(p.sum(axis=2), 1.0, atol=1e-4)
    with pytest.raises(ValueError, match=r"expected \(H, W, 3\) uint8"):
        gc_probabilities(pano.astype(np.float32))
    with pytest.raises(FileNotFoundError, match="expected a .pt file"):
        load_gc_net("/nonexistent/gc_net.pt")
    with pytest.raises(ValueError, match="multiple of 32"):
        GeometricContext(net=None, work_width=100)


def test_augment_is_seeded_and_keeps_images_and_targets_aligned():
    imgs = torch.zeros(3, 32, 64, 3, dtype=torch.uint8)
    imgs[:, :, :8] = 255  # a bright stripe marks the columns of class 1
    tg = torch.zeros(3, 32, 64, dtype=torch.long)
    tg[:, :, :8] = 1
    x1, y1 = augment(imgs, tg, torch.Generator().manual_seed(4))
    x2, y2 = augment(imgs, tg, torch.Generator().manual_seed(4))
    assert torch.equal(x1, x2) and torch.equal(y1, y2)
    for i in range(3):
        brightest = set(torch.argsort(x1[i].mean(dim=(0, 1)), descending=True)[:8].tolist())
        assert brightest == set(torch.nonzero((y1[i] == 1).any(dim=0)).flatten().tolist())
    assert set(AUGMENTATION) >= {"roll", "mirror_p", "gamma_log", "noise_sigma"}


def _write_rooms(root, seed, n, size=64):
    import cv2

    from layout.labelmap import render_room_labels

    root.mkdir(parents=True)
    rng = np.random.default_rng(seed)
    for i in range(n):
        d = root / f"room-{i:04d}"
        d.mkdir()
        lab = render_room_labels([[-2, -1.5], [3, -1.5], [3, 2], [-2, 2]], 2.7, rng.uniform(-0.5, 0.5, 2), 1.5, size)
        colours = np.array([[0, 0, 0], [40, 60, 120], [230, 230, 230], [180, 190, 200], [160, 170, 180], [0, 0, 200]])
        cv2.imwrite(str(d / "pano.png"), colours[lab].astype(np.uint8))
        cv2.imwrite(str(d / "labels.png"), lab)
        (d / "gt.json").write_text(json.dumps({"generator": {"seed": seed, "index": i}}))


def test_training_script_writes_loadable_weights_and_a_record(tmp_path):
    torch.manual_seed(0)
    _write_rooms(tmp_path / "train", 1000, 4)
    _write_rooms(tmp_path / "val", 2000, 2)
    tr = load_synth_folder(tmp_path / "train", 64)
    assert len(tr) == 4 and tr.sources[0]["seeds"] == [1000] and tr.images.shape == (4, 32, 64, 3)
    rec = train_gc(tr, load_synth_folder(tmp_path / "val", 64), tmp_path / "w", epochs=2, batch=2,
                   channels=(4, 4, 8, 8), log=lambda s: None)
    assert (tmp_path / "w" / "gc_net.pt").is_file() and rec["epochs_done"] == 2
    stored = json.loads((tmp_path / "w" / "gc_net.json").read_text())
    assert stored["val_pixel_accuracy"] == rec["val_pixel_accuracy"] and stored["weights_dtype"] == "float16"
    gc = load_gc_net(tmp_path / "w" / "gc_net.pt")
    assert gc.work_width == 64 and gc.record["train"]["rooms"] == 4
    # the command line refuses a validation seed that was trained on, and seed 0
    assert main(["--data", str(tmp_path / "train"), "--val", str(tmp_path / "train"), "--out",
                 str(tmp_path / "x"), "--work-width", "64"]) == 2
    assert main(["--data", str(tmp_path / "nothing"), "--val", str(tmp_path / "val"), "--out",
                 str(tmp_path / "x")]) == 2
    with pytest.raises(ValueError, match="non-empty"):
        train_gc(SynthSet(tr.images[:0], tr.labels[:0], []), tr, tmp_path / "y")
