"""Tests of panogeom.raycast: scene meshes, equirect ray casting, backends."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.path import Path

from panogeom.coords import pixel_grid_rays, ray_to_pixel, world_to_pixel
from panogeom.raycast import (LABEL_CEILING, LABEL_FLOOR, LABEL_OBJECT, LABEL_WALL_X, LABEL_WALL_Y, RayCaster,
                              RenderMesh, merge_meshes, pose_matrix, raycast_equirect, room_meshes,
                              transform_mesh, triangulate_polygon)
from panogeom.rotation import axis_angle_to_matrix
from panogeom.texture import Material

HAS_O3D = importlib.util.find_spec("open3d") is not None
HAS_IGL = importlib.util.find_spec("igl") is not None

# Box room [X0, X1] x [Y0, Y1] x [0, CZ], camera off-centre.
X0, X1, Y0, Y1, CZ = -2.1, 3.3, -1.7, 2.4, 2.75
BOX = [[X0, Y0], [X1, Y0], [X1, Y1], [X0, Y1]]
CAM_H = 1.6


def box_mesh(size, instance_id=1, label=LABEL_OBJECT) -> RenderMesh:
    """Axis-aligned box with its base centred at the origin (model canonical frame), outward normals."""
    hx, hy = size[0] / 2, size[1] / 2
    v = np.array([[x, y, z] for z in (0.0, size[2]) for y in (-hy, hy) for x in (-hx, hx)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    f = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return RenderMesh(v, f, labels=label, instance_ids=instance_id, material_ids=Material.FABRIC, colors=(200, 50, 50))


def analytic_box(rays: np.ndarray, cam: np.ndarray):
    """Depth and label of the first hit of rays from inside the box room (convex: nearest exit plane)."""
    planes = [(0, X0, LABEL_WALL_X), (0, X1, LABEL_WALL_X), (1, Y0, LABEL_WALL_Y), (1, Y1, LABEL_WALL_Y),
              (2, 0.0, LABEL_FLOOR), (2, CZ, LABEL_CEILING)]
    ts = []
    for axis, off, _ in planes:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (off - cam[axis]) / rays[..., axis]
        ts.append(np.where(t > 0, t, np.inf))
    ts = np.stack(ts, axis=-1)
    order = np.sort(ts, axis=-1)
    labels = np.array([p[2] for p in planes])[np.argmin(ts, axis=-1)]
    ambiguous = order[..., 1] - order[..., 0] < 1e-3 * order[..., 0]
    return order[..., 0], labels, ambiguous


# ----------------------------------------------------------------------------- room meshes


def test_room_meshes_box_labels_normals_and_materials():
    room = room_meshes(BOX, CZ, floor_material=Material.TILE, wall_color=(10, 20, 30))
    n = room.face_normals()
    assert room.n_faces == 2 + 2 + 8
    np.testing.assert_allclose(n[room.labels == LABEL_FLOOR], [[0, 0, 1]] * 2)
    np.testing.assert_allclose(n[room.labels == LABEL_CEILING], [[0, 0, -1]] * 2)
    assert np.all(np.abs(n[room.labels == LABEL_WALL_X][:, 0]) == 1)
    assert np.all(np.abs(n[room.labels == LABEL_WALL_Y][:, 1]) == 1)
    # Wall normals point into the room: the centroid nudged along the normal is inside the box.
    walls = np.isin(room.labels, [LABEL_WALL_X, LABEL_WALL_Y])
    c = room.vertices[room.faces[walls]].mean(axis=1) + 0.01 * n[walls]
    assert np.all((c[:, 0] > X0) & (c[:, 0] < X1) & (c[:, 1] > Y0) & (c[:, 1] < Y1))
    assert set(room.material_ids[room.labels == LABEL_FLOOR]) == {Material.TILE}
    assert set(room.instance_ids) == {0}
    np.testing.assert_allclose(room.colors[walls], np.tile(np.array([10, 20, 30]) / 255, (8, 1)), atol=1e-6)


@st.composite
def manhattan_polygons(draw):
    """Simple rectilinear polygons: the outline of a 'skyline' of columns, rotated by a multiple of 90 degrees."""
    k = draw(st.integers(1, 6))
    widths = draw(st.lists(st.floats(0.3, 3.0), min_size=k, max_size=k))
    heights = draw(st.lists(st.sampled_from([0.5, 1.0, 1.7, 2.2, 3.0, 4.1]), min_size=k, max_size=k))
    xs = np.concatenate([[0.0], np.cumsum(widths)])
    pts = [(0.0, 0.0), (xs[-1], 0.0)]
    for i in range(k - 1, -1, -1):
        pts += [(xs[i + 1], heights[i]), (xs[i], heights[i])]
    p = np.array(pts)
    # Drop vertices where the outline goes straight on (equal neighbouring heights).
    keep = []
    for i in range(len(p)):
        a, b, c = p[i - 1], p[i], p[(i + 1) % len(p)]
        if abs((b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])) > 1e-12:
            keep.append(i)
    p = p[keep]
    turns = draw(st.integers(0, 3))
    R = np.array([[0.0, -1.0], [1.0, 0.0]])
    for _ in range(turns):
        p = p @ R.T
    return p + draw(st.tuples(st.floats(-5, 5), st.floats(-5, 5)))


@settings(max_examples=60, deadline=None)
@given(manhattan_polygons())
def test_triangulation_covers_manhattan_polygons(poly):
    tris = triangulate_polygon(poly)
    assert tris.shape == (len(poly) - 2, 3)
    a, b, c = poly[tris[:, 0]], poly[tris[:, 1]], poly[tris[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    assert np.all(cross > 0)  # counter-clockwise, non-degenerate
    area = 0.5 * np.sum(poly[:, 0] * np.roll(poly[:, 1], -1) - np.roll(poly[:, 0], -1) * poly[:, 1])
    np.testing.assert_allclose(cross.sum() / 2, area, rtol=1e-9)
    # Every triangle lies inside the polygon (its centroid does; with the area equality, no overlap).
    assert np.all(Path(poly).contains_points((a + b + c) / 3))


@settings(max_examples=30, deadline=None)
@given(manhattan_polygons())
def test_room_meshes_walls_point_inwards_for_any_manhattan_polygon(poly):
    room = room_meshes(poly, 2.5)
    n = room.face_normals()
    walls = np.isin(room.labels, [LABEL_WALL_X, LABEL_WALL_Y])
    assert walls.sum() == 2 * len(poly)
    c = room.vertices[room.faces[walls]].mean(axis=1)
    assert np.all(Path(poly).contains_points(c[:, :2] + 1e-3 * n[walls][:, :2]))
    assert np.all(np.abs(n[room.labels == LABEL_WALL_X][:, 0]) > 0.999)
    assert np.all(np.abs(n[room.labels == LABEL_WALL_Y][:, 1]) > 0.999)


@pytest.mark.parametrize("poly, match", [
    ([[0, 0], [2, 0], [2, 2], [1, 3], [0, 2]], "even number"),
    ([[0, 0], [2, 0], [3, 2], [0, 2]], "axis-aligned"),
    ([[0, 0], [0, 2], [2, 2], [2, 0]], "counter-clockwise"),
    ([[0, 0], [2, 0], [2, 2], [0, 2], [0, 2], [0, 0]], "zero length"),
    ([[0, 0], [1, 0], [2, 0], [2, 2], [0, 2], [0, 1]], "orthogonal"),
    # Manhattan but self-intersecting (a figure-of-eight of two rectangles).
    ([[0, 0], [2, 0], [2, 1], [1, 1], [1, -1], [3, -1], [3, 2], [0, 2]], "simple"),
    ([[0, 0], [2, 0], [2, np.nan], [0, 2]], "finite"),
    ([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "shape"),
])
def test_room_meshes_rejects_bad_polygons(poly, match):
    with pytest.raises(ValueError, match=match):
        room_meshes(poly, 2.5)


def test_room_meshes_rejects_bad_heights():
    with pytest.raises(ValueError, match="ceiling_z > floor_z"):
        room_meshes(BOX, 0.0, floor_z=0.0)


# ----------------------------------------------------------------------------- meshes


def test_render_mesh_validation():
    v = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    with pytest.raises(ValueError, match="at least one triangle"):
        RenderMesh(v, np.zeros((0, 3), int))
    with pytest.raises(ValueError, match="finite"):
        RenderMesh([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    with pytest.raises(ValueError, match=r"indices in \[0, 3\)"):
        RenderMesh(v, [[0, 1, 3]])
    with pytest.raises(ValueError, match="labels: expected values <= 5"):
        RenderMesh(v, [[0, 1, 2]], labels=6)
    with pytest.raises(ValueError, match="one per face"):
        RenderMesh(v, [[0, 1, 2]], instance_ids=[1, 2])
    with pytest.raises(ValueError, match="colors"):
        RenderMesh(v, [[0, 1, 2]], colors=(300, 0, 0))
    m = RenderMesh(v, [[0, 1, 2]], colors=(255, 0, 0))
    np.testing.assert_allclose(m.colors, [[1, 0, 0]])
    with pytest.raises(ValueError):
        m.vertices[0, 0] = 5.0  # read-only


def test_merge_and_transform():
    a = box_mesh((1, 1, 1), instance_id=1)
    b = box_mesh((1, 1, 1), instance_id=2)
    m = merge_meshes([a, b])
    assert m.n_faces == 24 and m.faces.max() == 15
    np.testing.assert_array_equal(m.instance_ids, [1] * 12 + [2] * 12)
    with pytest.raises(ValueError, match="at least one"):
        merge_meshes([])
    T = pose_matrix(np.pi / 2, [1.0, 2.0, 0.0])
    moved = transform_mesh(a, T)
    np.testing.assert_allclose(moved.vertices, a.vertices @ T[:3, :3].T + [1, 2, 0])
    np.testing.assert_allclose(moved.face_normals(), a.face_normals() @ T[:3, :3].T, atol=1e-12)
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0])
    flipped = transform_mesh(a, mirror)
    # Outward normals stay outward after mirroring (winding reversed).
    c = flipped.vertices[flipped.faces].mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", flipped.face_normals(), c - [0, 0, 0.5]) > 0)
    with pytest.raises(ValueError, match="last row"):
        transform_mesh(a, np.ones((4, 4)))


def test_ray_caster_distance_in_direction_units():
    room = room_meshes(BOX, CZ)
    hits = RayCaster(room).cast([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], [[0.0, 0.0, -2.0], [X1 * 2, 0.0, 0.0]])
    np.testing.assert_allclose(hits.t, [0.5, 0.5], rtol=1e-6)
    assert room.labels[hits.face_ids].tolist() == [LABEL_FLOOR, LABEL_WALL_X]
    with pytest.raises(ValueError, match="non-zero"):
        RayCaster(room).cast([0, 0, 1], [[0.0, 0.0, 0.0]])


# ----------------------------------------------------------------------------- equirect render


@pytest.fixture(scope="module")
def box_render():
    room = room_meshes(BOX, CZ)
    return raycast_equirect(room, 512, [0.0, 0.0, CAM_H])


def test_floor_wall_boundary_matches_world_to_pixel(box_render):
    r = box_render
    H, W = r.labels.shape
    # Horizontal ray of each column centre, its wall hit at floor and ceiling height.
    horiz = pixel_grid_rays(W, H)[H // 2].copy()
    horiz[:, 2] = 0.0
    horiz /= np.linalg.norm(horiz, axis=1, keepdims=True)
    with np.errstate(divide="ignore"):
        t = np.min(np.stack([np.where(horiz[:, 0] > 0, X1, X0) / np.abs(horiz[:, 0]) * np.sign(horiz[:, 0]),
                             np.where(horiz[:, 1] > 0, Y1, Y0) / np.abs(horiz[:, 1]) * np.sign(horiz[:, 1])]),
                   axis=0)
    base = np.column_stack([t * horiz[:, 0], t * horiz[:, 1], np.zeros(W)])
    top = base + [0.0, 0.0, CZ]
    v_floor = world_to_pixel(base, W, H, camera_height=CAM_H)[:, 1]
    v_ceil = world_to_pixel(top, W, H, camera_height=CAM_H)[:, 1]
    first_floor = np.argmax(r.labels == LABEL_FLOOR, axis=0)
    last_ceiling = H - 1 - np.argmax((r.labels == LABEL_CEILING)[::-1], axis=0)
    assert np.abs(first_floor + 0.5 - v_floor).max() <= 1.0
    assert np.abs(last_ceiling + 0.5 - v_ceil).max() <= 1.0


def test_depth_and_labels_equal_analytic_planes(box_render):
    r = box_render
    cam = np.array([0.0, 0.0, CAM_H])
    depth, labels, ambiguous = analytic_box(r.rays.astype(np.float64), cam)
    assert r.hit.all()
    np.testing.assert_allclose(r.depth, depth, rtol=2e-5)
    assert np.mean(r.labels[~ambiguous] == labels[~ambiguous]) == 1.0
    assert ambiguous.mean() < 0.01
    # Hit points lie along the rays at the depth; normals face the camera.
    np.testing.assert_allclose(r.points, cam + r.depth[..., None] * r.rays, atol=1e-4)
    assert np.all(np.einsum("hwc,hwc->hw", r.normals, r.rays) <= 1e-6)
    assert set(np.unique(r.instance_ids)) == {0}
    np.testing.assert_array_equal(r.rays, pixel_grid_rays(512, 256).astype(np.float32))


def test_rotation_maps_camera_rays_into_world():
    room = room_meshes(BOX, CZ)
    R = axis_angle_to_matrix([0.1, -0.2, 0.9])
    cam = np.array([0.4, -0.3, 1.2])
    r = raycast_equirect(room, 256, cam, rotation=R)
    np.testing.assert_allclose(r.rays, pixel_grid_rays(256, 128) @ R.T, atol=1e-6)
    depth, labels, ambiguous = analytic_box(r.rays.astype(np.float64), cam)
    np.testing.assert_allclose(r.depth, depth, rtol=2e-5)
    assert np.all(r.labels[~ambiguous] == labels[~ambiguous])
    # A world point projects (world_to_pixel with the same rotation) onto the pixel whose hit it is.
    base = np.array([X1, 0.5, 0.0])
    uv = world_to_pixel(base - [cam[0], cam[1], 0.0], 256, 128, camera_height=cam[2], rotation=R)
    i, j = int(uv[1]), int(uv[0])
    near = r.points[max(i - 1, 0):i + 2, max(j - 1, 0):j + 2].reshape(-1, 3)
    assert np.linalg.norm(near - base, axis=1).min() < 0.1


def test_instance_ids_on_placed_box():
    room = room_meshes(BOX, CZ)
    size, yaw, pos = (0.8, 0.6, 1.0), np.radians(30), np.array([2.0, 0.5, 0.0])
    T = pose_matrix(yaw, pos)
    obj = transform_mesh(box_mesh(size, instance_id=7), T)
    cam = np.array([0.0, 0.0, CAM_H])
    r = raycast_equirect([room, obj], 512, cam)
    mask = r.instance_ids == 7
    assert mask.sum() > 500
    assert np.all(r.labels[mask] == LABEL_OBJECT)
    assert np.all(r.material_ids[mask] == Material.FABRIC)
    # Pixel towards the box centre sees the box.
    u, v = ray_to_pixel(pos + [0, 0, 0.5] - cam, 512, 256)
    assert r.instance_ids[int(v), int(u)] == 7
    # Hit points of the box pixels lie on its surface (local frame, within the half extents).
    local = (r.points[mask] - pos) @ T[:3, :3]
    half = np.array([size[0] / 2, size[1] / 2])
    assert np.all(np.abs(local[:, :2]) <= half + 1e-4) and np.all((local[:, 2] >= -1e-4) & (local[:, 2] <= 1.0001))
    # Analytic slab test in the box frame: rays that enter the box are exactly the box pixels (bar silhouettes).
    o = (cam - pos) @ T[:3, :3]
    d = r.rays.astype(np.float64) @ T[:3, :3]
    lo, hi = np.array([-half[0], -half[1], 0.0]), np.array([half[0], half[1], size[2]])
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (lo - o) / d, (hi - o) / d
    tin = np.nanmax(np.minimum(t1, t2), axis=-1)
    tout = np.nanmin(np.maximum(t1, t2), axis=-1)
    inside = (tin <= tout) & (tout > 0)
    assert np.mean(inside != mask) < 1e-3
    np.testing.assert_allclose(r.depth[mask & inside], np.maximum(tin, 0)[mask & inside], rtol=1e-4)


def test_l_shaped_room_is_watertight_and_camera_outside_is_allowed():
    poly = [[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]]
    room = room_meshes(poly, 2.6)
    r = raycast_equirect(room, 512, [1.0, 1.0, 1.5])
    assert r.hit.all() and set(np.unique(r.labels)) == {1, 2, 3, 4}
    out = raycast_equirect(room, 128, [6.0, 6.0, 1.5])  # outside, in the notch's far corner
    miss = ~out.hit
    assert miss.any() and out.hit.any()
    assert np.all(np.isinf(out.depth[miss])) and np.all(np.isnan(out.points[miss]))
    assert np.all(out.labels[miss] == 0) and np.all(out.instance_ids[miss] == -1)
    assert np.all(out.face_ids[miss] == -1) and np.all(out.material_ids[miss] == -1)


@pytest.mark.parametrize("kwargs, match", [
    (dict(camera_position=[0.0, 0.0, 0.0]), "on face"),            # on the floor
    (dict(camera_position=[X1, 0.3, 1.0]), "on face"),             # on a wall
    (dict(camera_position=[0.0, np.nan, 1.0]), "finite"),
    (dict(camera_position=[0.0, 1.0]), r"shape \(3,\)"),
    (dict(width=513), "even"),
    (dict(width=0), "even"),
    (dict(rotation=np.diag([1.0, 1.0, -1.0])), "reflection"),
    (dict(rotation=np.ones((3, 3))), "orthonormal"),
    (dict(backend="optix"), "backend"),
])
def test_raycast_equirect_rejects_bad_input(kwargs, match):
    args = dict(meshes=room_meshes(BOX, CZ), width=64, camera_position=[0.0, 0.0, CAM_H])
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        raycast_equirect(**args)


def test_raycast_equirect_rejects_empty_scene():
    with pytest.raises(ValueError, match="at least one"):
        raycast_equirect([], 64, [0.0, 0.0, 1.0])


@pytest.mark.skipif(not (HAS_O3D and HAS_IGL), reason="needs both open3d and libigl")
def test_backends_agree():
    room = room_meshes([[0, 0], [4, 0], [4, 2], [2, 2], [2, 4], [0, 4]], 2.6)
    rng = np.random.default_rng(5)
    objs = [transform_mesh(box_mesh(rng.uniform(0.3, 1.0, 3), instance_id=k + 1),
                           pose_matrix(rng.uniform(0, 2 * np.pi), [rng.uniform(0.5, 3.5), rng.uniform(0.5, 1.5), 0]))
            for k in range(4)]
    rot = axis_angle_to_matrix([0.05, 0.02, 0.3])
    a = raycast_equirect([room, *objs], 256, [1.2, 1.1, 1.4], rotation=rot, backend="open3d")
    b = raycast_equirect([room, *objs], 256, [1.2, 1.1, 1.4], rotation=rot, backend="embree")
    assert (a.backend, b.backend) == ("open3d", "embree")
    same = a.face_ids == b.face_ids
    assert same.mean() > 0.999
    assert np.mean(a.labels == b.labels) > 0.999 and np.mean(a.instance_ids == b.instance_ids) > 0.999
    np.testing.assert_allclose(a.depth[same], b.depth[same], rtol=1e-5)
    np.testing.assert_allclose(a.barycentric[same], b.barycentric[same], atol=1e-4)
