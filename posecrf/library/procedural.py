"""Procedural furniture: the built-in stand-ins for the paper's 3D Warehouse set.

The paper (Sec. 4, implementation details) renders 9 beds, 16 chairs, 6 TVs
and 4 plants from 3D Warehouse. We cannot ship those, so each model here is a
small parameter record (`BedSpec`, `ChairSpec`, ...) turned into coloured
primitives (boxes, cylinders, capsules, cones, ellipsoids, surfaces of
revolution) by a builder. The variants differ in visible structure (headboard
shape and height, footboards, legs versus box base, arm rests, swivel bases,
screen sizes and mounts, pot shapes and foliage), not only in colour.

Everything is deterministic: the only randomness (leaf placement of plants)
uses an explicit seed stored in the spec.

Convention:
    Canonical model frame: metres, z up, base centred at the origin
    (bbox centre x = y = 0, min z = 0), front facing +x: bed foot end at +x
    and headboard at -x, chair and sofa seat opening at +x with the backrest
    at -x, TV screen facing +x, nightstand drawers and wardrobe doors on the
    +x side. Angles in radians (`_deg` fields are degrees).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .model import Model3D, Symmetry
from .parts import (
    RGB,
    Part,
    assemble_model,
    box,
    box_between,
    capsule,
    cone,
    cylinder,
    ellipsoid,
    quad,
    revolved,
    rot_y,
    rot_z,
    rotated_about,
    sphere,
)

# --------------------------------------------------------------------------- palette

OAK: RGB = (182, 138, 88)
WALNUT: RGB = (104, 70, 44)
CHERRY: RGB = (138, 64, 42)
BIRCH: RGB = (214, 186, 140)
WHITE_PAINT: RGB = (232, 230, 224)
BLACK_WOOD: RGB = (44, 42, 40)
GREY_FABRIC: RGB = (128, 130, 136)
CHARCOAL: RGB = (70, 70, 76)
BLUE_FABRIC: RGB = (62, 92, 142)
BEIGE: RGB = (204, 188, 160)
GREEN_FABRIC: RGB = (76, 112, 80)
RED_FABRIC: RGB = (150, 52, 50)
TEAL: RGB = (40, 122, 128)
MUSTARD: RGB = (206, 160, 58)
BROWN_LEATHER: RGB = (110, 64, 38)
CREAM: RGB = (238, 232, 216)
LINEN: RGB = (246, 246, 242)
PILLOW: RGB = (252, 252, 248)
STEEL: RGB = (172, 174, 180)
CHROME: RGB = (205, 207, 212)
DARK_METAL: RGB = (58, 60, 64)
BLACK_PLASTIC: RGB = (26, 26, 30)
GREY_PLASTIC: RGB = (96, 98, 104)
WHITE_PLASTIC: RGB = (236, 236, 232)
SCREEN: RGB = (18, 24, 40)
TERRACOTTA: RGB = (188, 96, 62)
WHITE_CERAMIC: RGB = (236, 236, 230)
SLATE: RGB = (74, 76, 82)
SOIL: RGB = (72, 52, 36)
LEAF_A: RGB = (62, 132, 62)
LEAF_B: RGB = (40, 100, 52)
LEAF_C: RGB = (96, 152, 70)
TRUNK: RGB = (96, 70, 48)
MIRROR: RGB = (196, 210, 220)


def _inch(diag_in: float) -> tuple[float, float]:
    """Width and height (m) of a 16:9 screen of diagonal `diag_in` inches."""
    d = diag_in * 0.0254
    k = np.hypot(16.0, 9.0)
    return d * 16.0 / k, d * 9.0 / k


def _arc(center: np.ndarray, radius_xy: tuple[float, float], a0: float, a1: float, n: int) -> np.ndarray:
    """(n+1, 3) points on a horizontal elliptic arc, angles in radians from +x."""
    t = np.linspace(a0, a1, n + 1)
    return np.stack(
        [center[0] + radius_xy[0] * np.cos(t), center[1] + radius_xy[1] * np.sin(t), np.full_like(t, center[2])],
        axis=1,
    )


def _tube_path(name: str, material: str, color: RGB, points: np.ndarray, radius: float) -> list[Part]:
    """Capsules joining consecutive points: a bent tube."""
    return [capsule(name, material, color, points[i], points[i + 1], radius, count=6) for i in range(len(points) - 1)]


# =========================================================================== beds

BedBase = Literal["legs", "box", "platform", "drawers", "metal"]
BedBoard = Literal["panel", "tufted", "slats", "sleigh", "bars", "wingback", "arch"]
FootBoard = Literal["none", "panel", "slats", "sleigh", "bars"]


@dataclass(frozen=True)
class BedSpec:
    """Parameters of a procedural bed (lengths in metres, front = foot end = +x)."""

    id: str
    width: float
    length: float
    mattress_h: float
    base: BedBase
    base_h: float
    headboard: BedBoard
    head_h: float
    footboard: FootBoard
    foot_h: float
    frame: RGB
    upholstery: RGB
    duvet: RGB
    pillows: int


def _bed_board(
    kind: str, x_in: float, outward: float, w: float, z0: float, top: float, s: BedSpec, name: str
) -> list[Part]:
    """A head- or footboard whose inner face is at x = `x_in`, growing towards `outward` (-1 or +1)."""
    parts: list[Part] = []
    t = 0.06
    xc = x_in + outward * t / 2
    if kind == "panel":
        parts.append(box_between(name, "wood", s.frame, (xc - t / 2, -w / 2, 0.0), (xc + t / 2, w / 2, top)))
    elif kind == "tufted":
        t = 0.11
        xc = x_in + outward * t / 2
        parts.append(box_between(name, "fabric", s.upholstery, (xc - t / 2, -w / 2, z0), (xc + t / 2, w / 2, top)))
        rows = np.linspace(z0 + 0.55 * (top - z0), top - 0.1, 3)
        cols = np.linspace(-w / 2 + 0.15, w / 2 - 0.15, max(3, int(round(w / 0.22))))
        for i, z in enumerate(rows):
            for y in cols[(i % 2) :: 2] if len(cols) > 3 else cols:
                parts.append(sphere("button", "fabric", s.frame, (x_in + 0.005 * -outward, y, z), 0.022, 0))
    elif kind == "slats":
        post = 0.07
        for y in (-w / 2 + post / 2, w / 2 - post / 2):
            parts.append(box(name + "_post", "wood", s.frame, (post, post, top), (xc, y, top / 2)))
        parts.append(box(name + "_rail", "wood", s.frame, (t, w, 0.08), (xc, 0.0, top - 0.04)))
        lower = s.base_h + 0.05
        parts.append(box(name + "_rail", "wood", s.frame, (t, w, 0.08), (xc, 0.0, lower)))
        n = max(5, int(round(w / 0.2)))
        for y in np.linspace(-w / 2 + post + 0.06, w / 2 - post - 0.06, n):
            parts.append(box(name + "_slat", "wood", s.frame, (0.025, 0.05, top - lower - 0.08), (xc, y, (top + lower) / 2)))
    elif kind == "sleigh":
        roll = 0.075
        parts.append(box_between(name, "wood", s.frame, (xc - t / 2, -w / 2, 0.0), (xc + t / 2, w / 2, top - roll)))
        xr = xc + outward * 0.05
        parts.append(cylinder(name + "_roll", "wood", s.frame, (xr, -w / 2, top - roll), (xr, w / 2, top - roll), roll, 20))
    elif kind == "bars":
        r_post = 0.022
        for y in (-w / 2, w / 2):
            parts.append(cylinder(name + "_post", "metal", s.frame, (xc, y, 0.0), (xc, y, top), r_post, 12))
            parts.append(sphere(name + "_finial", "metal", s.frame, (xc, y, top + 0.02), 0.032, 1))
        lower = s.base_h + 0.04
        for z in (lower, top - 0.05):
            parts.append(cylinder(name + "_rail", "metal", s.frame, (xc, -w / 2, z), (xc, w / 2, z), 0.014, 10))
        for y in np.linspace(-w / 2 + 0.12, w / 2 - 0.12, max(5, int(round(w / 0.13)))):
            parts.append(cylinder(name + "_bar", "metal", s.frame, (xc, y, lower), (xc, y, top - 0.05), 0.008, 8))
    elif kind == "wingback":
        t = 0.13
        xc = x_in + outward * t / 2
        parts.append(box_between(name, "fabric", s.upholstery, (xc - t / 2, -w / 2, z0), (xc + t / 2, w / 2, top)))
        wing_len = 0.32
        for sgn in (-1, 1):
            y0 = sgn * (w / 2 - 0.05)
            parts.append(
                box_between(
                    name + "_wing",
                    "fabric",
                    s.upholstery,
                    (min(x_in, x_in - outward * wing_len), min(y0, y0 + sgn * 0.12), z0),
                    (max(x_in, x_in - outward * wing_len), max(y0, y0 + sgn * 0.12), top - 0.18),
                )
            )
    elif kind == "arch":
        shoulder = top - 0.28
        parts.append(box_between(name, "wood", s.frame, (xc - t / 2, -w / 2, 0.0), (xc + t / 2, w / 2, shoulder)))
        # an elliptic cylinder along x: the arch on top of the panel
        arch = cylinder(name + "_arch", "wood", s.frame, (xc - t / 2, 0.0, 0.0), (xc + t / 2, 0.0, 0.0), 1.0, 32)
        m = np.diag([1.0, w / 2, top - shoulder, 1.0])
        m[:3, 3] = (0.0, 0.0, shoulder)
        arch_mesh = arch.mesh.copy()
        arch_mesh.apply_transform(m)
        keep = arch_mesh.triangles_center[:, 2] > shoulder - 1e-9
        arch_mesh.update_faces(keep)
        arch_mesh.remove_unreferenced_vertices()
        parts.append(Part(arch.name, arch.material, arch.color, arch_mesh))
    else:
        raise ValueError(f"{s.id}: unknown board kind {kind!r}")
    return parts


def build_bed(s: BedSpec) -> Model3D:
    """Build a bed: foot end at +x, headboard at -x.

    Examples
    --------
    >>> spec = BED_SPECS[0]
    >>> m = build_bed(spec)
    >>> m.cls, m.id == spec.id, bool(m.size[0] > 2.0)
    ('bed', True, True)
    """
    L, W = s.length, s.width
    top = s.base_h + s.mattress_h
    parts: list[Part] = []
    # --- base
    if s.base == "legs":
        rail = 0.14
        parts.append(box_between("frame", "wood", s.frame, (-L / 2, -W / 2 - 0.03, s.base_h - rail), (L / 2, W / 2 + 0.03, s.base_h)))
        for x in (-L / 2 + 0.06, L / 2 - 0.06):
            for y in (-W / 2 + 0.03, W / 2 - 0.03):
                parts.append(cylinder("leg", "wood", s.frame, (x, y, 0.0), (x, y, s.base_h - rail), 0.028, 12))
    elif s.base == "box":
        parts.append(box_between("base", "fabric", s.upholstery, (-L / 2, -W / 2 - 0.02, 0.05), (L / 2, W / 2 + 0.02, s.base_h)))
        for x in (-L / 2 + 0.08, L / 2 - 0.08):
            for y in (-W / 2 + 0.08, W / 2 - 0.08):
                parts.append(cylinder("foot", "wood", s.frame, (x, y, 0.0), (x, y, 0.05), 0.03, 10))
    elif s.base == "platform":
        parts.append(box_between("platform", "wood", s.frame, (-L / 2 - 0.02, -W / 2 - 0.12, 0.04), (L / 2 + 0.12, W / 2 + 0.12, s.base_h)))
        parts.append(box_between("plinth", "wood", BLACK_WOOD, (-L / 2 + 0.1, -W / 2 + 0.05, 0.0), (L / 2 - 0.05, W / 2 - 0.05, 0.04)))
    elif s.base == "drawers":
        parts.append(box_between("base", "wood", s.frame, (-L / 2, -W / 2 - 0.03, 0.02), (L / 2, W / 2 + 0.03, s.base_h)))
        dh = s.base_h - 0.1
        for sgn in (-1, 1):
            y = sgn * (W / 2 + 0.03 + 0.006)
            for x in (-L / 4 + 0.05, L / 4 - 0.05):
                parts.append(box("drawer", "wood", WHITE_PAINT, (L / 2 - 0.16, 0.012, dh), (x, y, 0.05 + dh / 2)))
                parts.append(box("handle", "metal", CHROME, (0.16, 0.02, 0.02), (x, y + sgn * 0.012, 0.05 + dh * 0.7)))
    elif s.base == "metal":
        for y in (-W / 2, W / 2):
            parts.append(cylinder("rail", "metal", s.frame, (-L / 2, y, s.base_h - 0.03), (L / 2, y, s.base_h - 0.03), 0.018, 10))
        for x in np.linspace(-L / 2 + 0.3, L / 2 - 0.3, 4):
            parts.append(box("slat_base", "wood", BIRCH, (0.07, W, 0.02), (x, 0.0, s.base_h - 0.02)))
    else:
        raise ValueError(f"{s.id}: unknown bed base {s.base!r}")
    # --- mattress, duvet, pillows
    parts.append(box_between("mattress", "fabric", LINEN, (-L / 2 + 0.01, -W / 2, s.base_h), (L / 2 - 0.01, W / 2, top)))
    parts.append(
        box_between(
            "duvet",
            "fabric",
            s.duvet,
            (-L / 2 + 0.34 * L, -W / 2 - 0.03, s.base_h + 0.45 * s.mattress_h),
            (L / 2 + 0.02, W / 2 + 0.03, top + 0.05),
        )
    )
    pw = min(0.62, (W - 0.12) / max(1, min(s.pillows, 2)))
    row = min(s.pillows, 2)
    ys = np.linspace(-(row - 1) * pw / 2, (row - 1) * pw / 2, row)
    for y in ys:
        parts.append(ellipsoid("pillow", "fabric", PILLOW, (-L / 2 + 0.2, y, top + 0.07), (0.16, pw / 2 - 0.02, 0.08)))
    if s.pillows > 2:
        for y in ys:
            parts.append(
                ellipsoid(
                    "cushion",
                    "fabric",
                    s.duvet,
                    (-L / 2 + 0.42, y, top + 0.12),
                    (0.07, pw / 2 - 0.06, 0.16),
                    rotation=rot_y(-0.35),
                )
            )
    # --- head and foot boards
    z0 = s.base_h - 0.1
    hw = W + (0.26 if s.base == "platform" else 0.08)
    parts += _bed_board(s.headboard, -L / 2, -1.0, hw, z0, s.head_h, s, "headboard")
    if s.footboard != "none":
        parts += _bed_board(s.footboard, L / 2 + 0.02, +1.0, W + 0.08, z0, s.foot_h, s, "footboard")
    return assemble_model(s.id, "bed", parts, symmetry="none", source=f"procedural:bed/{s.headboard}")


BED_SPECS: tuple[BedSpec, ...] = (
    BedSpec("bed-01", 0.90, 2.00, 0.20, "legs", 0.36, "panel", 0.92, "none", 0.0, WALNUT, GREY_FABRIC, GREY_FABRIC, 1),
    BedSpec("bed-02", 1.40, 2.00, 0.24, "box", 0.40, "tufted", 1.25, "none", 0.0, DARK_METAL, BEIGE, CREAM, 2),
    BedSpec("bed-03", 1.60, 2.00, 0.22, "legs", 0.38, "slats", 1.05, "slats", 0.58, OAK, GREY_FABRIC, BLUE_FABRIC, 2),
    BedSpec("bed-04", 1.80, 2.00, 0.20, "platform", 0.22, "panel", 0.70, "none", 0.0, BIRCH, GREY_FABRIC, CHARCOAL, 2),
    BedSpec("bed-05", 1.40, 2.00, 0.24, "drawers", 0.40, "sleigh", 1.05, "sleigh", 0.72, CHERRY, BEIGE, RED_FABRIC, 2),
    BedSpec("bed-06", 1.00, 2.00, 0.18, "metal", 0.40, "bars", 1.10, "bars", 0.80, DARK_METAL, GREY_FABRIC, TEAL, 1),
    BedSpec("bed-07", 2.00, 2.10, 0.28, "box", 0.38, "wingback", 1.45, "none", 0.0, WALNUT, GREEN_FABRIC, LINEN, 4),
    BedSpec("bed-08", 1.60, 2.00, 0.24, "drawers", 0.36, "arch", 1.30, "panel", 0.50, WHITE_PAINT, BEIGE, MUSTARD, 2),
    BedSpec("bed-09", 1.40, 2.00, 0.14, "platform", 0.16, "panel", 0.52, "none", 0.0, WALNUT, GREY_FABRIC, BEIGE, 2),
)
"""9 beds: single to king, legs / divan / platform / drawers / metal base,
panel, tufted, slatted, sleigh, metal-bar, wingback and arched headboards."""


# =========================================================================== chairs

ChairBack = Literal["slats", "ladder", "panel", "padded", "wing", "hoop", "shell", "headrest", "tub", "sling"]
ChairLegs = Literal["four", "splayed", "swivel", "sled", "box", "short", "pedestal", "cross", "stool"]
ChairArms = Literal["none", "t", "box", "roll", "wood"]


@dataclass(frozen=True)
class ChairSpec:
    """Parameters of a procedural chair (seat opening at +x, backrest at -x)."""

    id: str
    seat_w: float
    seat_d: float
    seat_h: float
    seat_t: float
    back: ChairBack
    back_h: float
    back_tilt_deg: float
    legs: ChairLegs
    arms: ChairArms
    seat_mat: str
    seat_rgb: RGB
    frame_mat: str
    frame_rgb: RGB
    round_seat: bool = False


def _chair_back(s: ChairSpec) -> list[Part]:
    w, d, h = s.seat_w, s.seat_d, s.seat_h
    xb = -d / 2 + 0.025  # back plane
    top = s.back_h
    parts: list[Part] = []
    post_mat, post_rgb = s.frame_mat, s.frame_rgb
    if s.back in ("slats", "ladder", "panel", "sling"):
        for y in (-w / 2 + 0.025, w / 2 - 0.025):
            parts.append(box("back_post", post_mat, post_rgb, (0.04, 0.04, top - h), (xb, y, (top + h) / 2)))
        if s.back == "slats":
            parts.append(box("back_rail", post_mat, post_rgb, (0.03, w - 0.05, 0.09), (xb, 0.0, top - 0.06)))
            for y in np.linspace(-w / 2 + 0.1, w / 2 - 0.1, 4):
                parts.append(box("back_slat", post_mat, post_rgb, (0.015, 0.035, top - h - 0.17), (xb, y, (top + h + 0.06) / 2 - 0.04)))
        elif s.back == "ladder":
            for z in np.linspace(h + 0.18, top - 0.05, 3):
                parts.append(box("back_rail", post_mat, post_rgb, (0.025, w - 0.05, 0.06), (xb, 0.0, z)))
        elif s.back == "panel":
            parts.append(box("back_panel", s.seat_mat, s.seat_rgb, (0.03, w - 0.05, 0.24), (xb, 0.0, top - 0.14)))
        else:  # sling: fabric band between the posts
            parts.append(box("back_panel", "fabric", s.seat_rgb, (0.012, w - 0.06, 0.22), (xb, 0.0, top - 0.13)))
    elif s.back in ("padded", "wing", "headrest"):
        t = 0.1 if s.back != "headrest" else 0.08
        parts.append(box_between("back_panel", s.seat_mat, s.seat_rgb, (xb - t / 2, -w / 2, h - 0.02), (xb + t / 2, w / 2, top - (0.16 if s.back == "headrest" else 0.0))))
        if s.back == "wing":
            for sgn in (-1, 1):
                parts.append(
                    box_between(
                        "wing",
                        s.seat_mat,
                        s.seat_rgb,
                        (xb, min(sgn * w / 2, sgn * (w / 2 - 0.09)), h + 0.3),
                        (xb + 0.24, max(sgn * w / 2, sgn * (w / 2 - 0.09)), top - 0.04),
                    )
                )
        if s.back == "headrest":
            parts.append(box("headrest", s.seat_mat, s.seat_rgb, (0.08, w * 0.55, 0.13), (xb, 0.0, top - 0.065)))
            parts.append(box("headrest_bar", "metal", DARK_METAL, (0.03, 0.05, 0.05), (xb - 0.02, 0.0, top - 0.15)))
    elif s.back == "hoop":
        for y in (-w / 2 + 0.04, w / 2 - 0.04):
            parts.append(cylinder("back_post", post_mat, post_rgb, (xb + 0.03, y, h), (xb, y, top - 0.04), 0.014, 10))
        # a top rail curving backwards from one post top to the other
        arc = _arc(np.array([xb, 0.0, top - 0.04]), (0.09, w / 2 - 0.04), np.pi / 2, 3 * np.pi / 2, 8)
        parts += _tube_path("back_hoop", post_mat, post_rgb, arc, 0.02)
        parts.append(box("back_panel", s.seat_mat, s.seat_rgb, (0.015, w * 0.6, 0.1), (xb - 0.02, 0.0, top - 0.2)))
    elif s.back == "shell":
        # three angled plates read as a curved plastic shell
        hh = top - h
        parts.append(box("shell", s.seat_mat, s.seat_rgb, (0.025, w * 0.5, hh), (xb, 0.0, h + hh / 2)))
        half, bend = w * 0.15, 0.6
        for sgn in (-1, 1):
            # side plates continue from the edges of the centre plate, bending forward (+x)
            centre = (xb + half * np.sin(bend), sgn * (w * 0.25 + half * np.cos(bend)), h + hh * 0.46)
            parts.append(box("shell", s.seat_mat, s.seat_rgb, (0.025, 2 * half, hh * 0.92), centre, rot_z(-sgn * bend)))
    elif s.back == "tub":
        wall = 0.12
        parts.append(box_between("back_panel", s.seat_mat, s.seat_rgb, (-d / 2 - 0.02, -w / 2 - wall, h - 0.1), (-d / 2 + wall - 0.02, w / 2 + wall, top)))
        for sgn in (-1, 1):
            y0, y1 = sorted((sgn * w / 2, sgn * (w / 2 + wall)))
            parts.append(box_between("tub_side", s.seat_mat, s.seat_rgb, (-d / 2, y0, h - 0.1), (d / 2 - 0.05, y1, h + 0.22)))
    else:
        raise ValueError(f"{s.id}: unknown chair back {s.back!r}")
    tilt = np.deg2rad(s.back_tilt_deg)
    if tilt:
        parts = rotated_about(parts, rot_y(-tilt), (xb, 0.0, h))
    return parts


def _translation(t: tuple[float, float, float]) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = t
    return m


def _chair_legs(s: ChairSpec) -> list[Part]:
    w, d, h = s.seat_w, s.seat_d, s.seat_h
    under = h - s.seat_t
    fm, fc = s.frame_mat, s.frame_rgb
    parts: list[Part] = []
    corners = [(x, y) for x in (-d / 2 + 0.03, d / 2 - 0.03) for y in (-w / 2 + 0.03, w / 2 - 0.03)]
    if s.legs == "four":
        for x, y in corners:
            parts.append(box("leg", fm, fc, (0.035, 0.035, under), (x, y, under / 2)))
        for y in (-w / 2 + 0.03, w / 2 - 0.03):
            parts.append(box("stretcher", fm, fc, (d - 0.06, 0.018, 0.025), (0.0, y, 0.16)))
    elif s.legs == "splayed":
        for x, y in corners:
            foot = (x * 1.35, y * 1.35, 0.0)
            parts.append(cylinder("leg", fm, fc, foot, (x * 0.6, y * 0.6, under), 0.011, 8))
        parts.append(box("mount", fm, fc, (d * 0.6, w * 0.6, 0.02), (0.0, 0.0, under - 0.01)))
    elif s.legs == "stool":
        for x, y in corners:
            parts.append(cylinder("leg", fm, fc, (x * 1.15, y * 1.15, 0.0), (x, y, under), 0.016, 10))
        ring = [(x * 1.07, y * 1.07, 0.3) for x, y in corners]
        order = [0, 1, 3, 2, 0]
        for i in range(4):
            parts.append(cylinder("footrest", "metal", CHROME, ring[order[i]], ring[order[i + 1]], 0.01, 8))
    elif s.legs == "swivel":
        hub_z = 0.09
        for k in range(5):
            a = 2 * np.pi * k / 5 + np.pi / 5
            tip = np.array([0.31 * np.cos(a), 0.31 * np.sin(a), hub_z])
            parts.append(box("star", "plastic", BLACK_PLASTIC, (0.3, 0.045, 0.035), (tip[0] / 2, tip[1] / 2, hub_z), rot_z(a)))
            parts.append(sphere("caster", "plastic", BLACK_PLASTIC, (tip[0], tip[1], 0.03), 0.03, 1))
        parts.append(cylinder("hub", "plastic", BLACK_PLASTIC, (0, 0, hub_z - 0.03), (0, 0, hub_z + 0.04), 0.045, 16))
        parts.append(cylinder("gas_lift", "metal", CHROME, (0, 0, hub_z + 0.04), (0, 0, under - 0.05), 0.025, 12))
        parts.append(box("mechanism", "metal", DARK_METAL, (0.22, 0.2, 0.05), (0.0, 0.0, under - 0.025)))
    elif s.legs == "sled":
        r = 0.012
        for y in (-w / 2 + 0.02, w / 2 - 0.02):
            path = np.array(
                [
                    (-d / 2 + 0.02, y, under),
                    (-d / 2 + 0.05, y, r),
                    (d / 2, y, r),
                    (d / 2 - 0.02, y, under),
                ]
            )
            parts += _tube_path("sled", "metal", fc, path, r)
    elif s.legs == "box":
        parts.append(box_between("base", s.seat_mat, s.seat_rgb, (-d / 2, -w / 2, 0.03), (d / 2, w / 2, under)))
        parts.append(box_between("plinth", "wood", BLACK_WOOD, (-d / 2 + 0.04, -w / 2 + 0.04, 0.0), (d / 2 - 0.04, w / 2 - 0.04, 0.03)))
    elif s.legs == "short":
        leg_h = 0.14
        parts.append(box_between("base", s.seat_mat, s.seat_rgb, (-d / 2, -w / 2, leg_h), (d / 2, w / 2, under)))
        for x, y in corners:
            parts.append(cylinder("leg", fm, fc, (x * 1.02, y * 1.02, 0.0), (x * 0.95, y * 0.95, leg_h), 0.018, 10))
    elif s.legs == "pedestal":
        parts.append(cylinder("foot_disc", "metal", fc, (0, 0, 0.0), (0, 0, 0.02), 0.27, 28))
        parts.append(
            revolved("stem", "metal", fc, [(0.0, 0.02), (0.12, 0.02), (0.04, 0.12), (0.035, under - 0.06), (0.14, under), (0.0, under)], sections=20)
        )
    elif s.legs == "cross":
        for y in (-w / 2 + 0.015, w / 2 - 0.015):
            parts.append(cylinder("leg", fm, fc, (-d / 2 + 0.02, y, 0.0), (d / 2 - 0.02, y, under), 0.016, 8))
            parts.append(cylinder("leg", fm, fc, (d / 2 - 0.02, y, 0.0), (-d / 2 + 0.02, y, under), 0.016, 8))
        for x in (-d / 2 + 0.03, d / 2 - 0.03):
            parts.append(cylinder("stretcher", fm, fc, (x, -w / 2, 0.03), (x, w / 2, 0.03), 0.014, 8))
    else:
        raise ValueError(f"{s.id}: unknown chair legs {s.legs!r}")
    return parts


def _chair_arms(s: ChairSpec) -> list[Part]:
    w, d, h = s.seat_w, s.seat_d, s.seat_h
    parts: list[Part] = []
    if s.arms == "none":
        return parts
    for sgn in (-1, 1):
        if s.arms == "t":
            y = sgn * (w / 2 + 0.035)
            parts.append(box("arm_support", "plastic", BLACK_PLASTIC, (0.04, 0.03, 0.22), (-0.03, y, h + 0.09)))
            parts.append(box("arm_pad", "plastic", BLACK_PLASTIC, (0.26, 0.07, 0.03), (-0.02, y, h + 0.21)))
        elif s.arms in ("box", "roll"):
            aw = 0.14
            y0, y1 = sorted((sgn * w / 2, sgn * (w / 2 + aw)))
            z_top = h + 0.2 - (0.05 if s.arms == "roll" else 0.0)
            z_bot = 0.14 if s.legs == "short" else 0.03
            parts.append(box_between("arm", s.seat_mat, s.seat_rgb, (-d / 2, y0, z_bot), (d / 2, y1, z_top)))
            if s.arms == "roll":
                yc = (y0 + y1) / 2
                parts.append(cylinder("arm_roll", s.seat_mat, s.seat_rgb, (-d / 2, yc, z_top), (d / 2 + 0.02, yc, z_top), aw / 2 + 0.015, 16))
        elif s.arms == "wood":
            y = sgn * (w / 2 + 0.02)
            parts.append(box("arm", s.frame_mat, s.frame_rgb, (d * 0.85, 0.05, 0.025), (-0.02, y, h + 0.22)))
            parts.append(box("arm_support", s.frame_mat, s.frame_rgb, (0.03, 0.03, 0.22), (d / 2 - 0.1, y, h + 0.11)))
        else:
            raise ValueError(f"{s.id}: unknown chair arms {s.arms!r}")
    return parts


def build_chair(s: ChairSpec) -> Model3D:
    """Build a chair: seat opening at +x, backrest at -x.

    Examples
    --------
    >>> m = build_chair(CHAIR_SPECS[3])
    >>> m.cls, int(m.n_faces) < 5000
    ('chair', True)
    """
    w, d, h = s.seat_w, s.seat_d, s.seat_h
    parts: list[Part] = []
    if s.round_seat:
        parts.append(cylinder("seat", s.seat_mat, s.seat_rgb, (0, 0, h - s.seat_t), (0, 0, h), max(w, d) / 2, 28))
    else:
        parts.append(box_between("seat", s.seat_mat, s.seat_rgb, (-d / 2, -w / 2, h - s.seat_t), (d / 2, w / 2, h)))
    parts += _chair_legs(s)
    parts += _chair_back(s)
    parts += _chair_arms(s)
    return assemble_model(s.id, "chair", parts, symmetry="none", source=f"procedural:chair/{s.back}-{s.legs}-{s.arms}")


CHAIR_SPECS: tuple[ChairSpec, ...] = (
    ChairSpec("chair-01", 0.44, 0.42, 0.46, 0.03, "slats", 0.92, 6, "four", "none", "wood", OAK, "wood", OAK),
    ChairSpec("chair-02", 0.44, 0.42, 0.45, 0.03, "ladder", 0.98, 5, "four", "none", "wood", WALNUT, "wood", WALNUT),
    ChairSpec("chair-03", 0.46, 0.46, 0.48, 0.07, "padded", 0.92, 8, "four", "none", "fabric", BEIGE, "wood", WALNUT),
    ChairSpec("chair-04", 0.50, 0.48, 0.50, 0.08, "headrest", 1.22, 10, "swivel", "t", "fabric", CHARCOAL, "plastic", BLACK_PLASTIC),
    ChairSpec("chair-05", 0.48, 0.46, 0.48, 0.07, "padded", 0.95, 8, "swivel", "none", "fabric", GREY_FABRIC, "plastic", BLACK_PLASTIC),
    ChairSpec("chair-06", 0.56, 0.56, 0.44, 0.12, "padded", 0.80, 10, "short", "box", "fabric", BLUE_FABRIC, "wood", WALNUT),
    ChairSpec("chair-07", 0.58, 0.60, 0.44, 0.14, "padded", 0.86, 6, "box", "roll", "fabric", BROWN_LEATHER, "wood", BLACK_WOOD),
    ChairSpec("chair-08", 0.56, 0.58, 0.46, 0.12, "wing", 1.15, 6, "short", "roll", "fabric", GREEN_FABRIC, "wood", WALNUT),
    ChairSpec("chair-09", 0.44, 0.44, 0.46, 0.03, "panel", 0.86, 8, "sled", "none", "plastic", RED_FABRIC, "metal", CHROME),
    ChairSpec("chair-10", 0.40, 0.40, 0.46, 0.03, "hoop", 0.86, 0, "four", "none", "wood", BIRCH, "metal", DARK_METAL, True),
    ChairSpec("chair-11", 0.46, 0.44, 0.45, 0.03, "shell", 0.80, 12, "splayed", "none", "plastic", WHITE_PLASTIC, "wood", OAK),
    ChairSpec("chair-12", 0.42, 0.40, 0.76, 0.04, "ladder", 1.02, 4, "stool", "none", "wood", BLACK_WOOD, "metal", DARK_METAL),
    ChairSpec("chair-13", 0.48, 0.50, 0.48, 0.08, "padded", 1.06, 4, "four", "none", "fabric", GREY_FABRIC, "wood", BLACK_WOOD),
    ChairSpec("chair-14", 0.52, 0.50, 0.50, 0.09, "wing", 1.30, 12, "swivel", "t", "fabric", RED_FABRIC, "plastic", BLACK_PLASTIC),
    ChairSpec("chair-15", 0.52, 0.52, 0.44, 0.08, "tub", 0.84, 0, "pedestal", "none", "fabric", TEAL, "metal", WHITE_PLASTIC, True),
    ChairSpec("chair-16", 0.50, 0.46, 0.46, 0.02, "sling", 0.90, 6, "cross", "wood", "fabric", MUSTARD, "wood", BIRCH),
)
"""16 chairs: dining (slats, ladder, upholstered, parsons, bistro, shell),
office swivel chairs with and without arms, armchairs with box, rolled and
wing backs, a cantilever sled chair, a bar chair, a tulip tub chair and a
folding director's chair."""


# =========================================================================== TVs

TVMount = Literal["foot", "feet", "cabinet", "stand", "doors"]


@dataclass(frozen=True)
class TVSpec:
    """Parameters of a procedural TV (screen facing +x)."""

    id: str
    diag_in: float
    depth: float
    mount: TVMount
    body: RGB
    furniture: RGB
    hump: bool = False
    soundbar: bool = False


def build_tv(s: TVSpec) -> Model3D:
    """Build a TV: a thin panel whose screen quad faces +x, on a foot, feet, stand or cabinet.

    Examples
    --------
    >>> m = build_tv(TV_SPECS[0])
    >>> bool(np.allclose(m.mesh.face_normals[m.material_mask("screen")], [1, 0, 0]))
    True
    """
    sw, sh = _inch(s.diag_in)
    bezel = 0.012
    pw, ph = sw + 2 * bezel, sh + 2 * bezel
    parts: list[Part] = []
    x_panel = 0.0
    if s.mount == "foot":
        lift = 0.07
        parts.append(box("foot", "plastic", s.body, (0.22, min(0.36, pw * 0.5), 0.02), (-0.02, 0.0, 0.01)))
        parts.append(box("neck", "plastic", s.body, (0.04, 0.08, lift + 0.12), (-s.depth / 2 - 0.015, 0.0, (lift + 0.12) / 2)))
        z0 = lift
    elif s.mount == "feet":
        lift = 0.06
        for y in (-pw / 2 + 0.12, pw / 2 - 0.12):
            parts.append(box("foot", "metal", DARK_METAL, (0.24, 0.03, 0.015), (0.0, y, 0.0075)))
            parts.append(box("foot", "metal", DARK_METAL, (0.03, 0.03, lift + 0.05), (0.0, y, (lift + 0.05) / 2)))
        z0 = lift
    elif s.mount in ("cabinet", "doors"):
        cw, cd, chh = pw + 0.4, 0.42, 0.48
        parts.append(box_between("cabinet", "wood", s.furniture, (-cd / 2, -cw / 2, 0.06), (cd / 2, cw / 2, chh)))
        for x in (-cd / 2 + 0.04, cd / 2 - 0.04):
            for y in (-cw / 2 + 0.05, cw / 2 - 0.05):
                parts.append(box("cabinet_leg", "metal", DARK_METAL, (0.03, 0.03, 0.06), (x, y, 0.03)))
        if s.mount == "doors":
            n = 3
            dw = (cw - 0.04) / n
            for i in range(n):
                y = -cw / 2 + 0.02 + dw * (i + 0.5)
                parts.append(box("door", "wood", WHITE_PAINT if s.furniture != WHITE_PAINT else OAK, (0.012, dw - 0.01, chh - 0.1), (cd / 2 + 0.006, y, (chh + 0.06) / 2)))
                parts.append(box("handle", "metal", CHROME, (0.02, 0.1, 0.015), (cd / 2 + 0.02, y, chh - 0.08)))
        else:
            parts.append(box("shelf_gap", "wood", BLACK_WOOD, (0.01, cw - 0.1, 0.12), (cd / 2 + 0.005, 0.0, chh - 0.12)))
        parts.append(box("foot", "plastic", s.body, (0.2, 0.3, 0.02), (-0.05, 0.0, chh + 0.01)))
        parts.append(box("neck", "plastic", s.body, (0.04, 0.08, 0.16), (-0.05 - s.depth / 2 - 0.015, 0.0, chh + 0.08)))
        x_panel = -0.05
        z0 = chh + 0.08
    elif s.mount == "stand":
        parts.append(box("stand_base", "metal", s.furniture, (0.42, 0.62, 0.025), (-0.06, 0.0, 0.0125)))
        pole_x = -s.depth / 2 - 0.04
        z0 = 0.62
        parts.append(cylinder("stand_pole", "metal", s.furniture, (pole_x, 0, 0.02), (pole_x, 0, z0 + ph * 0.7), 0.03, 16))
        parts.append(box("stand_mount", "metal", s.furniture, (0.03, 0.3, 0.2), (pole_x + 0.02, 0.0, z0 + ph * 0.5)))
        parts.append(box("stand_shelf", "glass", MIRROR, (0.3, 0.5, 0.012), (0.0, 0.0, 0.32)))
    else:
        raise ValueError(f"{s.id}: unknown TV mount {s.mount!r}")
    x0, x1 = x_panel - s.depth / 2, x_panel + s.depth / 2
    parts.append(box_between("panel", "plastic", s.body, (x0, -pw / 2, z0), (x1, pw / 2, z0 + ph)))
    if s.hump:
        parts.append(box_between("back_cover", "plastic", s.body, (x0 - 0.06, -pw * 0.3, z0 + ph * 0.15), (x0, pw * 0.3, z0 + ph * 0.75)))
    xs = x1 + 0.002
    zs0, zs1 = z0 + bezel, z0 + bezel + sh
    # corners counter-clockwise seen from +x (looking along -x, +y is on the right)
    parts.append(quad("screen", "screen", SCREEN, [(xs, sw / 2, zs0), (xs, sw / 2, zs1), (xs, -sw / 2, zs1), (xs, -sw / 2, zs0)]))
    if s.soundbar:
        sx = x1 + 0.1 if s.mount != "doors" else x_panel + 0.12
        sz = 0.0 if s.mount == "feet" else z0 - 0.08
        parts.append(box_between("soundbar", "plastic", BLACK_PLASTIC, (sx - 0.05, -sw * 0.4, sz), (sx + 0.05, sw * 0.4, sz + 0.065)))
    return assemble_model(s.id, "tv", parts, symmetry="none", source=f"procedural:tv/{s.mount}")


TV_SPECS: tuple[TVSpec, ...] = (
    TVSpec("tv-01", 32, 0.06, "foot", BLACK_PLASTIC, BLACK_WOOD, hump=True),
    TVSpec("tv-02", 43, 0.05, "feet", GREY_PLASTIC, BLACK_WOOD),
    TVSpec("tv-03", 50, 0.05, "cabinet", BLACK_PLASTIC, WALNUT),
    TVSpec("tv-04", 55, 0.04, "stand", BLACK_PLASTIC, DARK_METAL),
    TVSpec("tv-05", 65, 0.035, "feet", DARK_METAL, BLACK_WOOD, soundbar=True),
    TVSpec("tv-06", 75, 0.03, "doors", BLACK_PLASTIC, WHITE_PAINT, soundbar=True),
)
"""6 TVs: 32" to 75" on a centre foot, two feet, a media cabinet, a floor
stand and a cabinet with doors; two with a sound bar."""


# =========================================================================== plants

PotShape = Literal["cylinder", "tapered", "bowl", "square"]
Foliage = Literal["bush", "conifer", "blades", "palm"]


@dataclass(frozen=True)
class PlantSpec:
    """Parameters of a procedural potted plant (rotationally symmetric)."""

    id: str
    pot: PotShape
    pot_r: float
    pot_h: float
    pot_rgb: RGB
    foliage: Foliage
    height: float
    seed: int


def _pot(s: PlantSpec) -> list[Part]:
    r, h = s.pot_r, s.pot_h
    if s.pot == "cylinder":
        prof = [(0.0, 0.0), (r, 0.0), (r, h), (r * 0.9, h), (r * 0.9, h - 0.03), (0.0, h - 0.03)]
    elif s.pot == "tapered":
        prof = [(0.0, 0.0), (r * 0.62, 0.0), (r, h - 0.04), (r * 1.06, h - 0.04), (r * 1.06, h), (r * 0.92, h), (r * 0.92, h - 0.03), (0.0, h - 0.03)]
    elif s.pot == "bowl":
        prof = [(0.0, 0.0), (r * 0.45, 0.0), (r * 0.5, 0.03)] + [
            (r * np.sin(t), h * (1 - np.cos(t)) + 0.03 * (1 - t / (np.pi / 2))) for t in np.linspace(0.35, np.pi / 2, 6)
        ] + [(r * 0.9, h), (r * 0.9, h - 0.02), (0.0, h - 0.02)]
    elif s.pot == "square":
        return [
            box("pot", "ceramic", s.pot_rgb, (2 * r, 2 * r, h), (0.0, 0.0, h / 2)),
            box("soil", "soil", SOIL, (2 * r - 0.03, 2 * r - 0.03, 0.01), (0.0, 0.0, h + 0.005)),
        ]
    else:
        raise ValueError(f"{s.id}: unknown pot shape {s.pot!r}")
    return [
        revolved("pot", "ceramic", s.pot_rgb, prof, sections=28),
        cylinder("soil", "soil", SOIL, (0, 0, h - 0.035), (0, 0, h - 0.015), r * 0.88, 24),
    ]


def _foliage(s: PlantSpec) -> list[Part]:
    rng = np.random.default_rng(s.seed)
    base = s.pot_h - 0.02
    crown = s.height - base
    parts: list[Part] = []
    greens = (LEAF_A, LEAF_B, LEAF_C)
    if s.foliage == "bush":
        parts.append(cylinder("stem", "wood", TRUNK, (0, 0, base), (0, 0, base + crown * 0.35), 0.015, 8))
        n = 14
        for i in range(n):
            a = 2 * np.pi * (i / n) + rng.uniform(-0.2, 0.2)
            ring = 0.6 if i % 2 else 0.25
            rad = crown * rng.uniform(0.17, 0.24)
            zc = base + crown * (0.42 + 0.28 * (i % 3) / 2)
            rr = crown * 0.34 * ring
            parts.append(sphere("leaves", "leaf", greens[i % 3], (rr * np.cos(a), rr * np.sin(a), zc), rad, 1))
        parts.append(sphere("leaves", "leaf", LEAF_A, (0.0, 0.0, base + crown - crown * 0.22), crown * 0.22, 2))
    elif s.foliage == "conifer":
        trunk_top = base + crown * 0.2
        parts.append(cylinder("trunk", "wood", TRUNK, (0, 0, base), (0, 0, trunk_top), 0.025, 10))
        tiers = 3
        for i in range(tiers):
            z = trunk_top + i * crown * 0.22
            r = s.pot_r * (1.5 - 0.35 * i)
            hgt = s.height - z if i == tiers - 1 else crown * 0.42
            parts.append(cone("leaves", "leaf", greens[i % 2], (0.0, 0.0, z), r, hgt, 20))
    elif s.foliage == "blades":
        n = 11
        for i in range(n):
            a = 2 * np.pi * i / n + rng.uniform(-0.15, 0.15)
            lean = rng.uniform(0.12, 0.3)
            length = crown * rng.uniform(0.85, 1.0) / np.cos(lean)
            blade = box("leaves", "leaf", greens[i % 3], (0.012, 0.055, length), (0.0, 0.0, length / 2))
            blade = blade.transformed(_rot4(rot_z(a) @ rot_y(lean)))
            blade = blade.transformed(_translation((0.03 * np.cos(a), 0.03 * np.sin(a), base)))
            parts.append(blade)
    elif s.foliage == "palm":
        top = base + crown * 0.62
        parts.append(cylinder("trunk", "wood", TRUNK, (0, 0, base), (0, 0, top), 0.022, 10))
        n = 8
        for i in range(n):
            a = 2 * np.pi * i / n + rng.uniform(-0.1, 0.1)
            rise = rng.uniform(-0.35, 0.55)
            frond_len = crown * 0.4
            d = np.array([np.cos(a) * np.cos(rise), np.sin(a) * np.cos(rise), np.sin(rise)])
            c = np.array([0.0, 0.0, top]) + d * frond_len / 2
            rot = rot_z(a) @ rot_y(-rise)
            parts.append(ellipsoid("leaves", "leaf", greens[i % 3], c, (frond_len / 2, 0.07, 0.012), rot, 1))
        parts.append(sphere("leaves", "leaf", LEAF_B, (0.0, 0.0, top), 0.05, 1))
    else:
        raise ValueError(f"{s.id}: unknown foliage {s.foliage!r}")
    return parts


def _rot4(r: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = r
    return m


def build_plant(s: PlantSpec) -> Model3D:
    """Build a potted plant (symmetry "full"; the seed in `s` fixes leaf jitter).

    Examples
    --------
    >>> m = build_plant(PLANT_SPECS[1])
    >>> m.symmetry, m.content_hash() == build_plant(PLANT_SPECS[1]).content_hash()
    ('full', True)
    """
    return assemble_model(s.id, "plant", _pot(s) + _foliage(s), symmetry="full", source=f"procedural:plant/{s.pot}-{s.foliage}")


PLANT_SPECS: tuple[PlantSpec, ...] = (
    PlantSpec("plant-01", "cylinder", 0.16, 0.30, TERRACOTTA, "bush", 0.85, 11),
    PlantSpec("plant-02", "tapered", 0.17, 0.34, WHITE_CERAMIC, "conifer", 1.45, 12),
    PlantSpec("plant-03", "bowl", 0.2, 0.2, SLATE, "blades", 0.95, 13),
    PlantSpec("plant-04", "square", 0.18, 0.42, WHITE_CERAMIC, "palm", 1.7, 14),
)
"""4 plants: bush in a terracotta cylinder, conifer tiers in a tapered pot,
blade leaves in a bowl, palm fronds in a square planter."""


# =========================================================================== clutter


@dataclass(frozen=True)
class SofaSpec:
    """Parameters of a procedural sofa (seat facing +x, back at -x)."""

    id: str
    seats: int
    seat_w: float
    depth: float
    arms: Literal["box", "roll", "track"]
    legs: Literal["wood", "plinth"]
    fabric: RGB
    wood: RGB
    pillows: bool


def build_sofa(s: SofaSpec) -> Model3D:
    """Build a sofa: seat cushions open to +x, back cushions at -x."""
    arm_w = {"box": 0.18, "roll": 0.16, "track": 0.08}[s.arms]
    W = s.seats * s.seat_w
    D = s.depth
    leg_h = 0.12 if s.legs == "wood" else 0.04
    seat_top, back_top = 0.45, 0.86
    arm_top = {"box": 0.62, "roll": 0.56, "track": 0.58}[s.arms]
    parts: list[Part] = []
    parts.append(box_between("base", "fabric", s.fabric, (-D / 2, -W / 2, leg_h), (D / 2, W / 2, seat_top - 0.14)))
    parts.append(box_between("back", "fabric", s.fabric, (-D / 2, -W / 2, leg_h), (-D / 2 + 0.2, W / 2, back_top - 0.12)))
    for i in range(s.seats):
        y0 = -W / 2 + i * s.seat_w
        parts.append(box_between("seat_cushion", "fabric", s.fabric, (-D / 2 + 0.2, y0 + 0.005, seat_top - 0.14), (D / 2, y0 + s.seat_w - 0.005, seat_top)))
        parts.append(
            box(
                "back_cushion",
                "fabric",
                s.fabric,
                (0.16, s.seat_w - 0.02, back_top - seat_top),
                (0.0, 0.0, 0.0),
                rot_y(-0.18),
            ).transformed(_translation((-D / 2 + 0.2, y0 + s.seat_w / 2, (seat_top + back_top) / 2 + 0.01)))
        )
    for sgn in (-1, 1):
        y0, y1 = sorted((sgn * W / 2, sgn * (W / 2 + arm_w)))
        parts.append(box_between("arm", "fabric", s.fabric, (-D / 2, y0, leg_h), (D / 2, y1, arm_top)))
        if s.arms == "roll":
            yc = (y0 + y1) / 2
            parts.append(cylinder("arm_roll", "fabric", s.fabric, (-D / 2, yc, arm_top), (D / 2 + 0.02, yc, arm_top), arm_w / 2 + 0.02, 16))
        if s.pillows:
            parts.append(
                ellipsoid("pillow", "fabric", MUSTARD, (-D / 2 + 0.32, sgn * (W / 2 - 0.25), seat_top + 0.2), (0.07, 0.2, 0.2), rot_y(-0.25))
            )
    if s.legs == "wood":
        for x in (-D / 2 + 0.06, D / 2 - 0.06):
            for y in (-W / 2 - arm_w + 0.06, W / 2 + arm_w - 0.06):
                parts.append(revolved("leg", "wood", s.wood, [(0.0, 0.0), (0.014, 0.0), (0.024, leg_h), (0.0, leg_h)], (x, y, 0.0), 10))
    else:
        parts.append(box_between("plinth", "wood", s.wood, (-D / 2 + 0.05, -W / 2 - arm_w + 0.05, 0.0), (D / 2 - 0.05, W / 2 + arm_w - 0.05, leg_h)))
    return assemble_model(s.id, "sofa", parts, symmetry="none", source=f"procedural:sofa/{s.seats}-{s.arms}")


SOFA_SPECS: tuple[SofaSpec, ...] = (
    SofaSpec("sofa-01", 3, 0.62, 0.92, "box", "wood", GREY_FABRIC, WALNUT, True),
    SofaSpec("sofa-02", 2, 0.66, 0.9, "roll", "wood", BLUE_FABRIC, CHERRY, False),
    SofaSpec("sofa-03", 3, 0.66, 0.98, "track", "plinth", BEIGE, BLACK_WOOD, True),
)


@dataclass(frozen=True)
class TableSpec:
    """Parameters of a procedural table (rectangular tables have 2-fold symmetry)."""

    id: str
    kind: Literal["dining", "coffee", "round"]
    length: float
    width: float
    height: float
    top_rgb: RGB
    leg_rgb: RGB


def build_table(s: TableSpec) -> Model3D:
    """Build a table; a rectangle is symmetric under 180 deg ("two"), a round one fully."""
    L, W, H = s.length, s.width, s.height
    parts: list[Part] = []
    if s.kind == "dining":
        t = 0.04
        parts.append(box_between("top", "wood", s.top_rgb, (-L / 2, -W / 2, H - t), (L / 2, W / 2, H)))
        parts.append(box_between("apron", "wood", s.leg_rgb, (-L / 2 + 0.06, -W / 2 + 0.06, H - t - 0.08), (L / 2 - 0.06, W / 2 - 0.06, H - t)))
        for x in (-L / 2 + 0.08, L / 2 - 0.08):
            for y in (-W / 2 + 0.08, W / 2 - 0.08):
                parts.append(box("leg", "wood", s.leg_rgb, (0.06, 0.06, H - t), (x, y, (H - t) / 2)))
        symmetry: Symmetry = "two"
    elif s.kind == "coffee":
        t = 0.035
        parts.append(box_between("top", "wood", s.top_rgb, (-L / 2, -W / 2, H - t), (L / 2, W / 2, H)))
        parts.append(box_between("shelf", "wood", s.top_rgb, (-L / 2 + 0.05, -W / 2 + 0.05, 0.1), (L / 2 - 0.05, W / 2 - 0.05, 0.125)))
        for x in (-L / 2 + 0.04, L / 2 - 0.04):
            for y in (-W / 2 + 0.04, W / 2 - 0.04):
                parts.append(cylinder("leg", "metal", s.leg_rgb, (x, y, 0.0), (x, y, H - t), 0.016, 10))
        symmetry = "two"
    elif s.kind == "round":
        r = L / 2
        parts.append(cylinder("top", "wood", s.top_rgb, (0, 0, H - 0.035), (0, 0, H), r, 40))
        parts.append(cylinder("column", "metal", s.leg_rgb, (0, 0, 0.03), (0, 0, H - 0.035), 0.04, 16))
        parts.append(cylinder("base", "metal", s.leg_rgb, (0, 0, 0.0), (0, 0, 0.03), r * 0.55, 32))
        symmetry = "full"
    else:
        raise ValueError(f"{s.id}: unknown table kind {s.kind!r}")
    return assemble_model(s.id, "table", parts, symmetry=symmetry, source=f"procedural:table/{s.kind}")


TABLE_SPECS: tuple[TableSpec, ...] = (
    TableSpec("table-01", "dining", 1.6, 0.9, 0.75, OAK, OAK),
    TableSpec("table-02", "coffee", 1.1, 0.6, 0.42, WALNUT, DARK_METAL),
    TableSpec("table-03", "round", 0.9, 0.9, 0.74, WHITE_PAINT, DARK_METAL),
)


@dataclass(frozen=True)
class CabinetSpec:
    """Parameters of a nightstand or wardrobe (doors and drawers on the +x side)."""

    id: str
    cls: Literal["nightstand", "wardrobe"]
    depth: float
    width: float
    height: float
    fronts: tuple[tuple[str, float], ...]
    columns: int
    body: RGB
    front: RGB
    legs: bool


def build_cabinet(s: CabinetSpec) -> Model3D:
    """Build a nightstand or wardrobe; door and drawer fronts and handles sit on the +x face.

    `fronts` lists, bottom to top, (kind, height fraction) with kind one of
    ``"drawer"``, ``"door"``, ``"mirror"`` (a mirrored sliding door) or
    ``"open"`` (an open shelf).
    """
    D, W, H = s.depth, s.width, s.height
    leg_h = 0.12 if s.legs else 0.0
    parts: list[Part] = []
    if s.legs:
        for x in (-D / 2 + 0.04, D / 2 - 0.04):
            for y in (-W / 2 + 0.04, W / 2 - 0.04):
                parts.append(cylinder("leg", "wood", s.body, (x, y, 0.0), (x, y, leg_h), 0.018, 10))
    else:
        parts.append(box_between("plinth", "wood", BLACK_WOOD, (-D / 2 + 0.03, -W / 2 + 0.02, 0.0), (D / 2 - 0.03, W / 2 - 0.02, 0.07)))
        leg_h = 0.07
    parts.append(box_between("body", "wood", s.body, (-D / 2, -W / 2, leg_h), (D / 2, W / 2, H)))
    gap = 0.006
    xf = D / 2 + 0.009
    z = leg_h + 0.02
    usable = H - leg_h - 0.04
    total = sum(f for _, f in s.fronts)
    for kind, frac in s.fronts:
        fh = usable * frac / total
        if kind == "drawer":
            parts.append(box("drawer", "wood", s.front, (0.018, W - 0.04, fh - gap), (xf, 0.0, z + fh / 2)))
            if s.cls == "wardrobe" or W > 0.5:
                parts.append(box("handle", "metal", CHROME, (0.025, min(0.16, W * 0.3), 0.018), (xf + 0.02, 0.0, z + fh * 0.6)))
            else:
                parts.append(sphere("handle", "metal", CHROME, (xf + 0.02, 0.0, z + fh * 0.6), 0.016, 1))
        elif kind in ("door", "mirror"):
            cw = (W - 0.04) / s.columns
            for c in range(s.columns):
                y = -W / 2 + 0.02 + cw * (c + 0.5)
                if kind == "mirror":
                    parts.append(box("door", "wood", s.front, (0.018, cw - gap, fh - gap), (xf, y, z + fh / 2)))
                    parts.append(box("mirror", "glass", MIRROR, (0.004, cw * 0.7, fh * 0.8), (xf + 0.011, y, z + fh / 2)))
                    parts.append(box("handle", "metal", CHROME, (0.02, 0.02, 0.5), (xf + 0.02, y + (cw / 2 - 0.05) * (1 if c % 2 == 0 else -1), z + fh * 0.5)))
                else:
                    parts.append(box("door", "wood", s.front, (0.018, cw - gap, fh - gap), (xf, y, z + fh / 2)))
                    hy = y + (cw / 2 - 0.05) * (1 if c % 2 == 0 else -1)
                    hl = min(0.3, fh * 0.3)
                    parts.append(box("handle", "metal", CHROME, (0.025, 0.018, hl), (xf + 0.02, hy, z + fh * (0.5 if s.cls == "wardrobe" else 0.7))))
        elif kind == "open":
            parts.append(box_between("shelf_gap", "wood", BLACK_WOOD, (D / 2 - 0.01, -W / 2 + 0.03, z + 0.02), (D / 2 + 0.001, W / 2 - 0.03, z + fh - 0.02)))
        else:
            raise ValueError(f"{s.id}: unknown front kind {kind!r}")
        z += fh
    parts.append(box_between("top", "wood", s.body, (-D / 2, -W / 2 - 0.01, H), (D / 2 + 0.02, W / 2 + 0.01, H + 0.025)))
    return assemble_model(s.id, s.cls, parts, symmetry="none", source=f"procedural:{s.cls}")


NIGHTSTAND_SPECS: tuple[CabinetSpec, ...] = (
    CabinetSpec("nightstand-01", "nightstand", 0.4, 0.45, 0.55, (("drawer", 1.0), ("drawer", 1.0)), 1, WHITE_PAINT, WHITE_PAINT, False),
    CabinetSpec("nightstand-02", "nightstand", 0.38, 0.48, 0.58, (("open", 1.2), ("drawer", 0.8)), 1, OAK, OAK, True),
    CabinetSpec("nightstand-03", "nightstand", 0.4, 0.42, 0.66, (("drawer", 1.0), ("drawer", 1.0), ("drawer", 1.0)), 1, WALNUT, WALNUT, False),
)

WARDROBE_SPECS: tuple[CabinetSpec, ...] = (
    CabinetSpec("wardrobe-01", "wardrobe", 0.6, 1.0, 2.0, (("door", 1.0),), 2, WHITE_PAINT, WHITE_PAINT, False),
    CabinetSpec("wardrobe-02", "wardrobe", 0.6, 1.5, 2.1, (("drawer", 0.13), ("drawer", 0.13), ("door", 1.0)), 3, OAK, BIRCH, False),
    CabinetSpec("wardrobe-03", "wardrobe", 0.62, 1.8, 2.2, (("mirror", 1.0),), 2, BLACK_WOOD, CHARCOAL, True),
)


AnySpec = BedSpec | ChairSpec | TVSpec | PlantSpec | SofaSpec | TableSpec | CabinetSpec

BUILDERS: dict[type, Callable[..., Model3D]] = {
    BedSpec: build_bed,
    ChairSpec: build_chair,
    TVSpec: build_tv,
    PlantSpec: build_plant,
    SofaSpec: build_sofa,
    TableSpec: build_table,
    CabinetSpec: build_cabinet,
}

ALL_SPECS: tuple[AnySpec, ...] = (
    BED_SPECS + CHAIR_SPECS + TV_SPECS + PLANT_SPECS + SOFA_SPECS + TABLE_SPECS + NIGHTSTAND_SPECS + WARDROBE_SPECS
)
"""Every built-in model spec, in library order."""


def build_model(spec: AnySpec) -> Model3D:
    """Build the model of one spec record (dispatch on its type).

    Examples
    --------
    >>> build_model(TABLE_SPECS[0]).symmetry
    'two'
    """
    builder = BUILDERS.get(type(spec))
    if builder is None:
        raise ValueError(f"expected one of {[t.__name__ for t in BUILDERS]}, got {type(spec).__name__}")
    return builder(spec)


def build_all() -> list[Model3D]:
    """Build every built-in model, in `ALL_SPECS` order (no caching; see `builtin_library`)."""
    return [build_model(s) for s in ALL_SPECS]
