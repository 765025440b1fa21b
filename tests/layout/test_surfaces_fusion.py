"""Tests of layout.surfaces.fusion and .overlay: column boundaries, wall orientation, fused labels, overlays."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from layout.labelmap import render_room_labels, room_boundaries
from layout.surfaces import (
    LABEL_COLORS,
    SurfaceLabels,
    boxes_to_mask,
    estimate_surfaces,
    fuse_surfaces,
    label_overlay,
    orientation_map,
    surfaces_figure,
)
from layout.surfaces.fusion import column_boundaries, column_orientation
from layout.surfaces.gc_net import gc_targets
from layout.surfaces.orientation_map import OrientationMap
from panogeom.lines import LineSegments
from panogeom.rotation import rot_z

L_ROOM = np.array([[-1.0, -1.5], [3.0, -1.5], [3.0, 0.5], [1.0, 0.5], [1.0, 2.0], [-1.0, 2.0]])
SHARED = Path(__file__).resolve().parents[2].parent / "shared"


def oracle_probs(labels: np.ndarray, seed: int = 0, noise: float = 0.15, blur: bool = True) -> np.ndarray:
    """GC probabilities from true labels, softened and perturbed (a stand-in for the network)."""
    import cv2

    rng = np.random.default_rng(seed)
    t = gc_targets(labels)
    p = np.eye(4, dtype=np.float32)[np.maximum(t, 0)] * 0.8 + 0.05
    p += noise * rng.random(p.shape).astype(np.float32)
    if blur:
        p = cv2.GaussianBlur(p, (5, 5), 1.5)
    return p / p.sum(axis=2, keepdims=True)


def empty_om(h: int, w: int) -> OrientationMap:
    return OrientationMap(np.zeros((h, w), np.uint8), np.zeros((h, w), np.float32), np.zeros((h, w, 3), np.float32),
                          np.zeros(3, np.int64))


def box_edges(lo, hi, camera) -> LineSegments:
    c = np.array(list(itertools.product([lo[0], hi[0]], [lo[1], hi[1]], [lo[2], hi[2]]))) - np.asarray(camera)
    pairs = [(i, j) for i, j in itertools.combinations(range(8), 2) if np.sum(c[i] != c[j]) == 1]
    return LineSegments.from_endpoints(c[[i for i, _ in pairs]], c[[j for _, j in pairs]])


def test_column_boundaries_find_the_best_split_rows():
    rng = np.random.default_rng(1)
    H, W = 32, 64
    c_true = rng.integers(2, 15, W)
    f_true = rng.integers(18, 30, W)
    rows = np.arange(H)[:, None]
    lab = np.where(rows < c_true, 2, np.where(rows >= f_true, 1, 3)).astype(np.uint8)
    c, f = column_boundaries(oracle_probs(lab, noise=0.0, blur=False))
    assert np.abs(c - c_true).max() <= 1 and np.abs(f - f_true).max() <= 1
    assert np.all(c <= H / 2) and np.all(f >= H / 2)
    with pytest.raises(ValueError, match=r"expected \(H, W, 4\)"):
        column_boundaries(np.zeros((4, 8, 3)))


def test_clutter_mask_is_neutral_for_the_boundaries():
    H, W = 32, 64
    lab = render_room_labels(L_ROOM, 2.7, [0.0, 0.0], 1.5, W)
    p = oracle_probs(lab, noise=0.0)
    c0, f0 = column_boundaries(p)
    hide = np.zeros((H, W), bool)
    hide[20:26, 10:30] = True  # an object over the floor boundary
    bad = p.copy()
    bad[hide] = (0.0, 1.0, 0.0, 0.0)  # nonsense (ceiling) under the object
    c1, f1 = column_boundaries(bad, hide)
    assert np.array_equal(c0, c1)
    assert np.all(np.abs(f1 - f0)[:10] == 0) and np.all(np.abs(f1 - f0)[30:] == 0)


@pytest.mark.parametrize("floor, cam", [(L_ROOM, [0.0, 0.0]), (L_ROOM, [2.2, -0.6]),
                                        (np.array([[-2.0, -1.0], [4.0, -1.0], [4.0, 3.0], [-2.0, 3.0]]), [0.3, 0.1])])
def test_boundary_shape_alone_orients_the_walls(floor, cam):
    W, H = 512, 256
    truth = render_room_labels(floor, 2.8, cam, 1.5, W)
    s = fuse_surfaces(oracle_probs(truth), empty_om(H, W))
    wall = (truth == 3) | (truth == 4)
    assert np.mean(s.layout[wall] == truth[wall]) > 0.95
    assert np.mean(s.labels == truth) > 0.93
    assert s.columns.ceiling_ratio == pytest.approx((2.8 - 1.5) / 1.5, rel=0.05)


@pytest.mark.parametrize("cam", [[0.0, 0.0], [2.2, -0.6]])
def test_the_empty_room_boundaries_orient_the_walls_that_objects_hide(cam):
    # an object hides 80 columns around each corner from floor to ceiling and the OM is empty: GC's boundaries say
    # nothing there and the chain guesses where the wall turns (half the columns wrong); the empty room's
    # boundaries (what the boundary network regresses) put the turn in its place
    W, H = 512, 256
    truth = render_room_labels(L_ROOM, 2.8, cam, 1.5, W)
    rb = room_boundaries(L_ROOM, 2.8, cam, 1.5, W)
    corners = np.flatnonzero(rb.wall_label != np.roll(rb.wall_label, 1))
    for c in corners:
        band = np.abs((np.arange(W) - c + W // 2) % W - W // 2) <= 40
        obj = np.zeros((H, W), bool)
        obj[:, band] = True
        gc_only = fuse_surfaces(oracle_probs(truth), empty_om(H, W), object_mask=obj)
        empty = fuse_surfaces(oracle_probs(truth), empty_om(H, W), object_mask=obj,
                              empty_room_rows=np.stack([rb.ceil_v, rb.floor_v]))
        assert np.mean(empty.columns.wall_label[band] == rb.wall_label[band]) > 0.94
        assert np.mean(gc_only.columns.wall_label[band] == rb.wall_label[band]) < 0.75
        # the labels' own boundaries still come from GC
        assert np.array_equal(empty.columns.ceiling_v, gc_only.columns.ceiling_v)
    with pytest.raises(ValueError, match="empty_room_rows"):
        fuse_surfaces(oracle_probs(truth), empty_om(H, W), empty_room_rows=np.zeros((2, W - 1)))


def test_column_orientation_follows_the_om_where_the_boundaries_say_nothing():
    W = 128
    psi = np.linspace(-np.pi, np.pi, W, endpoint=False)
    zero, one = np.zeros(W), np.ones(W)
    om_x = np.where(np.arange(W) < 64, 1.0, 0.0)
    r = column_orientation(psi, -0.5 * one, 0.5 * one, zero, zero, om_x, 1.0 - om_x, height=64)
    assert np.all(r["wall_label"][5:59] == 3) and np.all(r["wall_label"][69:123] == 4)
    assert np.isnan(r["ceiling_ratio"])
    with pytest.raises(ValueError, match="one length"):
        column_orientation(psi, zero[:5], zero, zero, zero, zero, zero)


def test_fusion_with_orientation_map_and_objects():
    W, H = 512, 256
    lo, hi, cam = np.array([-1.5, -2.5, 0.0]), np.array([3.5, 2.0, 2.7]), np.array([0.0, 0.0, 1.5])
    floor = [[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]]
    truth = render_room_labels(floor, hi[2], cam[:2], cam[2], W)
    om = orientation_map(box_edges(lo, hi, cam), W, om_width=256)
    obj = np.zeros((H, W), bool)
    obj[150:200, 100:160] = True
    s = fuse_surfaces(oracle_probs(truth, seed=2), om, object_mask=obj)
    assert isinstance(s, SurfaceLabels)
    assert np.all(s.labels[obj] == 5) and not np.any(s.labels[~obj] == 5)
    keep = ~obj
    assert np.mean(s.labels[keep] == truth[keep]) > 0.95
    wall = ((truth == 3) | (truth == 4)) & keep & ((s.labels == 3) | (s.labels == 4))
    assert np.mean(s.labels[wall] == truth[wall]) > 0.97
    assert s.labels.dtype == np.uint8 and s.confidence.dtype == np.float32 and s.gc_probs.shape == (H, W, 4)
    assert np.all((s.confidence >= 0) & (s.confidence <= 1)) and np.all(s.confidence[s.labels == 0] == 0)
    # the layout map fills what the object hides
    assert np.mean(s.layout[obj] == truth[obj]) > 0.9


def test_unknown_where_both_sources_are_unsure():
    W, H = 256, 128
    truth = render_room_labels(L_ROOM, 2.7, [0.0, 0.0], 1.5, W)
    p = oracle_probs(truth, noise=0.0)
    flat = p.copy()
    flat[40:60, 20:60] = 0.25  # GC has no idea here, no OM either
    s = fuse_surfaces(flat, empty_om(H, W))
    assert np.all(s.labels[40:60, 20:60] == 0)
    om = OrientationMap(truth.copy(), np.ones((H, W), np.float32), np.ones((H, W, 3), np.float32),
                        np.array([5, 5, 5]))
    s2 = fuse_surfaces(flat, om)  # the OM confirms what the column model says
    region = s2.labels[40:60, 20:60]
    assert np.mean(region == truth[40:60, 20:60]) > 0.9


def test_fusion_checks_its_inputs():
    p = np.full((8, 16, 4), 0.25, np.float32)
    with pytest.raises(ValueError, match="W == 2\\*H"):
        fuse_surfaces(np.zeros((8, 8, 4)), empty_om(8, 8))
    with pytest.raises(ValueError, match="OrientationMap of shape"):
        fuse_surfaces(p, empty_om(4, 8))
    with pytest.raises(ValueError, match="upright"):
        fuse_surfaces(p, empty_om(8, 16), axes=np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]]))
    with pytest.raises(ValueError, match="object_mask: expected shape"):
        fuse_surfaces(p, empty_om(8, 16), object_mask=np.zeros((8, 8), bool))
    with pytest.raises(ValueError, match=r"pano: expected \(H, W, 3\) uint8"):
        estimate_surfaces(np.zeros((8, 16), np.uint8))
    with pytest.raises(ValueError, match="v0 <= v1"):
        boxes_to_mask([[0, 5, 4, 2]], 16, 8)


def test_turned_axes_relabel_the_walls():
    W, H = 256, 128
    truth = render_room_labels(L_ROOM, 2.7, [0.0, 0.0], 1.5, W)
    p = oracle_probs(truth, noise=0.0)
    # axes with x and y exchanged (a quarter turn): the same walls, the other label
    s0 = fuse_surfaces(p, empty_om(H, W))
    s1 = fuse_surfaces(p, empty_om(H, W), axes=rot_z(np.pi / 2).T)
    wall = (s0.layout >= 3)
    assert np.mean(s1.layout[wall] == (7 - s0.layout[wall])) > 0.98


def render_empty_room(seed: int, width: int = 512):
    """A furnished-free room of the project's generator, rendered and shaded (no furniture)."""
    from layout.labelmap import sample_camera_xy
    from layout.rooms import generate_room
    from panogeom.raycast import raycast_equirect, room_meshes
    from panogeom.texture import sample_post, sample_styles, shade

    rng = np.random.default_rng([seed, 0])
    room = generate_room(rng)
    room = room.translated(-sample_camera_xy(room.floor, rng, margin=0.6))
    meshes = [room_meshes(room.floor, room.ceiling_z)]
    res = raycast_equirect(meshes, width, camera_position=(0.0, 0.0, float(rng.uniform(1.3, 1.7))))
    rgb = shade(res, meshes, materials=sample_styles(rng), rng=rng, post=sample_post(rng))
    return rgb, res.labels.astype(np.uint8)


def test_estimate_surfaces_on_rendered_rooms():
    acc, orient = [], []
    for seed in (9001, 9002, 9003):
        rgb, truth = render_empty_room(seed)
        s = estimate_surfaces(rgb)
        assert s.om.shape == truth.shape and s.warnings == ()
        wall = ((truth == 3) | (truth == 4)) & (s.labels >= 3)
        acc.append(np.mean(s.labels == truth))
        orient.append(np.mean(s.labels[wall] == truth[wall]))
    # room 9002 has a dark ceiling much like its walls: the weakest of the three
    assert min(acc) > 0.85 and np.mean(acc) > 0.93
    assert min(orient) > 0.95


def test_no_lines_still_give_gc_labels_and_a_warning():
    rgb, truth = render_empty_room(9003, 256)
    blurred = np.ascontiguousarray(rgb)
    s = estimate_surfaces(blurred, segments=LineSegments.empty())
    assert any("no usable line segments" in w for w in s.warnings)
    assert np.all(s.om == 0)
    assert np.mean(s.labels == truth) > 0.85
    s2 = estimate_surfaces(np.zeros((64, 128, 3), np.uint8))  # black: no lines at all
    assert s2.labels.shape == (64, 128) and len(s2.warnings) >= 1


def test_object_boxes_are_masked_and_wrap_the_seam():
    rgb, _ = render_empty_room(9004, 256)
    s = estimate_surfaces(rgb, object_boxes=[[250.0, 70.0, 10.0, 100.0]])
    assert np.all(s.labels[70:100, 250:] == 5) and np.all(s.labels[70:100, :10] == 5)
    assert not np.any(s.labels[:, 20:240] == 5)


def test_overlays():
    rgb, truth = render_empty_room(9005, 256)
    s = estimate_surfaces(rgb)
    ov = label_overlay(rgb, s.labels, alpha=1.0, edges=False)
    assert ov.shape == rgb.shape and ov.dtype == np.uint8
    assert np.array_equal(ov[s.labels == 1][0], LABEL_COLORS[1])
    fig = surfaces_figure(rgb, s, truth)
    assert fig.shape[1] == 256 and fig.shape[0] > 5 * 128 and fig.dtype == np.uint8
    with pytest.raises(ValueError, match="label ids"):
        label_overlay(rgb, np.full((128, 256), 9))


@pytest.mark.skipif(not (SHARED / "data" / "real").is_dir(), reason="shared real panoramas absent")
def test_real_panoramas_layout_accuracy():
    import cv2
    import json

    from panogeom.rectify import estimate_rectification
    from panogeom.transform import rotate_pano

    accs = []
    for d in sorted((SHARED / "data" / "real").iterdir()):
        if not (d / "gt.json").is_file():
            continue
        gt = json.loads((d / "gt.json").read_text())
        pano = cv2.imread(str(d / gt["image"]["file"]), cv2.IMREAD_COLOR)[..., ::-1]
        if pano.shape[1] != 1024:
            pano = cv2.resize(pano, (1024, 512), interpolation=cv2.INTER_AREA)
        pano = np.ascontiguousarray(pano)
        rect = estimate_rectification(pano, "walls")
        s = estimate_surfaces(rect.apply(pano), rect.segments.rotated(rect.rotation))
        lay = s.labels_in_input(rect.rotation, "layout")
        assert np.array_equal(lay, rotate_pano(s.layout, rect.rotation.T, "nearest"))
        truth = render_room_labels(gt["room"]["floor"], gt["room"]["ceiling_z"], [0.0, 0.0],
                                   gt["camera_height_m"], 1024)
        three = np.array([0, 1, 2, 3, 3, 0])
        accs.append(np.mean(three[lay] == three[truth]))
    assert accs and np.mean(accs) > 0.8


def test_labels_go_back_into_the_input_geometry():
    from panogeom.rotation import rot_x

    W, H = 256, 128
    truth = render_room_labels(L_ROOM, 2.7, [0.0, 0.0], 1.5, W)
    s = fuse_surfaces(oracle_probs(truth, noise=0.0), empty_om(H, W))
    assert np.array_equal(s.labels_in_input(np.eye(3)), s.labels)
    R = rot_x(0.2)
    tilted = s.labels_in_input(R, "layout")
    from panogeom.transform import rotate_pano

    back = rotate_pano(tilted, R, "nearest")  # rectify the tilted labels again
    assert np.mean(back[10:-10] == s.layout[10:-10]) > 0.97
    with pytest.raises(ValueError, match="which"):
        s.labels_in_input(np.eye(3), "gc")
