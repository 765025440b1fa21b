"""Textured Manhattan box rooms rendered as equirectangular panoramas (test helper).

A room is an axis-aligned box in the world frame of CONVENTIONS.md (z up,
floor at z = 0) with the camera at ``(0, 0, camera_height)``, off the room's
centre. Walls, floor and ceiling carry textures with strong axis-aligned
edges (tiles, skirting, doors, panels, pictures, ceiling lights) plus a few
rotated rectangles as non-Manhattan clutter. A panorama is rendered per
pixel by intersecting each pixel ray with the box; a tilted panorama is the
same scene seen by a rotated camera.

Convention: ``R`` maps input-camera-frame directions into the world frame
(scene.json's ``camera.rotation``): the ray of input pixel ``d`` hits the
scene along ``R @ d``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from panogeom.coords import pixel_grid_rays
from panogeom.rotation import rot_x, rot_y, rot_z

PPM = 200.0  # texture pixels per metre


@dataclass(frozen=True)
class Room:
    lo: np.ndarray  # (3,) min corner (x0, y0, 0)
    hi: np.ndarray  # (3,) max corner (x1, y1, ceiling)
    camera: np.ndarray  # (3,) camera centre
    textures: dict  # (axis, side) -> (image (h, w, 3) uint8, (s_axis, t_axis))


def _shade(rng, base, spread=25):
    return tuple(int(np.clip(c + rng.integers(-spread, spread + 1), 0, 255)) for c in base)


def _rect(img, rng, s0, t0, s1, t1, color, size_t):
    """Filled axis-aligned rectangle in metres; texture row 0 is the top (t = size_t)."""
    p0 = (int(round(s0 * PPM)), int(round((size_t - t1) * PPM)))
    p1 = (int(round(s1 * PPM)), int(round((size_t - t0) * PPM)))
    cv2.rectangle(img, p0, p1, color, -1)


def _clutter(img, rng, n):
    h, w = img.shape[:2]
    for _ in range(n):
        c = rng.uniform([0.1 * w, 0.1 * h], [0.9 * w, 0.9 * h])
        ang = rng.uniform(np.deg2rad(15), np.deg2rad(75))
        sz = rng.uniform(0.15, 0.5, size=2) * PPM
        box = cv2.boxPoints(((float(c[0]), float(c[1])), (float(sz[0]), float(sz[1])), float(np.rad2deg(ang))))
        cv2.fillPoly(img, [np.round(box).astype(np.int32)], _shade(rng, (120, 110, 100), 80))


def _wall_texture(rng, length, height, base):
    img = np.empty((int(np.ceil(height * PPM)), int(np.ceil(length * PPM)), 3), np.uint8)
    img[:] = base
    # horizontal panel lines / dado rail
    for z in rng.uniform(0.8, 1.3, size=rng.integers(1, 3)):
        _rect(img, rng, 0, z, length, z + 0.03, _shade(rng, (90, 80, 70)), height)
    _rect(img, rng, 0, 0, length, 0.1, _shade(rng, (60, 50, 45)), height)  # skirting
    _rect(img, rng, 0, height - 0.08, length, height, _shade(rng, (235, 235, 230), 10), height)  # cornice
    # doors, cupboards, pictures, windows
    for _ in range(rng.integers(3, 7)):
        kind = rng.integers(3)
        if kind == 0:
            w, h, z0 = rng.uniform(0.7, 1.0), rng.uniform(1.9, 2.2), 0.0
        elif kind == 1:
            w, h, z0 = rng.uniform(0.3, 1.2), rng.uniform(0.3, 0.9), rng.uniform(1.0, 1.6)
        else:
            w, h, z0 = rng.uniform(0.2, 0.6), rng.uniform(0.3, 1.2), rng.uniform(0.2, 1.0)
        s0 = rng.uniform(0.05, max(0.06, length - w - 0.05))
        h = min(h, height - z0 - 0.1)
        _rect(img, rng, s0 - 0.04, z0, s0 + w + 0.04, z0 + h + 0.04, _shade(rng, (70, 60, 50), 30), height)
        _rect(img, rng, s0, z0, s0 + w, z0 + h, _shade(rng, (200, 190, 170), 50), height)
        if kind == 1:  # window bars
            _rect(img, rng, s0 + w / 2 - 0.015, z0, s0 + w / 2 + 0.015, z0 + h, (80, 80, 80), height)
    _clutter(img, rng, rng.integers(1, 4))
    return img


def _floor_texture(rng, lx, ly, base, tile):
    img = np.empty((int(np.ceil(ly * PPM)), int(np.ceil(lx * PPM)), 3), np.uint8)
    img[:] = tuple(int(c) // 3 for c in base)  # dark grout
    for x in np.arange(0.0, lx, tile):
        for y in np.arange(0.0, ly, tile):
            _rect(img, rng, x + 0.015, y + 0.015, x + tile - 0.015, y + tile - 0.015, _shade(rng, base, 25), ly)
    _clutter(img, rng, rng.integers(1, 3))
    return img


def _ceiling_texture(rng, lx, ly, base):
    img = np.empty((int(np.ceil(ly * PPM)), int(np.ceil(lx * PPM)), 3), np.uint8)
    img[:] = base
    for _ in range(rng.integers(2, 5)):
        w, h = rng.uniform(0.3, 1.2, size=2)
        x, y = rng.uniform(0.2, lx - w - 0.2), rng.uniform(0.2, ly - h - 0.2)
        _rect(img, rng, x, y, x + w, y + h, _shade(rng, (250, 250, 240), 5), ly)
    return img


def make_room(seed: int) -> Room:
    """A random box room with the camera off-centre."""
    rng = np.random.default_rng(seed)
    x0, y0 = -rng.uniform(1.2, 3.0, size=2)
    x1, y1 = rng.uniform(1.2, 3.0, size=2)
    zc = rng.uniform(2.5, 3.0)
    lo, hi = np.array([x0, y0, 0.0]), np.array([x1, y1, zc])
    cam = np.array([0.0, 0.0, rng.uniform(1.3, 1.7)])
    walls = [_shade(rng, (190, 175, 160), 40) for _ in range(4)]
    tex = {
        (0, 0): (_wall_texture(rng, y1 - y0, zc, walls[0]), (1, 2)),
        (0, 1): (_wall_texture(rng, y1 - y0, zc, walls[1]), (1, 2)),
        (1, 0): (_wall_texture(rng, x1 - x0, zc, walls[2]), (0, 2)),
        (1, 1): (_wall_texture(rng, x1 - x0, zc, walls[3]), (0, 2)),
        (2, 0): (_floor_texture(rng, x1 - x0, y1 - y0, _shade(rng, (140, 120, 100), 30), rng.uniform(0.3, 0.6)),
                 (0, 1)),
        (2, 1): (_ceiling_texture(rng, x1 - x0, y1 - y0, _shade(rng, (225, 225, 220), 10)), (0, 1)),
    }
    return Room(lo, hi, cam, tex)


def render_room(room: Room, R: np.ndarray, width: int = 1024, supersample: int = 2) -> np.ndarray:
    """(width/2, width, 3) uint8 panorama of ``room`` seen by a camera with rotation ``R``."""
    sw, sh = width * supersample, width * supersample // 2
    d = pixel_grid_rays(sw, sh).reshape(-1, 3) @ np.asarray(R).T
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = np.where(d > 0, room.hi, room.lo)
        t = (bound - room.camera) / d
    t[~np.isfinite(t) | (t <= 0)] = np.inf
    axis = np.argmin(t, axis=1)
    tmin = t[np.arange(len(t)), axis]
    hit = room.camera + tmin[:, None] * d
    side = (d[np.arange(len(d)), axis] > 0).astype(int)
    out = np.zeros((len(d), 3), np.uint8)
    for (ax, sd), (img, (sa, ta)) in room.textures.items():
        m = (axis == ax) & (side == sd)
        if not m.any():
            continue
        s = (hit[m, sa] - room.lo[sa]) * PPM - 0.5
        tt = (room.hi[ta] - hit[m, ta]) * PPM - 0.5
        n = len(s)
        cols = 4096
        pad = (-n) % cols
        ms = np.pad(s, (0, pad)).astype(np.float32).reshape(-1, cols)
        mt = np.pad(tt, (0, pad)).astype(np.float32).reshape(-1, cols)
        vals = cv2.remap(img, ms, mt, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        out[m] = vals.reshape(-1, 3)[:n]
    big = out.reshape(sh, sw, 3)
    return cv2.resize(big, (width, width // 2), interpolation=cv2.INTER_AREA)


def random_rotation(rng: np.random.Generator, max_tilt_deg: float = 15.0) -> np.ndarray:
    """Any yaw, roll and pitch each uniform in [-max_tilt_deg, max_tilt_deg]."""
    yaw = rng.uniform(-np.pi, np.pi)
    pitch, roll = np.deg2rad(rng.uniform(-max_tilt_deg, max_tilt_deg, size=2))
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
