"""Tests of layout.likelihood: silhouettes, observations, E_s and E_o."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from layout.labelmap import render_room_labels, room_boundaries
from layout.likelihood import (
    box_silhouettes,
    boxes_mask,
    observe_labels,
    orientation_likelihood,
    render_scene_labels,
    surface_energy,
    surface_likelihood,
    yaw_bin_energy,
)
from panogeom.coords import lonlat_to_ray, pixel_grid_rays
from panogeom.lines import LineSegments
from panogeom.project import world_box_to_pano

ROOM = np.array([[-2.0, -1.5], [3.0, -1.5], [3.0, 2.5], [-2.0, 2.5]])
L_ROOM = np.array([[-1.5, -1.5], [3.5, -1.5], [3.5, 1.0], [1.0, 1.0], [1.0, 3.0], [-1.5, 3.0]])
# objects inside ROOM, clear of the camera and of each other
CENTERS = np.array([[2.4, 0.3, 0.4], [0.8, 1.9, 0.45], [-1.3, -0.9, 0.5], [1.6, -1.1, 0.3]])
SIZES = np.array([[0.5, 1.2, 0.8], [0.6, 0.6, 0.9], [0.9, 1.0, 1.0], [0.4, 0.4, 0.6]])
YAWS = np.array([0.3, 1.0, 2.5, 4.0])


def brute_force_cover(centers, sizes, yaws, camera_height, width):
    """(N, H, W) bool: pixel-centre rays that hit each box (3D slab test per pixel)."""
    rays = pixel_grid_rays(width, width // 2)
    out = []
    for c, s, y in zip(np.atleast_2d(centers), np.atleast_2d(sizes), np.atleast_1d(yaws)):
        cs, sn = np.cos(y), np.sin(y)
        rot = np.array([[cs, sn, 0.0], [-sn, cs, 0.0], [0.0, 0.0, 1.0]])  # world -> box frame
        o = rot @ (np.array([0.0, 0.0, camera_height]) - c)
        d = rays @ rot.T
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-0.5 * s - o) / d
            t2 = (0.5 * s - o) / d
        t1 = np.where(np.isnan(t1), -np.inf, t1)
        t2 = np.where(np.isnan(t2), np.inf, t2)
        near = np.max(np.minimum(t1, t2), axis=-1)
        far = np.min(np.maximum(t1, t2), axis=-1)
        out.append((far >= np.maximum(near, 0.0)))
    return np.array(out)


def brute_force_es(obs_labels, in_box, per_box, pred_room, cover, mode):
    """E_s counted pixel by pixel on rasters (the definition, centre rule)."""
    surface = (obs_labels >= 1) & (obs_labels <= 4)
    clutter = (obs_labels == 0) | (obs_labels == 5)
    any_cover = cover.any(axis=0)
    valid = surface & ~in_box
    n_c = np.count_nonzero(valid & ~any_cover & (obs_labels == pred_room))
    n_pix = np.count_nonzero(valid)
    if mode == "matched":
        for k in range(len(per_box)):
            ev = per_box[k] & clutter
            n_pix += np.count_nonzero(ev)
            n_c += np.count_nonzero(ev & cover[k])
    return 1.0 - n_c / n_pix


def test_boxes_mask_scaling_and_seam():
    m = boxes_mask([[2000.0, 100.0, 48.0, 300.0], [500.0, 0.0, 600.0, 40.0]], 64, box_width=2048)
    assert m.shape == (32, 64)
    cols = np.flatnonzero(m[5])
    assert cols.tolist() == [0, 1, 62, 63]  # centres 0.5, 1.5, 62.5, 63.5: u >= 62.5 or u <= 1.5
    assert m[0, 17] and not m[1, 17] and not m[0, 15]  # second box: u in [15.6, 18.75], v <= 1.25
    assert not boxes_mask(None, 8).any() and not boxes_mask(np.zeros((0, 4)), 8).any()
    with pytest.raises(ValueError, match=r"boxes: expected finite \(K, 4\)"):
        boxes_mask([[1, 2, 3]], 8)


def _plane_box(lon0, lon1, lat0, lat1, tilt):
    """(4, 3) inward normals of the great circles through consecutive corners of a quadrilateral on the sphere:
    corners at (lon, lat) of panogeom's convention, the top and bottom edges tilted by ``tilt`` radians of latitude
    from one side to the other (the edges of a box in a turned or pitched pinhole view)."""
    corners = lonlat_to_ray(np.array([[lon0, lat0], [lon0, lat1], [lon1, lat1 + tilt], [lon1, lat0 + tilt]]))
    normals = LineSegments.from_endpoints(corners, np.roll(corners, -1, axis=0)).normals  # the edges' great circles
    centre = corners.sum(axis=0)
    return normals * np.where(normals @ centre < 0, -1.0, 1.0)[:, None]


def test_boxes_mask_with_the_planes_of_several_views_keeps_their_intersection():
    W = 128
    box = np.array([[40.0, 20.0, 90.0, 50.0]])
    a = _plane_box(-0.9, 0.5, -0.5, 0.3, 0.1)
    b = _plane_box(-0.3, 1.0, -0.2, 0.6, -0.15)
    ma, mb = boxes_mask(box, W, planes=[a]), boxes_mask(box, W, planes=[b])
    both = boxes_mask(box, W, planes=[np.stack([a, b])])
    assert ma.any() and mb.any() and (ma & ~mb).any() and (mb & ~ma).any()  # neither holds the other
    np.testing.assert_array_equal(both, ma & mb)
    assert both.sum() < min(ma.sum(), mb.sum()) and not (both & ~boxes_mask(box, W)).any()
    with pytest.raises(ValueError, match=r"planes\[0\]: expected a finite \(4, 3\) or \(V, 4, 3\)"):
        boxes_mask(box, W, planes=[np.zeros((3, 3))])
    with pytest.raises(ValueError, match=r"planes\[0\]"):
        boxes_mask(box, W, planes=[np.zeros((0, 4, 3))])


@settings(max_examples=25, deadline=None)
@given(st.floats(0.6, 4.0), st.floats(-np.pi, np.pi), st.floats(0, 2 * np.pi), st.floats(0.1, 2.0),
       st.floats(0.1, 2.0), st.floats(0.1, 2.2), st.floats(0.0, 1.0), st.floats(1.0, 2.0))
def test_silhouettes_equal_ray_casting(dist, az, yaw, l, w, h, elev, cam_h):
    """Every pixel centre inside [top_v, bottom_v] of its column is exactly a ray that hits the box."""
    c = np.array([dist * np.cos(az), dist * np.sin(az), elev + h / 2])
    size = np.array([l, w, h])
    sil = box_silhouettes(c[None], size[None], [yaw], cam_h, 128)
    top, bottom, hit = sil.dense()
    rows = np.arange(64)[:, None] + 0.5
    mine = hit[0][None, :] & (rows >= top[0][None, :]) & (rows <= bottom[0][None, :])
    ref = brute_force_cover(c, size, yaw, cam_h, 128)[0]
    cs, sn = np.cos(yaw), np.sin(yaw)
    margin = np.minimum(l / 2 - abs(-c[0] * cs - c[1] * sn), w / 2 - abs(c[0] * sn - c[1] * cs))
    if abs(margin) < 1e-6:  # the camera axis on the footprint's boundary: grazing everywhere
        return
    assert bool(sil.inside[0]) == (margin > 0)
    if sil.inside[0]:  # a box around the camera axis covers a pole (rays near it travel ~1 cm sideways)
        assert margin < 0.05 or ref[-1].all() or ref[0].all()
        return
    # rays that graze an edge may go either way: allow a few pixels out of 8192
    assert np.count_nonzero(mine != ref) <= 3


def test_silhouette_batch_broadcasting_matches_single():
    rng = np.random.default_rng(0)
    c = CENTERS[None] + rng.normal(0, 0.05, (5, 4, 3))
    y = YAWS[None] + rng.normal(0, 0.1, (5, 4))
    cam = np.array([1.4, 1.5, 1.6, 1.7, 1.8])
    batch = box_silhouettes(c, SIZES, y, cam, 64)
    assert batch.batch_shape == (5,) and batch.inside.shape == (5, 4)
    tb, bb, hb = batch.dense()
    for i in range(5):
        t1, b1, h1 = box_silhouettes(c[i], SIZES, y[i], cam[i], 64).dense()
        assert np.array_equal(h1, hb[i]) and np.allclose(t1, tb[i]) and np.allclose(b1, bb[i])


def test_render_scene_labels_room_part_and_raycaster():
    lab = render_scene_labels(L_ROOM, 2.6, 1.5, width=128)
    assert np.array_equal(lab, render_room_labels(L_ROOM, 2.6, [0, 0], 1.5, 128))
    from panogeom.raycast import RenderMesh, raycast_equirect, room_meshes
    from panogeom.project import world_box_corners

    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6], [0, 4, 5], [0, 5, 1], [1, 5, 6], [1, 6, 2],
                      [2, 6, 7], [2, 7, 3], [3, 7, 4], [3, 4, 0]])
    meshes = [room_meshes(ROOM, 2.6)] + [RenderMesh(world_box_corners(c, s, y), faces, labels=5)
                                        for c, s, y in zip(CENTERS, SIZES, YAWS)]
    ref = raycast_equirect(meshes, 256, [0.0, 0.0, 1.5]).labels
    mine = render_scene_labels(ROOM, 2.6, 1.5, CENTERS, SIZES, YAWS, width=256)
    assert np.count_nonzero(mine != ref) <= 10  # of 32768: float32 grazing rays in the ray caster


def test_observe_labels_resampling_and_tables():
    fine = render_room_labels(ROOM, 2.7, [0, 0], 1.6, 512)
    obs = observe_labels(fine, width=128)
    # majority vote in 4 x 4 blocks equals the room rendered at 128 almost everywhere
    coarse = render_room_labels(ROOM, 2.7, [0, 0], 1.6, 128)
    assert np.mean(obs.labels != coarse) < 0.02
    odd = observe_labels(fine, width=96)  # not an integer factor: nearest pixel centre
    assert odd.labels.shape == (48, 96) and set(np.unique(odd.labels)) <= {1, 2, 3, 4}
    assert obs.n_pix == 64 * 128 and obs.n_boxes == 0
    assert np.allclose(obs.cumulative[:, -1], obs.weights.sum(axis=1))
    with pytest.raises(ValueError, match="object_pixels: expected 'masked' or 'matched'"):
        observe_labels(fine, object_pixels="both")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="width: expected an even integer"):
        observe_labels(fine, width=127)


def scene_observation(mode, width=128, noise=0, centers=CENTERS, sizes=SIZES):
    """Observed labels of ROOM with the objects as clutter, their true boxes, optional label noise."""
    lab = render_scene_labels(ROOM, 2.6, 1.5, centers, sizes, YAWS, width=512, object_label=0)
    if noise:
        rng = np.random.default_rng(noise)
        flip = rng.random(lab.shape) < 0.05
        lab = np.where(flip, rng.integers(0, 6, lab.shape), lab).astype(np.uint8)
    boxes = np.array([world_box_to_pano(c, s, y, 512, 256, camera_height=1.5).extent
                      for c, s, y in zip(centers, sizes, YAWS)])
    return observe_labels(lab, boxes, width=width, object_pixels=mode), boxes


@pytest.mark.parametrize("mode", ["masked", "matched"])
@pytest.mark.parametrize("noise", [0, 3])
def test_surface_energy_equals_pixel_count(mode, noise):
    obs, boxes = scene_observation(mode, noise=noise)
    rng = np.random.default_rng(1)
    per_box = np.array([boxes_mask(b[None], 128, box_width=512) for b in boxes])
    b = room_boundaries(ROOM, 2.6, [0, 0], 1.5, 128)
    pred_room = render_room_labels(ROOM, 2.6, [0, 0], 1.5, 128)
    for _ in range(4):
        c = CENTERS + rng.normal(0, 0.15, CENTERS.shape) * [1, 1, 0]
        y = YAWS + rng.normal(0, 0.2, 4)
        sil = box_silhouettes(c, SIZES, y, 1.5, 128)
        e = surface_energy(obs, b, sil, coverage="centre")
        ref = brute_force_es(obs.labels, obs.box_mask, per_box, pred_room,
                             brute_force_cover(c, SIZES, y, 1.5, 128), mode)
        assert e.energy == pytest.approx(ref, abs=1e-12)
        area = surface_energy(obs, b, sil, coverage="area")
        assert abs(area.energy - e.energy) < 0.01  # fractions of boundary pixels only


def test_true_scene_has_no_error_and_full_object_coverage():
    obs, _ = scene_observation("matched", width=512)
    es = surface_likelihood(obs, ROOM, 2.6, 1.5, coverage="centre")
    e = es(CENTERS, SIZES, YAWS)
    assert e.energy == pytest.approx(0.0, abs=1e-12)
    assert np.allclose(e.object_coverage, 1.0)
    assert e.covered == pytest.approx(obs.box_evidence.sum() - 0.0, rel=0.05)  # boxes may overlap


def test_two_sided_penalty_only_when_matched():
    """Object 0 is exactly as tall as the camera height: pushed away, its silhouette shrinks inside its
    box (the top stays on the horizon), which costs nothing with the paper's masking and something when
    matched; pulled closer, it spills over the wall and floor around the box and costs in both."""
    centers, sizes = CENTERS.copy(), SIZES.copy()
    sizes[0, 2], centers[0, 2] = 1.5, 0.75
    out = {}
    for mode in ("masked", "matched"):
        obs, _ = scene_observation(mode, centers=centers, sizes=sizes)
        es = surface_likelihood(obs, ROOM, 2.6, 1.5)
        far, near = centers.copy(), centers.copy()
        far[0, :2] *= 1.15
        near[0, :2] *= 0.8
        out[mode] = es(np.stack([centers, far, near]), sizes, np.stack([YAWS] * 3)).energy
    assert out["masked"][1] <= out["masked"][0] + 1e-4  # no penalty (the area rule may even gain a little)
    assert out["masked"][2] > out["masked"][0] + 1e-3
    assert out["matched"][1] > out["matched"][0] + 1e-3 and out["matched"][2] > out["matched"][0] + 1e-3


def test_scale_changes_only_the_objects():
    """Scale lambda multiplies room AND camera height: same as the scaled room rendered directly."""
    obs, _ = scene_observation("masked")
    es = surface_likelihood(obs, ROOM, 2.6, 1.5)
    lam = np.array([0.9, 1.0, 1.2])
    e = es(np.broadcast_to(CENTERS, (3, 4, 3)), SIZES, np.broadcast_to(YAWS, (3, 4)), lam)
    for i, s in enumerate(lam):
        b = room_boundaries(ROOM * s, 2.6 * s, [0, 0], 1.5 * s, 128)
        ref = surface_energy(obs, b, box_silhouettes(CENTERS, SIZES, YAWS, 1.5 * s, 128))
        assert e.energy[i] == pytest.approx(ref.energy, abs=1e-12)
    assert e.energy[1] < e.energy[0] and e.energy[1] < e.energy[2]


def test_batched_rooms_and_single_silhouettes_broadcast():
    obs, _ = scene_observation("masked")
    b = room_boundaries(ROOM, 2.6, [0, 0], 1.5, 128, scale=[[1.0], [1.1]])  # (2, 1) room batch
    sil = box_silhouettes(np.stack([CENTERS, CENTERS * [1.05, 1.05, 1]]), SIZES, np.stack([YAWS, YAWS]), 1.5, 128)
    e = surface_energy(obs, b, sil)
    assert e.energy.shape == (2, 2)
    for i, s in enumerate([1.0, 1.1]):
        for j, f in enumerate([1.0, 1.05]):
            one = surface_energy(obs, room_boundaries(ROOM, 2.6, [0, 0], 1.5, 128, scale=s),
                                 box_silhouettes(CENTERS * [f, f, 1], SIZES, YAWS, 1.5, 128))
            assert e.energy[i, j] == pytest.approx(float(one.energy), abs=1e-12)


def test_batch_equals_loop_of_singles():
    obs, _ = scene_observation("matched")
    es = surface_likelihood(obs, ROOM, 2.6, 1.5)
    rng = np.random.default_rng(2)
    c = CENTERS[None] + rng.normal(0, 0.1, (30, 4, 3)) * [1, 1, 0]
    y = YAWS[None] + rng.normal(0, 0.1, (30, 4))
    lam = rng.uniform(0.9, 1.1, 30)
    batch = es(c, SIZES, y, lam).energy
    loop = np.array([es(c[i], SIZES, y[i], lam[i]).energy for i in range(30)])
    assert np.allclose(batch, loop, atol=1e-12)


def test_surface_energy_errors():
    obs, _ = scene_observation("matched")
    b = room_boundaries(ROOM, 2.6, [0, 0], 1.5, 128)
    with pytest.raises(ValueError, match="expected one object per detection box"):
        surface_energy(obs, b, box_silhouettes(CENTERS[:2], SIZES[:2], YAWS[:2], 1.5, 128))
    with pytest.raises(ValueError, match="boundaries: expected width 128"):
        surface_energy(obs, room_boundaries(ROOM, 2.6, [0, 0], 1.5, 64))
    with pytest.raises(ValueError, match="coverage: expected 'area' or 'centre'"):
        surface_energy(obs, b, coverage="pixel")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="expected 0 < camera_height < ceiling_z"):
        surface_likelihood(obs, ROOM, 1.4, 1.5)
    with pytest.raises(ValueError, match=r"sizes: expected shape \(4, 3\)"):
        box_silhouettes(CENTERS, SIZES[:3], YAWS, 1.5, 64)
    with pytest.raises(ValueError, match="camera_height: expected finite values > 0"):
        box_silhouettes(CENTERS, SIZES, YAWS, -1.0, 64)
    with pytest.raises(ValueError, match="scale: expected finite values > 0"):
        surface_likelihood(obs, ROOM, 2.6, 1.5)(CENTERS, SIZES, YAWS, 0.0)


def test_orientation_likelihood_forms():
    table = [0.0, 1.0, 4.0, 1.0]
    f = yaw_bin_energy(table)
    assert f(np.array([np.pi / 4, -np.pi / 4, 3 * np.pi])).tolist() == [0.5, 0.5, 4.0]
    eo = orientation_likelihood([table, lambda y: 2.0 * np.ones_like(y), None], ["bed", "tv", "plant"])
    yaws = np.array([[0.0, 0.3, 1.0], [np.pi, 0.0, 2.0]])
    assert eo.per_object(yaws).tolist() == [[0.0, 2.0, 0.0], [4.0, 2.0, 0.0]]
    assert eo(yaws).tolist() == [2.0, 6.0]
    by_class = orientation_likelihood(lambda cls, y: np.full(y.shape, len(cls), float), ["bed", "chair"])
    assert by_class(np.zeros((3, 2))).tolist() == [8.0, 8.0, 8.0]
    assert orientation_likelihood(None, ["bed"])(np.zeros((2, 1))).tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match=r"E_o: expected one term per object \(2\), got 1"):
        orientation_likelihood([table], ["bed", "tv"])
    with pytest.raises(ValueError, match=r"energies: expected a finite \(K,\) table"):
        yaw_bin_energy([1.0])
    bad = orientation_likelihood([lambda y: np.zeros(3)], ["bed"])
    with pytest.raises(ValueError, match="E_o of object 0: expected finite energies of shape"):
        bad(np.zeros((2, 1)))


def test_box_planes_restrict_a_box_to_the_region_they_bound():
    """A panorama box with the great circles of a pitched tile's box: only pixels inside all four planes are the
    box's (its object evidence when matched); without planes the whole box is."""
    from panogeom.coords import pixel_to_ray

    lab = render_scene_labels(ROOM, 2.6, 1.5, CENTERS, SIZES, YAWS, width=512, object_label=0)
    box = np.array([[100.0, 150.0, 180.0, 220.0]])
    whole = observe_labels(lab, box, width=128, object_pixels="matched")
    # planes through the camera and the box's four corner-to-corner great circles, tilted inwards: a diamond
    c = pixel_to_ray(np.array([[140.0, 185.0]]), 512, 256)[0]
    corners = pixel_to_ray(np.array([[140.0, 150.0], [180.0, 185.0], [140.0, 220.0], [100.0, 185.0]]), 512, 256)
    n = np.cross(corners, np.roll(corners, -1, axis=0))
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    n = n * np.where(n @ c < 0, -1.0, 1.0)[:, None]
    part = observe_labels(lab, box, width=128, object_pixels="matched", box_planes=[n])
    assert part.box_mask.sum() < 0.75 * whole.box_mask.sum() and part.box_mask.sum() > 0.3 * whole.box_mask.sum()
    assert np.all(whole.box_mask[part.box_mask])
    assert observe_labels(lab, box, width=128, box_planes=[None]).box_mask.sum() == whole.box_mask.sum()
    with pytest.raises(ValueError, match="one \\(4, 3\\) array or None per box"):
        observe_labels(lab, box, width=128, box_planes=[n, n])
    with pytest.raises(ValueError, match="planes\\[0\\]"):
        observe_labels(lab, box, width=128, box_planes=[n[:3]])
