"""Tests of layout.surfaces.boundary_net and .train_boundary: the network, its targets, the training script."""

from __future__ import annotations

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from layout.labelmap import render_room_labels  # noqa: E402
from layout.surfaces import estimate_surfaces  # noqa: E402
from layout.surfaces.boundary_net import (  # noqa: E402
    BOUNDARY_WEIGHTS,
    BoundaryNet,
    build_boundary_net,
    load_boundary_net,
    predict_boundaries,
)
from layout.surfaces.train_boundary import (  # noqa: E402
    load_boundary_folder,
    main,
    room_boundary_targets,
    train_boundary,
)

ROOM = [[-2.0, -1.5], [3.0, -1.5], [3.0, 2.0], [-2.0, 2.0]]
COLOURS = np.array([[0, 0, 0], [40, 60, 120], [230, 230, 230], [180, 190, 200], [160, 170, 180], [0, 0, 200]])


def _room_image(floor, ceiling_z, camera_height, width):
    lab = render_room_labels(floor, ceiling_z, [0.0, 0.0], camera_height, width)
    return COLOURS[lab].astype(np.uint8), lab


def test_network_maps_a_panorama_to_two_boundaries_per_column():
    torch.manual_seed(0)
    net = build_boundary_net(64).eval()
    with torch.inference_mode():
        y = net(torch.rand(2, 3, 64, 128))
    assert tuple(y.shape) == (2, 2, 128)
    # untrained, the head starts near a ceiling above and a floor below the horizon
    assert float(y[:, 0].max()) < 0.5 < float(y[:, 1].min())
    with pytest.raises(ValueError, match="multiple of 32"):
        build_boundary_net(48)


def test_targets_are_the_rendered_rooms_boundaries():
    img, lab = _room_image(ROOM, 2.7, 1.5, 256)
    t = room_boundary_targets({"room": {"floor": ROOM, "ceiling_z": 2.7}, "camera_height_m": 1.5}, 256)
    h = lab.shape[0]
    # rows of the first wall pixel under the ceiling and of the first floor pixel, per column
    first_wall = np.argmax(np.isin(lab, (3, 4)), axis=0)
    first_floor = np.argmax(lab == 1, axis=0)
    assert np.all(np.abs(t[0] * h - first_wall) <= 1.0)
    assert np.all(np.abs(t[1] * h - first_floor) <= 1.0)
    with pytest.raises(ValueError, match="not inside"):
        room_boundary_targets({"room": {"floor": [[1, 1], [2, 1], [2, 2], [1, 2]], "ceiling_z": 2.7},
                               "camera_height_m": 1.5}, 64)


def test_boundaries_are_resampled_to_the_panorama_and_kept_on_their_side_of_the_horizon():
    torch.manual_seed(0)
    model = BoundaryNet(net=build_boundary_net(32).eval(), work_width=64)
    img, _ = _room_image(ROOM, 2.7, 1.5, 256)
    rows = model(img)
    assert rows.shape == (2, 256)
    assert np.all((rows[0] >= 1) & (rows[0] <= 63)) and np.all((rows[1] >= 65) & (rows[1] <= 127))
    small = model.rows_at_work_size(img) * 32
    # a column of the panorama takes the value of the working-size columns around it
    assert np.allclose(rows[:, 2::4] / 4, np.clip(small, [[1 / 4], [65 / 4]], [[63 / 4], [127 / 4]]), atol=0.6)


def test_committed_weights_and_their_record():
    model = load_boundary_net()
    rec = model.record
    assert rec["schema"] == "pano2cad/boundary-net@1" and rec["work_width"] == model.work_width == 512
    assert rec["params"] == sum(p.numel() for p in model.net.parameters())
    assert BOUNDARY_WEIGHTS.stat().st_size < 2_000_000
    seeds = {x for src in rec["train"]["sources"] for x in src["seeds"]}
    val_seeds = {x for src in rec["val"]["sources"] for x in src["seeds"]}
    assert seeds and not seeds & ({0, 7000, 8000} | val_seeds)
    assert rec["val"]["ceiling_mae_px"] < 2.0 and rec["best_epoch"] <= rec["epochs_done"]


@pytest.mark.parametrize("floor", [ROOM, [[-2, -1.5], [3, -1.5], [3, 1], [1, 1], [1, 2.5], [-2, 2.5]]])
def test_committed_network_finds_the_boundaries_of_a_plain_room(floor):
    # flat colours, no furniture: unlike the textured training rooms, but the junctions are plain to see
    colours = np.array([[0, 0, 0], [120, 90, 60], [235, 235, 235], [200, 195, 185], [185, 180, 170], [0, 0, 200]])
    lab = render_room_labels(floor, 2.7, [0.0, 0.0], 1.5, 1024)
    rows = predict_boundaries(colours[lab].astype(np.uint8))
    true = room_boundary_targets({"room": {"floor": floor, "ceiling_z": 2.7}, "camera_height_m": 1.5}, 1024) * 512
    err = np.abs(rows - true)
    assert rows.shape == (2, 1024) and err.mean() < 6.0 and np.median(err) < 6.0


def _write_rooms(root, seed, n, size=64):
    import cv2

    rng = np.random.default_rng(seed)
    for i in range(n):
        d = root / f"room-{i:04d}"
        d.mkdir(parents=True)
        shift = rng.uniform(-0.5, 0.5, 2)
        floor = (np.asarray(ROOM) - shift).tolist()
        img, lab = _room_image(floor, 2.7, 1.5, size)
        cv2.imwrite(str(d / "pano.png"), img[..., ::-1])
        cv2.imwrite(str(d / "labels.png"), lab)
        (d / "gt.json").write_text(json.dumps({"generator": {"seed": seed, "index": i}, "camera_height_m": 1.5,
                                               "room": {"floor": floor, "ceiling_z": 2.7}}))


def test_training_script_writes_loadable_weights_and_a_record(tmp_path):
    torch.manual_seed(0)
    _write_rooms(tmp_path / "train", 1000, 4)
    _write_rooms(tmp_path / "val", 2000, 2)
    tr, tr_t = load_boundary_folder(tmp_path / "train", 64)
    va, va_t = load_boundary_folder(tmp_path / "val", 64)
    assert tr_t.shape == (4, 2, 64) and tr.sources[0]["seeds"] == [1000]
    rec = train_boundary(tr, tr_t, va, va_t, tmp_path / "w", epochs=3, batch=2, log=lambda s: None)
    assert rec["epochs_done"] == 3 and rec["weights_dtype"] == "float16"
    # training moved the boundaries towards the targets
    assert rec["history"][-1]["loss"] < rec["history"][0]["loss"]
    stored = json.loads((tmp_path / "w" / "boundary_net.json").read_text())
    assert stored["val"]["ceiling_mae_px"] == rec["val"]["ceiling_mae_px"]
    model = load_boundary_net(tmp_path / "w" / "boundary_net.pt")
    assert model.work_width == 64 and model.record["train"]["rooms"] == 4
    # a second stage starts from the first one's weights: its first epoch begins where they ended
    rec2 = train_boundary(tr, tr_t, va, va_t, tmp_path / "w2", epochs=1, batch=2, lr=1e-4,
                          init=tmp_path / "w" / "boundary_net.pt", log=lambda s: None)
    assert rec2["init"]["path"] == str(tmp_path / "w" / "boundary_net.pt") and rec2["epochs_total"] == 4
    assert rec2["history"][0]["loss"] < rec["history"][0]["loss"]
    with pytest.raises(ValueError, match="working width"):
        va128, va128_t = load_boundary_folder(tmp_path / "val", 128)
        train_boundary(va128, va128_t, va128, va128_t, tmp_path / "w3", epochs=1,
                       init=tmp_path / "w" / "boundary_net.pt", log=lambda s: None)
    # the command line refuses a validation set that was trained on, and the evaluation / tuning seeds
    assert main(["--data", str(tmp_path / "train"), "--val", str(tmp_path / "train"), "--out",
                 str(tmp_path / "x"), "--work-width", "64"]) == 2
    _write_rooms(tmp_path / "tune", 7000, 1)
    assert main(["--data", str(tmp_path / "tune"), "--val", str(tmp_path / "val"), "--out",
                 str(tmp_path / "x"), "--work-width", "64"]) == 2
    (tmp_path / "train" / "room-0000" / "gt.json").unlink()
    assert main(["--data", str(tmp_path / "train"), "--val", str(tmp_path / "val"), "--out",
                 str(tmp_path / "x"), "--work-width", "64"]) == 2
    with pytest.raises(FileNotFoundError, match="train_boundary"):
        load_boundary_net(tmp_path / "nothing.pt")


class _ShiftedRows:
    """A stand-in boundary model: fixed ceiling and floor curves (one row per column of the panorama; the floor
    three quarters down where not given)."""

    def __init__(self, rows, floor_rows=None):
        self.rows = np.asarray(rows, dtype=float)
        self.floor_rows = None if floor_rows is None else np.asarray(floor_rows, dtype=float)

    def __call__(self, pano):
        h, w = pano.shape[:2]
        return np.stack([self.rows, np.full(w, h * 0.75) if self.floor_rows is None else self.floor_rows])


def test_estimate_surfaces_moves_the_ceiling_boundary_onto_the_networks():
    img, _ = _room_image(ROOM, 2.7, 1.5, 256)
    base = estimate_surfaces(img)
    for shift in (-1.0, 1.0):  # one row up / down in every column (4 of a 512-row map)
        target = np.round(base.columns.ceiling_v) + shift
        moved = estimate_surfaces(img, ceiling_net=_ShiftedRows(target, base.columns.floor_v))
        rows = np.arange(64)[:, None]
        above = (rows < target[None, :]) & np.isin(base.labels[:64], (2, 3, 4))
        lo, hi = np.minimum(target, target - shift), np.maximum(target, target - shift)
        band = (rows >= lo[None, :]) & (rows < hi[None, :])  # the row between the old and the new boundary
        assert np.all(moved.labels[:64][above] == 2)
        assert np.isin(moved.labels[:64][band], (3, 4) if shift < 0 else (2,)).mean() > 0.95
    assert np.array_equal(moved.columns.ceiling_v, target) and not moved.warnings
    assert np.array_equal(moved.labels[64:], base.labels[64:])
    with pytest.raises(ValueError, match="at most one"):
        estimate_surfaces(img, snap_ceiling=True, ceiling_net=_ShiftedRows(target))


def test_a_network_boundary_far_from_the_labels_everywhere_is_not_used():
    img, _ = _room_image(ROOM, 2.7, 1.5, 256)
    base = estimate_surfaces(img)
    # 12 rows of this 128-row map are 48 of a 512-row one: the network "sees another room"
    far = estimate_surfaces(img, ceiling_net=_ShiftedRows(np.round(base.columns.ceiling_v) - 12.0))
    assert np.array_equal(far.labels, base.labels)
    assert any("labels' boundary is kept" in w for w in far.warnings)
