"""Procedural textures, lights and a Lambert shader for ray-cast panoramas.

Turns a :class:`panogeom.raycast.RenderResult` into an RGB panorama that is
not made of flat colours: every material has a seeded procedural pattern
evaluated at the 3D hit points (plaster mottling, wood planks with grain and
gaps, tiles with grout lines, carpet fleck, fabric weave, brushed metal, ...),
walls get straight skirting boards along the floor and door / window frames,
the ceiling gets light fixtures, and the image is lit by a few point lights
(Lambert, soft shadows, soft ambient) and passed through a small camera model
(auto exposure, exposure / white-balance / gamma jitter, blur, sensor noise).

Convention:

- Hit points and lights are in world metres (z up, CONVENTIONS.md); pattern
  sizes (tile size, plank width, grout width) are metres on the surface.
- Patterns use 2D surface coordinates picked by the dominant axis of the
  face normal: ``(x, y)`` on floors and ceilings, ``(y, z)`` on faces facing
  +-x, ``(x, z)`` on faces facing +-y, so wall patterns are vertical/horizontal.
- Colours are sRGB in [0, 1] (float) or 0..255 (uint8); lighting is done in
  linear RGB (sRGB decoded with gamma 2.2) and encoded with the output gamma.
- Thin lines (grout, plank gaps, frames, skirting) are box-filtered over the
  pixel's footprint on the surface, so they do not alias into dotted lines
  at a distance; noise octaves finer than the footprint fade out.
- Everything random comes from a seed or a ``numpy.random.Generator``: the
  same inputs give the same image.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from functools import lru_cache
from typing import TYPE_CHECKING, Literal, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._checks import float_array

if TYPE_CHECKING:  # pragma: no cover
    from .raycast import RenderMesh, RenderResult

__all__ = [
    "Material",
    "MaterialStyle",
    "default_style",
    "sample_styles",
    "sample_palette",
    "value_noise",
    "material_albedo",
    "PointLight",
    "sample_lights",
    "Decor",
    "sample_decor",
    "Opening",
    "place_openings",
    "PostProcess",
    "sample_post",
    "shade",
]

F32 = NDArray[np.float32]
_TABLE = 256  # noise lattice period (cells)
_LUMA = np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
# sRGB decoding through a table (albedo in [0, 1] quantised to _LUT steps).
_LUT = 4096
_SRGB_DECODE = (np.linspace(0.0, 1.0, _LUT, dtype=np.float32) ** np.float32(2.2)).astype(np.float32)
# Surface axes by dominant normal axis (x, y, z): faces facing +-x use (y, z),
# facing +-y use (x, z), facing +-z use (x, y).
_S_AXIS = np.array([1, 0, 0])
_T_AXIS = np.array([2, 2, 1])


class Material(IntEnum):
    """Material ids understood by the shader (per-face ``material_ids`` of a mesh)."""

    PLASTER = 0
    WOOD = 1
    TILE = 2
    CARPET = 3
    FABRIC = 4
    METAL = 5
    PLASTIC = 6
    LEAF = 7
    SCREEN = 8


def _color3(value: ArrayLike | None, name: str) -> NDArray[np.float32] | None:
    if value is None:
        return None
    a = np.asarray(value)
    if a.shape != (3,) or a.dtype.kind not in "uif":
        raise ValueError(f"{name}: expected an RGB triple, got {a!r}")
    a = a.astype(np.float32) / (255.0 if a.dtype.kind in "ui" else 1.0)
    if not (np.all(np.isfinite(a)) and a.min() >= 0 and a.max() <= 1):
        raise ValueError(f"{name}: expected colour values in [0, 1] (float) or 0..255 (int), got {value!r}")
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class MaterialStyle:
    """Parameters of one material's procedural pattern (all lengths in metres).

    Attributes
    ----------
    material : Material
    seed : int
        Seed of the pattern's noise.
    scale : float
        Main feature size: plaster mottling wavelength, plank width, tile size
        along the first surface axis, carpet fleck, fabric weave period,
        metal brush length, leaf size.
    length : float
        Plank length (wood), tile size along the second axis (tile).
    line_width : float
        Gap between planks / grout width; 0 for none.
    line_color : (3,) float or None
        sRGB colour of gaps / grout; None for the base colour darkened.
    contrast : float
        Strength of the pattern's brightness variation (0 = flat colour).
    axis : {0, 1}
        Planks run along the first (0) or second (1) surface axis.
    """

    material: Material
    seed: int = 0
    scale: float = 0.5
    length: float = 1.0
    line_width: float = 0.0
    line_color: ArrayLike | None = None
    contrast: float = 1.0
    axis: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "material", Material(int(self.material)))
        for name in ("scale", "length"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: expected a positive length in metres, got {v!r}")
        lw, c = float(self.line_width), float(self.contrast)
        if not (np.isfinite(lw) and lw >= 0):
            raise ValueError(f"line_width: expected a non-negative length in metres, got {lw!r}")
        if not (np.isfinite(c) and c >= 0):
            raise ValueError(f"contrast: expected a non-negative number, got {c!r}")
        if self.axis not in (0, 1):
            raise ValueError(f"axis: expected 0 or 1, got {self.axis!r}")
        object.__setattr__(self, "line_color", _color3(self.line_color, "line_color"))


_DEFAULTS: dict[Material, dict] = {
    Material.PLASTER: dict(scale=0.8, contrast=0.08),
    Material.WOOD: dict(scale=0.14, length=1.2, line_width=0.003, contrast=1.0),
    Material.TILE: dict(scale=0.4, length=0.4, line_width=0.005, line_color=(0.78, 0.77, 0.74), contrast=1.0),
    Material.CARPET: dict(scale=0.006, contrast=0.35),
    Material.FABRIC: dict(scale=0.004, contrast=0.25),
    Material.METAL: dict(scale=0.3, contrast=0.15),
    Material.PLASTIC: dict(scale=0.2, contrast=0.05),
    Material.LEAF: dict(scale=0.05, contrast=1.0),
    Material.SCREEN: dict(scale=0.5, contrast=0.3),
}


def default_style(material: int, seed: int = 0) -> MaterialStyle:
    """The default pattern of a material (used for materials missing from a mapping).

    Examples
    --------
    >>> default_style(Material.TILE).scale
    0.4
    """
    m = Material(int(material)) if int(material) in Material._value2member_map_ else None
    if m is None:
        return MaterialStyle(Material.PLASTIC, seed=seed, **_DEFAULTS[Material.PLASTIC])
    return MaterialStyle(m, seed=seed, **_DEFAULTS[m])


def _rng(rng: np.random.Generator | int | None) -> np.random.Generator:
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or isinstance(rng, (int, np.integer)):
        return np.random.default_rng(0 if rng is None else int(rng))
    raise ValueError(f"rng: expected a numpy Generator or an int seed, got {type(rng).__name__}")


def sample_styles(rng: np.random.Generator | int | None = None) -> dict[int, MaterialStyle]:
    """Random pattern parameters for every :class:`Material`, for one room.

    Tile sizes 0.15..0.6 m (square or 2:1), grout 2..8 mm light or dark; wood
    planks 0.08..0.25 m wide, 0.6..2 m long, along x or y; plaster mottling,
    carpet fleck etc. with random scale and contrast.

    Examples
    --------
    >>> s = sample_styles(3)
    >>> sorted(s) == [int(m) for m in Material]
    True
    """
    g = _rng(rng)
    seeds = g.integers(0, 2**31 - 1, size=len(Material))
    tile = float(g.choice([0.15, 0.2, 0.3, 0.4, 0.45, 0.6]))
    grout = (0.8, 0.79, 0.76) if g.random() < 0.65 else (0.25, 0.24, 0.23)
    out = {
        Material.PLASTER: dict(scale=g.uniform(0.4, 1.5), contrast=g.uniform(0.03, 0.12)),
        Material.WOOD: dict(scale=g.uniform(0.08, 0.25), length=g.uniform(0.6, 2.0),
                            line_width=g.uniform(0.0015, 0.005),
                            contrast=g.uniform(0.6, 1.4), axis=int(g.integers(0, 2))),
        Material.TILE: dict(scale=tile, length=tile * (2.0 if g.random() < 0.25 else 1.0),
                            line_width=g.uniform(0.002, 0.008), line_color=grout, contrast=g.uniform(0.5, 1.5)),
        Material.CARPET: dict(scale=g.uniform(0.003, 0.012), contrast=g.uniform(0.2, 0.5)),
        Material.FABRIC: dict(scale=g.uniform(0.002, 0.008), contrast=g.uniform(0.1, 0.4)),
        Material.METAL: dict(scale=g.uniform(0.1, 0.6), contrast=g.uniform(0.05, 0.25), axis=int(g.integers(0, 2))),
        Material.PLASTIC: dict(scale=g.uniform(0.1, 0.4), contrast=g.uniform(0.02, 0.1)),
        Material.LEAF: dict(scale=g.uniform(0.03, 0.08), contrast=g.uniform(0.7, 1.3)),
        Material.SCREEN: dict(scale=g.uniform(0.3, 1.0), contrast=g.uniform(0.1, 0.5)),
    }
    return {int(m): MaterialStyle(m, seed=int(s), **out[m]) for m, s in zip(Material, seeds)}


def _hsv(h: float, s: float, v: float) -> NDArray[np.float32]:
    h6 = (h % 1.0) * 6.0
    c = v * s
    x = c * (1 - abs(h6 % 2 - 1))
    rgb = [(c, x, 0), (x, c, 0), (0, c, x), (0, x, c), (x, 0, c), (c, 0, x)][int(h6) % 6]
    return (np.array(rgb, dtype=np.float32) + (v - c)).clip(0, 1)


def sample_palette(rng: np.random.Generator | int | None = None) -> dict[int, NDArray[np.float32]]:
    """A plausible base colour (sRGB, [0, 1]) for each :class:`Material`, for one room.

    Walls off-white to pastel, wood browns, tiles white / grey / terracotta /
    tinted, carpets muted, leaves greens, screens near black, fabric and
    plastic any hue.

    Examples
    --------
    >>> p = sample_palette(0)
    >>> bool(p[Material.SCREEN].max() < 0.15 and p[Material.PLASTER].min() > 0.4)
    True
    """
    g = _rng(rng)
    u = g.uniform
    tile_kind = g.random()
    if tile_kind < 0.5:
        tile = _hsv(u(0, 1), u(0, 0.08), u(0.55, 0.95))
    elif tile_kind < 0.75:
        tile = _hsv(u(0.02, 0.07), u(0.4, 0.65), u(0.5, 0.75))
    else:
        tile = _hsv(u(0.3, 0.65), u(0.1, 0.35), u(0.5, 0.85))
    return {
        int(Material.PLASTER): _hsv(u(0, 1), u(0.0, 0.22), u(0.72, 0.95)),
        int(Material.WOOD): _hsv(u(0.05, 0.1), u(0.35, 0.7), u(0.3, 0.8)),
        int(Material.TILE): tile,
        int(Material.CARPET): _hsv(u(0, 1), u(0.05, 0.4), u(0.25, 0.7)),
        int(Material.FABRIC): _hsv(u(0, 1), u(0.1, 0.7), u(0.2, 0.8)),
        int(Material.METAL): _hsv(u(0, 1), u(0.0, 0.05), u(0.45, 0.8)),
        int(Material.PLASTIC): _hsv(u(0, 1), u(0.0, 0.6), u(0.3, 0.95)),
        int(Material.LEAF): _hsv(u(0.22, 0.38), u(0.4, 0.8), u(0.25, 0.55)),
        int(Material.SCREEN): _hsv(u(0.55, 0.7), u(0.0, 0.3), u(0.03, 0.1)),
    }


# --------------------------------------------------------------------------- noise

@lru_cache(maxsize=64)
def _table(seed: int) -> F32:
    """Random lattice values in [-1, 1): 256 x 256 cells, stored 257 x 257 with the
    first row and column repeated at the end so that neighbours need no wrapping."""
    t = np.random.default_rng(seed).uniform(-1.0, 1.0, (_TABLE, _TABLE)).astype(np.float32)
    t = np.pad(t, ((0, 1), (0, 1)), mode="wrap").ravel()
    t.setflags(write=False)
    return t


def _cell(i: np.ndarray, j: np.ndarray, seed: int) -> F32:
    """A random value in [-1, 1) per integer cell (i, j), periodic every 256 cells."""
    i = np.asarray(i, np.int64) & (_TABLE - 1)
    j = np.asarray(j, np.int64) & (_TABLE - 1)
    return _table(seed)[j * (_TABLE + 1) + i]


def _noise(s: F32, t: F32, seed: int, fs: float, ft: float, octaves: int = 1,
           dxs: F32 | None = None, dxt: F32 | None = None, gain: float = 0.5) -> F32:
    tab = _table(seed)
    row = _TABLE + 1
    out = np.zeros(s.shape, np.float32)
    norm = 0.0
    for o in range(octaves):
        m = float(2**o)
        fade = None
        if dxs is not None and dxt is not None:
            # Fade an octave out as its wavelength nears the pixel footprint (no aliasing).
            ratio = np.maximum(dxs * np.float32(fs * m), dxt * np.float32(ft * m))
            fade = np.clip(1.5 - 2.0 * ratio, 0.0, 1.0)
        amp = gain**o
        norm += amp
        if fade is not None and not fade.any():
            continue  # finer than every pixel here
        x = s * np.float32(fs * m) + np.float32(17.31 * o)
        y = t * np.float32(ft * m) + np.float32(31.77 * o)
        xf, yf = np.floor(x), np.floor(y)
        fx, fy = x - xf, y - yf
        xi = xf.astype(np.int32)
        xi &= _TABLE - 1
        idx = yf.astype(np.int32)
        idx &= _TABLE - 1
        idx *= row
        idx += xi
        a, b = np.take(tab, idx), np.take(tab, idx + 1)
        c, d = np.take(tab, idx + row), np.take(tab, idx + (row + 1))
        sx = fx * fx * (3 - 2 * fx)
        sy = fy * fy * (3 - 2 * fy)
        b -= a
        b *= sx
        a += b  # bottom edge
        d -= c
        d *= sx
        c += d  # top edge
        c -= a
        c *= sy
        a += c
        if fade is not None:
            a *= fade
        a *= np.float32(amp)
        out += a
    return out / np.float32(norm)


def value_noise(coords: ArrayLike, seed: int = 0, frequency: float = 1.0, octaves: int = 1) -> F32:
    """Smooth 2D value noise (fractal when ``octaves > 1``), deterministic in ``seed``.

    Parameters
    ----------
    coords : (..., 2) float
        Positions (metres on a surface).
    seed : int
    frequency : float
        Lattice cells per metre of the first octave.
    octaves : int
        Octave ``k`` has frequency ``frequency * 2**k`` and weight ``0.5**k``.

    Returns
    -------
    noise : (...) float32 in [-1, 1]
        Periodic every ``256 / frequency`` metres.

    Examples
    --------
    >>> n = value_noise(np.random.default_rng(0).uniform(0, 10, (1000, 2)), seed=1, frequency=2.0, octaves=3)
    >>> bool(np.abs(n).max() <= 1.0), bool(n.std() > 0.1)
    (True, True)
    """
    c = float_array(coords, "coords", last=2).astype(np.float32)
    if not (np.isfinite(frequency) and frequency > 0):
        raise ValueError(f"frequency: expected a positive number of cells per metre, got {frequency!r}")
    if int(octaves) < 1:
        raise ValueError(f"octaves: expected >= 1, got {octaves!r}")
    return _noise(c[..., 0], c[..., 1], int(seed), float(frequency), float(frequency), int(octaves))


def _pulse(x: F32, period: float, width: float, dx: F32) -> F32:
    """Fraction of the footprint ``[x - dx/2, x + dx/2]`` covered by lines of ``width``
    centred on the multiples of ``period`` (a box-filtered pulse train)."""
    if width <= 0:
        return np.zeros_like(x)
    nw = np.float32(min(width / period, 1.0))
    w = dx / np.float32(period)
    xc = (x + np.float32(width / 2)) / np.float32(period)
    # Footprints far below a line width are point samples (the filtered difference would lose precision).
    point = (xc - np.floor(xc) < nw).astype(np.float32)
    wide = w > np.float32(0.02) * nw
    if not np.any(wide):
        return point
    w = np.maximum(w, np.float32(1e-6))
    x0 = xc - w / 2
    x1 = x0 + w

    def integral(t: F32) -> F32:
        f = np.floor(t)
        return f * nw + np.minimum(t - f, nw)

    return np.where(wide, np.clip((integral(x1) - integral(x0)) / w, 0.0, 1.0), point)


def _step(x: F32, dx: F32) -> F32:
    """Box-filtered step: fraction of the footprint of width ``dx`` where ``x > 0``."""
    return np.clip(x / np.maximum(dx, np.float32(1e-6)) + 0.5, 0.0, 1.0)


def _surface_frame(points: F32, normals: F32) -> tuple[F32, F32, NDArray[np.int64]]:
    """2D surface coordinates by dominant normal axis and the index of that axis."""
    dom = np.argmax(np.abs(normals), axis=1)
    s = np.take_along_axis(points, _S_AXIS[dom][:, None], axis=1)[:, 0]
    t = np.take_along_axis(points, _T_AXIS[dom][:, None], axis=1)[:, 0]
    return s.astype(np.float32), t.astype(np.float32), dom


def _footprints(dom: NDArray[np.int64], normals: F32, rays: F32 | None, footprint: F32) -> tuple[F32, F32]:
    """Extent of the pixel footprint along the two surface axes (anisotropic at grazing angles)."""
    if rays is None:
        return footprint, footprint
    cos = np.maximum(np.abs(np.einsum("ij,ij->i", normals, rays)), np.float32(0.05))
    ds = np.take_along_axis(rays, _S_AXIS[dom][:, None], axis=1)[:, 0]
    dt = np.take_along_axis(rays, _T_AXIS[dom][:, None], axis=1)[:, 0]
    return (footprint * np.sqrt(1 + (ds / cos) ** 2)).astype(np.float32), \
        (footprint * np.sqrt(1 + (dt / cos) ** 2)).astype(np.float32)


def _mix(a: F32, b: F32 | NDArray, w: F32) -> F32:
    return a + (b - a) * w[:, None]


def _albedo(style: MaterialStyle, s: F32, t: F32, dxs: F32, dxt: F32, base: F32) -> F32:
    m, k = style.material, np.float32(style.contrast)
    seed = style.seed
    if m == Material.PLASTER:
        low = _noise(s, t, seed, 1 / style.scale, 1 / style.scale, 3, dxs, dxt)
        fine = _noise(s, t, seed + 1, 60.0, 60.0, 2, dxs, dxt)
        return base * (1 + k * (0.8 * low + 0.25 * fine))[:, None]
    if m == Material.WOOD:
        along, across = (s, t) if style.axis == 0 else (t, s)
        dxa, dxc = (dxs, dxt) if style.axis == 0 else (dxt, dxs)
        row = np.floor(across / np.float32(style.scale))
        along = along + (_cell(row, 0, seed) * 0.5 + 0.5) * np.float32(style.length)
        col = np.floor(along / np.float32(style.length))
        tone = 1 + 0.14 * k * _cell(row, col, seed + 1)
        grain = _noise(along, across, seed + 2, 1.5, 1 / 0.004, 2, dxa, dxc)
        streak = _noise(along, across, seed + 3, 0.6, 1 / 0.03, 2, dxa, dxc)
        out = base * (tone * (1 + k * (0.12 * grain + 0.1 * streak)))[:, None]
        gaps = 1 - (1 - _pulse(across, style.scale, style.line_width, dxc)) * \
            (1 - _pulse(along, style.length, style.line_width, dxa))
        line = style.line_color if style.line_color is not None else base * 0.35
        return _mix(out, line, gaps)
    if m == Material.TILE:
        i, j = np.floor(s / np.float32(style.scale)), np.floor(t / np.float32(style.length))
        tone = 1 + 0.05 * k * _cell(i, j, seed)
        speck = _noise(s, t, seed + 1, 40.0, 40.0, 2, dxs, dxt)
        cloud = _noise(s, t, seed + 2, 4.0, 4.0, 2, dxs, dxt)
        out = base * (tone * (1 + k * (0.03 * speck + 0.04 * cloud)))[:, None]
        grout = 1 - (1 - _pulse(s, style.scale, style.line_width, dxs)) * \
            (1 - _pulse(t, style.length, style.line_width, dxt))
        line = style.line_color if style.line_color is not None else base * 0.6
        return _mix(out, line, grout)
    if m == Material.CARPET:
        fleck = _noise(s, t, seed, 1 / style.scale, 1 / style.scale, 2, dxs, dxt)
        blotch = _noise(s, t, seed + 1, 2.5, 2.5, 3, dxs, dxt)
        return base * (1 + k * (0.6 * fleck + 0.35 * blotch))[:, None]
    if m == Material.FABRIC:
        p = np.float32(2 * np.pi / style.scale)
        fade = np.clip(1.5 - 2.0 * np.maximum(dxs, dxt) / np.float32(style.scale), 0.0, 1.0)
        weave = np.sin(s * p) * np.sin(t * p) * fade
        folds = _noise(s, t, seed, 3.0, 3.0, 2, dxs, dxt)
        fuzz = _noise(s, t, seed + 1, 0.5 / style.scale, 0.5 / style.scale, 1, dxs, dxt)
        return base * (1 + k * (0.35 * weave + 0.5 * folds + 0.25 * fuzz))[:, None]
    if m == Material.METAL:
        fa, fc = (1 / style.scale, 1 / 0.002) if style.axis == 0 else (1 / 0.002, 1 / style.scale)
        brush = _noise(s, t, seed, fa, fc, 2, dxs, dxt)
        sheen = _noise(s, t, seed + 1, 1.2, 1.2, 1, dxs, dxt)
        return base * (1 + k * (0.5 * brush + 0.8 * sheen))[:, None]
    if m == Material.LEAF:
        f = 1 / style.scale
        n = _noise(s, t, seed, f, f, 3, dxs, dxt)
        vein = _noise(s, t, seed + 1, 3 * f, 3 * f, 1, dxs, dxt)
        out = base * (1 + k * (0.45 * n + 0.15 * vein))[:, None]
        yellow = np.array([0.55, 0.6, 0.2], np.float32)
        out = _mix(out, yellow * base.max(axis=1, keepdims=True) * 1.2, np.clip(k * 0.4 * vein, 0, 0.4))
        gaps = np.clip((-n - 0.35) * 4 * k, 0, 0.8)  # dark holes between leaves
        return out * (1 - gaps)[:, None]
    if m == Material.SCREEN:
        refl = _noise(s, t, seed, 1 / style.scale, 1 / style.scale, 2, dxs, dxt)
        return base + k * 0.06 * (refl[:, None] + 1)
    # PLASTIC and unknown ids
    n = _noise(s, t, seed, 1 / style.scale, 1 / style.scale, 2, dxs, dxt)
    return base * (1 + k * n)[:, None]


def material_albedo(style: MaterialStyle, points: ArrayLike, normals: ArrayLike, base_colors: ArrayLike,
                    footprint: ArrayLike | None = None, rays: ArrayLike | None = None) -> F32:
    """sRGB albedo of a material's pattern at surface points.

    Parameters
    ----------
    style : MaterialStyle
    points : (N, 3) float
        World hit points (metres).
    normals : (N, 3) float
        Unit surface normals (pick the 2D surface coordinates, see the module note).
    base_colors : (N, 3) or (3,) float in [0, 1]
        Base colour the pattern modulates.
    footprint : (N,) float or float, optional
        Width in metres of the pixel's footprint seen head-on (depth times
        pixel angle); lines and noise are filtered over it. None: point sampling.
    rays : (N, 3) float, optional
        Unit view rays; widen the footprint along the surface at grazing angles.

    Returns
    -------
    albedo : (N, 3) float32 in [0, 1]

    Examples
    --------
    >>> tile = MaterialStyle(Material.TILE, scale=0.5, length=0.5, line_width=0.01, line_color=(0, 0, 0))
    >>> pts = np.array([[0.25, 0.25, 0.0], [0.5, 0.25, 0.0]])
    >>> a = material_albedo(tile, pts, [[0, 0, 1]] * 2, (0.9, 0.9, 0.9))
    >>> bool(a[0].min() > 0.7), a[1].tolist()          # tile centre, grout line
    (True, [0.0, 0.0, 0.0])
    """
    p = float_array(points, "points")
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"points: expected shape (N, 3), got {p.shape}")
    n = float_array(normals, "normals")
    if n.shape != p.shape:
        raise ValueError(f"normals: expected shape {p.shape}, got {n.shape}")
    base = float_array(base_colors, "base_colors")
    base = np.broadcast_to(base, p.shape) if base.shape == (3,) else base
    if base.shape != p.shape:
        raise ValueError(f"base_colors: expected shape (3,) or {p.shape}, got {base.shape}")
    p32, n32 = p.astype(np.float32), n.astype(np.float32)
    s, t, dom = _surface_frame(p32, n32)
    if footprint is None:
        fp = np.zeros(len(p), np.float32)
    else:
        fp = np.broadcast_to(float_array(footprint, "footprint"), (len(p),)).astype(np.float32)
    r = None if rays is None else float_array(rays, "rays", last=3).astype(np.float32)
    dxs, dxt = _footprints(dom, n32, r, fp)
    return np.clip(_albedo(style, s, t, dxs, dxt, base.astype(np.float32)), 0.0, 1.0).astype(np.float32)


# --------------------------------------------------------------------------- lights

@dataclass(frozen=True, eq=False)
class PointLight:
    """A spherical light: Lambert shading from its centre, soft shadows from its radius.

    Attributes
    ----------
    position : (3,) float
        World metres.
    color : (3,) float
        Linear RGB tint, [0, 1].
    intensity : float
        Relative power (the shader's auto exposure fixes the absolute scale).
    radius : float
        Metres; shadow rays aim at random points of the cube of this half-size
        around the centre (soft shadows).
    """

    position: ArrayLike
    color: ArrayLike = (1.0, 1.0, 1.0)
    intensity: float = 1.0
    radius: float = 0.1

    def __post_init__(self) -> None:
        p = float_array(self.position, "position")
        if p.shape != (3,):
            raise ValueError(f"position: expected shape (3,), got {p.shape}")
        object.__setattr__(self, "position", p)
        object.__setattr__(self, "color", _color3(self.color, "color"))
        if not (np.isfinite(self.intensity) and self.intensity > 0):
            raise ValueError(f"intensity: expected a positive number, got {self.intensity!r}")
        if not (np.isfinite(self.radius) and self.radius >= 0):
            raise ValueError(f"radius: expected a non-negative length in metres, got {self.radius!r}")


def sample_lights(meshes: "RenderMesh | Sequence[RenderMesh]", rng: np.random.Generator | int | None = None,
                  n: int | None = None, drop: float = 0.25, clearance: float = 0.35,
                  backend: Literal["auto", "open3d", "embree"] = "auto") -> list[PointLight]:
    """A few ceiling lights at random points of the ceiling faces (label 2).

    Parameters
    ----------
    meshes : RenderMesh or sequence of RenderMesh
    rng : Generator or int seed
    n : int, optional
        Number of lights; default 1 to 3 at random.
    drop : float
        Metres below the ceiling.
    clearance : float
        Wanted free distance (m) from the light to any surface in 8 horizontal
        directions and below; of 32 random candidates the first that has it
        is kept, else the one with the most room.
    backend : {"auto", "open3d", "embree"}
        Ray casting used for the clearance test.

    Returns
    -------
    list of PointLight
        Positions uniform by area over the ceiling (or, without ceiling faces,
        in the top of the scene's bounding box), colour between warm and cool
        white, intensity 0.6..1.4, radius 0.05..0.2 m but less than the
        light's free distance (so soft-shadow samples stay inside the room).
    """
    from .raycast import LABEL_CEILING, RayCaster, merge_meshes

    g = _rng(rng)
    mesh = merge_meshes(meshes)
    count = int(g.integers(1, 4)) if n is None else int(n)
    if count < 1:
        raise ValueError(f"n: expected at least one light, got {n!r}")
    if not (np.isfinite(drop) and drop > 0 and np.isfinite(clearance) and clearance >= 0):
        raise ValueError(f"drop, clearance: expected drop > 0 and clearance >= 0 metres, got {drop!r}, {clearance!r}")
    tri = mesh.vertices[mesh.faces[mesh.labels == LABEL_CEILING]]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    caster = RayCaster(mesh, backend)
    ang = np.arange(8) * (np.pi / 4)
    dirs = np.concatenate([np.column_stack([np.cos(ang), np.sin(ang), np.zeros(8)]), [[0.0, 0.0, -1.0]]])
    lights = []
    for _ in range(count):
        if area.sum() > 0:
            k = g.choice(len(tri), size=32, p=area / area.sum())
            ab = g.random((32, 2))
            ab = np.where(ab.sum(axis=1, keepdims=True) > 1, 1 - ab, ab)
            cand = tri[k, 0] + ab[:, :1] * (tri[k, 1] - tri[k, 0]) + ab[:, 1:] * (tri[k, 2] - tri[k, 0])
        else:
            lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
            cand = np.column_stack([g.uniform(lo[0], hi[0], 32), g.uniform(lo[1], hi[1], 32), np.full(32, hi[2])])
        cand = cand - [0.0, 0.0, drop]
        free = caster.cast(np.repeat(cand, len(dirs), axis=0), np.tile(dirs, (32, 1))).t.reshape(32, -1).min(axis=1)
        good = np.flatnonzero(free >= clearance)
        best = int(good[0]) if good.size else int(np.argmax(free))
        warm = g.random()
        color = (1 - warm) * np.array([0.92, 0.96, 1.0]) + warm * np.array([1.0, 0.82, 0.62])
        radius = min(float(g.uniform(0.05, 0.2)), 0.5 * float(min(free[best], drop)))
        lights.append(PointLight(cand[best], color, float(g.uniform(0.6, 1.4)), radius))
    return lights


# --------------------------------------------------------------------------- decor

@dataclass(frozen=True, eq=False)
class Decor:
    """Straight-edged room details drawn on the walls and ceiling.

    Attributes
    ----------
    skirting_height : float
        Height (m) of the skirting board along the bottom of the walls; 0 for none.
    skirting_color : (3,) float
    door_probability, window_probability : float
        Chance of a door / a window on each wall long enough to hold one.
    door_color, frame_color : (3,) float
    frame_width : float
        Width (m) of door and window frames.
    light_fixtures : bool
        Draw a glowing square panel on the ceiling above each light that hangs
        within 0.6 m of it.
    """

    skirting_height: float = 0.08
    skirting_color: ArrayLike = (0.94, 0.93, 0.9)
    door_probability: float = 0.3
    window_probability: float = 0.3
    door_color: ArrayLike = (0.7, 0.55, 0.38)
    frame_color: ArrayLike = (0.95, 0.95, 0.93)
    frame_width: float = 0.06
    light_fixtures: bool = True

    def __post_init__(self) -> None:
        for name in ("skirting_color", "door_color", "frame_color"):
            object.__setattr__(self, name, _color3(getattr(self, name), name))
        for name in ("skirting_height", "frame_width"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: expected a non-negative length in metres, got {v!r}")
        for name in ("door_probability", "window_probability"):
            v = float(getattr(self, name))
            if not 0 <= v <= 1:
                raise ValueError(f"{name}: expected a probability in [0, 1], got {v!r}")


def sample_decor(rng: np.random.Generator | int | None = None) -> Decor:
    """Random skirting height and colours, door / window chances, for one room."""
    g = _rng(rng)
    white = _hsv(g.uniform(0, 1), g.uniform(0, 0.05), g.uniform(0.85, 0.97))
    wood = _hsv(g.uniform(0.05, 0.1), g.uniform(0.3, 0.6), g.uniform(0.3, 0.75))
    return Decor(
        skirting_height=float(g.choice([0.0, 0.06, 0.08, 0.1, 0.12, 0.15])),
        skirting_color=white if g.random() < 0.7 else wood,
        door_probability=float(g.uniform(0.15, 0.5)),
        window_probability=float(g.uniform(0.1, 0.5)),
        door_color=wood if g.random() < 0.6 else white * 0.97,
        frame_color=white if g.random() < 0.7 else wood * 0.9,
        frame_width=float(g.uniform(0.04, 0.09)),
        light_fixtures=bool(g.random() < 0.8),
    )


@dataclass(frozen=True)
class Opening:
    """A door or window drawn on a wall plane (texture only, the wall stays a wall).

    Attributes
    ----------
    kind : {"door", "window"}
    normal_axis : {0, 1}
        The wall is the plane ``x = offset`` (0, label 3) or ``y = offset`` (1, label 4).
    offset : float
    s0, s1 : float
        Extent along the wall: along y when ``normal_axis == 0``, along x otherwise.
    z0, z1 : float
        Bottom and top (world z).
    """

    kind: Literal["door", "window"]
    normal_axis: int
    offset: float
    s0: float
    s1: float
    z0: float
    z1: float


def _wall_runs(mesh: "RenderMesh") -> list[tuple[int, float, float, float, float, float]]:
    """Connected stretches of coplanar wall faces: (normal_axis, offset, s0, s1, z0, z1)."""
    from .raycast import LABEL_WALL_X, LABEL_WALL_Y

    out = []
    for label, axis in ((LABEL_WALL_X, 0), (LABEL_WALL_Y, 1)):
        tri = mesh.vertices[mesh.faces[mesh.labels == label]]
        if not len(tri):
            continue
        c = tri[:, :, axis]
        planar = (c.max(axis=1) - c.min(axis=1)) < 1e-6
        tri, off = tri[planar], c[planar].mean(axis=1)
        s = tri[:, :, 1 - axis]
        z = tri[:, :, 2]
        key = np.round(off / 1e-4).astype(np.int64)
        for k in np.unique(key):
            sel = key == k
            lo, hi = s[sel].min(axis=1), s[sel].max(axis=1)
            zlo, zhi = z[sel].min(axis=1), z[sel].max(axis=1)
            order = np.argsort(lo)
            cur = None
            for i in order:
                if cur is not None and lo[i] <= cur[1] + 1e-6:
                    cur = [cur[0], max(cur[1], hi[i]), min(cur[2], zlo[i]), max(cur[3], zhi[i])]
                else:
                    if cur is not None:
                        out.append((axis, float(off[sel].mean()), *cur))
                    cur = [lo[i], hi[i], zlo[i], zhi[i]]
            out.append((axis, float(off[sel].mean()), *map(float, cur)))
    return out


def place_openings(meshes: "RenderMesh | Sequence[RenderMesh]", decor: Decor | None = None,
                   rng: np.random.Generator | int | None = None) -> list[Opening]:
    """Random doors and windows on the walls (faces labelled 3 or 4) of a scene.

    A door (0.75..0.95 m wide, 1.95..2.1 m high, standing on the wall's bottom)
    goes on a wall at least 1.2 m long and 2.2 m high with
    ``decor.door_probability``; a window (sill 0.8..1 m, top 1.9..2.2 m)
    takes the longest free stretch left with ``decor.window_probability``.
    Openings keep 0.15 m from wall ends and 0.3 m from each other.

    Examples
    --------
    >>> from panogeom.raycast import room_meshes
    >>> room = room_meshes([[0, 0], [5, 0], [5, 4], [0, 4]], ceiling_z=2.6)
    >>> ops = place_openings(room, Decor(door_probability=1.0, window_probability=0.0), rng=0)
    >>> len(ops), {o.kind for o in ops}
    (4, {'door'})
    """
    from .raycast import merge_meshes

    decor = Decor() if decor is None else decor
    g = _rng(rng)
    out: list[Opening] = []
    for axis, off, s0, s1, z0, z1 in _wall_runs(merge_meshes(meshes)):
        free = [(s0 + 0.15, s1 - 0.15)]
        if g.random() < decor.door_probability and s1 - s0 >= 1.2 and z1 - z0 >= 2.2:
            # A door leaves 0.15 m of wall each side: at most s1 - s0 - 0.3 wide (>= 0.9 here).
            w = g.uniform(0.75, min(0.95, s1 - s0 - 0.3))
            a = g.uniform(s0 + 0.15, s1 - 0.15 - w)
            out.append(Opening("door", axis, off, a, a + w, z0, z0 + min(g.uniform(1.95, 2.1), z1 - z0 - 0.15)))
            free = [(s0 + 0.15, a - 0.3), (a + w + 0.3, s1 - 0.15)]
        if g.random() < decor.window_probability:
            lo, hi = max(free, key=lambda f: f[1] - f[0])
            sill, top = z0 + g.uniform(0.8, 1.0), min(z0 + g.uniform(1.9, 2.2), z1 - 0.15)
            if hi - lo >= 0.7 and top - sill >= 0.5:
                w = g.uniform(0.7, min(2.0, hi - lo))
                a = g.uniform(lo, hi - w)
                out.append(Opening("window", axis, off, a, a + w, sill, top))
    return out


# --------------------------------------------------------------------------- camera model

@dataclass(frozen=True, eq=False)
class PostProcess:
    """Camera model applied after lighting.

    Attributes
    ----------
    exposure : float
        Multiplier after auto exposure (which maps the 97th percentile of
        luminance to 0.85 linear).
    gamma : float
        Output encoding gamma (2.2 ~ sRGB).
    white_balance : (3,) float
        Per-channel gains.
    blur_sigma : float
        Gaussian blur in pixels (0 for none), wrapping across the seam.
    noise_sigma : float
        Sensor noise std in linear units (0 for none): read noise plus shot
        noise proportional to the square root of the signal.
    """

    exposure: float = 1.0
    gamma: float = 2.2
    white_balance: ArrayLike = (1.0, 1.0, 1.0)
    blur_sigma: float = 0.0
    noise_sigma: float = 0.0

    def __post_init__(self) -> None:
        wb = float_array(self.white_balance, "white_balance")
        if wb.shape != (3,) or np.any(wb <= 0):
            raise ValueError(f"white_balance: expected three positive gains, got {self.white_balance!r}")
        object.__setattr__(self, "white_balance", wb.astype(np.float32))
        for name in ("exposure", "gamma"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: expected a positive number, got {v!r}")
        for name in ("blur_sigma", "noise_sigma"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: expected a non-negative number, got {v!r}")


def sample_post(rng: np.random.Generator | int | None = None) -> PostProcess:
    """Random exposure (x0.6..1.6), gamma (1.9..2.5), white balance (~6 % per channel),
    blur (none in 40 % of cases, else up to 1.2 px) and sensor noise."""
    g = _rng(rng)
    wb = np.exp(g.normal(0.0, 0.06, 3))
    return PostProcess(
        exposure=float(np.clip(np.exp(g.normal(0.0, 0.25)), 0.6, 1.6)),
        gamma=float(g.uniform(1.9, 2.5)),
        white_balance=wb / wb.mean(),
        blur_sigma=0.0 if g.random() < 0.4 else float(g.uniform(0.3, 1.2)),
        noise_sigma=float(g.uniform(0.003, 0.02)),
    )


def _cv2():
    try:
        import cv2
    except ImportError as exc:  # pragma: no cover - dependency of the package
        raise ImportError("panogeom's shading needs OpenCV: pip install opencv-contrib-python-headless") from exc
    return cv2


def _blur_wrap(img: F32, sigma: float) -> F32:
    """Gaussian blur of an equirect image, wrapping across the left/right seam."""
    cv2 = _cv2()
    pad = int(np.ceil(3 * sigma)) + 1
    wide = np.concatenate([img[:, -pad:], img, img[:, :pad]], axis=1)
    out = cv2.GaussianBlur(wide, (0, 0), sigmaX=sigma, sigmaY=sigma, borderType=cv2.BORDER_REFLECT)
    return out[:, pad:-pad]


# --------------------------------------------------------------------------- shading

def _rect(s: F32, z: F32, s0: float, s1: float, z0: float, z1: float, dxs: F32, dxt: F32) -> F32:
    return _step(s - np.float32(s0), dxs) * _step(np.float32(s1) - s, dxs) * \
        _step(z - np.float32(z0), dxt) * _step(np.float32(z1) - z, dxt)


def shade(result: "RenderResult", meshes: "RenderMesh | Sequence[RenderMesh]",
          materials: Mapping[int, MaterialStyle] | None = None, lights: Sequence[PointLight] | None = None,
          rng: np.random.Generator | int | None = None, *, decor: Decor | None = None,
          openings: Sequence[Opening] | None = None, post: PostProcess | None = None,
          ambient: float = 0.5, shadows: bool = True, background: ArrayLike = (0.0, 0.0, 0.0),
          backend: Literal["auto", "open3d", "embree"] = "auto") -> NDArray[np.uint8]:
    """RGB panorama of a ray-cast scene: textures, decor, lights, camera model.

    Parameters
    ----------
    result : RenderResult
        From :func:`panogeom.raycast.raycast_equirect` on ``meshes``.
    meshes : RenderMesh or sequence of RenderMesh
        The same scene (per-face base colours and materials are read from it).
    materials : mapping material id -> MaterialStyle, optional
        Patterns (:func:`sample_styles`); ids missing here use :func:`default_style`.
    lights : sequence of PointLight, optional
        Default: :func:`sample_lights` from ``rng``.
    rng : Generator or int seed
        Drives default lights, door / window placement, soft-shadow jitter and
        sensor noise. The same seed gives the same image.
    decor : Decor, optional
        Default ``Decor()``; skirting boards are drawn on wall faces (labels
        3, 4) within ``skirting_height`` above the lowest floor face.
    openings : sequence of Opening, optional
        Default: :func:`place_openings` with ``decor`` and ``rng``.
    post : PostProcess, optional
        Default ``PostProcess()`` (no blur, no noise).
    ambient : float
        Soft ambient light as a fraction of the mean direct light.
    shadows : bool
        Cast one shadow ray per pixel and light (on a grid of at most 1024
        columns, upsampled beyond) towards a random point of the light, and
        smooth the visibility (soft shadows). Open3D makes this cheap;
        libigl's Embree binding (one Python call per ray) is slow here.
    background : (3,) float
        sRGB colour of pixels whose ray hits nothing.
    backend : {"auto", "open3d", "embree"}
        Ray-casting backend for shadows.

    Returns
    -------
    image : (H, W, 3) uint8

    Convention: Lambert reflection in linear RGB, ``albedo * (ambient +
    sum_l I_l c_l max(0, n.l) V_l / (1 + d_l^2))`` with ``V_l`` the soft-shadow
    visibility; albedo is the sRGB base colour times the pattern, decoded with
    gamma 2.2.

    Examples
    --------
    >>> from panogeom.raycast import raycast_equirect, room_meshes
    >>> room = room_meshes([[-2, -2], [2, -2], [2, 2], [-2, 2]], ceiling_z=2.5)
    >>> r = raycast_equirect(room, 64, [0.0, 0.0, 1.6])
    >>> img = shade(r, room, sample_styles(0), rng=0)
    >>> img.shape, img.dtype.name
    ((32, 64, 3), 'uint8')
    """
    from .raycast import (LABEL_CEILING, LABEL_FLOOR, LABEL_WALL_X, LABEL_WALL_Y, RayCaster, merge_meshes)

    mesh = merge_meshes(meshes)
    if mesh.n_faces != result.n_faces:
        raise ValueError(f"meshes: expected the scene of the render ({result.n_faces} faces), "
                         f"got {mesh.n_faces} faces")
    if not (np.isfinite(ambient) and ambient >= 0):
        raise ValueError(f"ambient: expected a non-negative fraction, got {ambient!r}")
    bg = _color3(background, "background")
    g = _rng(rng)
    decor = Decor() if decor is None else decor
    post = PostProcess() if post is None else post
    materials = {} if materials is None else dict(materials)
    lights = sample_lights(mesh, g, backend=backend) if lights is None else list(lights)
    for i, light in enumerate(lights):
        if not isinstance(light, PointLight):
            raise ValueError(f"lights[{i}]: expected a PointLight, got {type(light).__name__}")
    if openings is None:
        openings = place_openings(mesh, decor, g)

    H, W = result.height, result.width
    flat = np.flatnonzero(result.face_ids.ravel() >= 0)
    if flat.size == H * W:  # closed scene: every pixel hit, no gathers needed
        flat = slice(None)
    fid = result.face_ids.ravel()[flat]
    P = result.points.reshape(-1, 3)[flat]
    Nrm = result.normals.reshape(-1, 3)[flat]
    D = result.rays.reshape(-1, 3)[flat]
    depth = result.depth.ravel()[flat]
    labels = mesh.labels[fid]
    footprint = depth * np.float32(np.pi / H)
    s, t, dom = _surface_frame(P, Nrm)
    dxs, dxt = _footprints(dom, Nrm, D, footprint)

    # Albedo: material patterns.
    base = mesh.colors[fid]
    mat = mesh.material_ids[fid]
    alb = np.empty_like(base)
    for m in np.unique(mat):
        sel = np.flatnonzero(mat == m)
        style = materials.get(int(m)) or default_style(int(m))
        alb[sel] = _albedo(style, s[sel], t[sel], dxs[sel], dxt[sel], base[sel])
    emission = np.zeros_like(alb)
    glow = np.zeros(len(fid), np.float32)  # emission strength relative to the scene's bright level

    # Decor on walls: skirting boards, then door and window frames over them.
    wall = np.flatnonzero((labels == LABEL_WALL_X) | (labels == LABEL_WALL_Y))
    floor_faces = mesh.labels == LABEL_FLOOR
    if wall.size and decor.skirting_height > 0 and np.any(floor_faces):
        floor_z = np.float32(mesh.vertices[mesh.faces[floor_faces]][:, :, 2].min())
        h = P[wall, 2] - floor_z
        board = _step(np.float32(decor.skirting_height) - h, dxt[wall])
        groove = _pulse(h - np.float32(decor.skirting_height - 0.012), 1e6, 0.004, dxt[wall])
        color = decor.skirting_color * (1 - 0.35 * groove)[:, None]
        alb[wall] = _mix(alb[wall], color, board)
    for op in openings:
        if wall.size == 0:
            break
        axis = op.normal_axis
        on = wall[np.abs(P[wall, axis] - np.float32(op.offset)) < 2e-3]
        if on.size == 0:
            continue
        ws, wz = P[on, 1 - axis], P[on, 2]
        ds, dz = dxs[on], dxt[on]
        fw = decor.frame_width
        outer = _rect(ws, wz, op.s0 - fw, op.s1 + fw, op.z0 - (fw if op.kind == "window" else 0), op.z1 + fw, ds, dz)
        inner = _rect(ws, wz, op.s0, op.s1, op.z0, op.z1, ds, dz)
        edge = outer - _rect(ws, wz, op.s0 - fw + 0.006, op.s1 + fw - 0.006,
                             op.z0 - (fw - 0.006 if op.kind == "window" else 0), op.z1 + fw - 0.006, ds, dz)
        frame = decor.frame_color * (1 - 0.3 * edge)[:, None]
        a = _mix(alb[on], frame, outer)
        if op.kind == "door":
            hgt = op.z1 - op.z0
            panels = np.zeros(on.size, np.float32)
            for lo, hi in ((0.12, 0.45), (0.55, 0.88)):
                box = (op.s0 + 0.12, op.s1 - 0.12, op.z0 + lo * hgt, op.z0 + hi * hgt)
                panels += _rect(ws, wz, *box, ds, dz) - _rect(ws, wz, box[0] + 0.012, box[1] - 0.012,
                                                               box[2] + 0.012, box[3] - 0.012, ds, dz)
            door = decor.door_color * (1 - 0.35 * panels)[:, None]
            a = _mix(a, door, inner)
        else:
            mull = _pulse(ws - np.float32((op.s0 + op.s1) / 2), 1e6, 0.04, ds) + \
                _pulse(wz - np.float32(op.z0 + 0.6 * (op.z1 - op.z0)), 1e6, 0.04, dz)
            glass = inner * (1 - np.clip(mull, 0, 1))
            sky = np.array([0.75, 0.85, 1.0], np.float32) * (0.8 + 0.2 * (wz - op.z0) / (op.z1 - op.z0))[:, None]
            a = _mix(a, decor.frame_color, inner * np.clip(mull, 0, 1))
            a = _mix(a, np.float32(0.05) * sky, glass)
            emission[on] += sky * glass[:, None]
            glow[on] = np.maximum(glow[on], 1.3 * glass)
        alb[on] = a
    if decor.light_fixtures and lights:
        ceil = np.flatnonzero(labels == LABEL_CEILING)
        for light in lights:
            half = 0.12 + 0.5 * light.radius
            lp = light.position
            near = (P[ceil, 2] - np.float32(lp[2]) < 0.6).astype(np.float32)  # ceiling lights only, not lamps
            panel = near * _rect(P[ceil, 0], P[ceil, 1], lp[0] - half, lp[0] + half, lp[1] - half, lp[1] + half,
                                 dxs[ceil], dxt[ceil])
            rim = near * _rect(P[ceil, 0], P[ceil, 1], lp[0] - half - 0.02, lp[0] + half + 0.02,
                               lp[1] - half - 0.02, lp[1] + half + 0.02, dxs[ceil], dxt[ceil]) - panel
            alb[ceil] = _mix(alb[ceil], np.float32(0.55) * alb[ceil], rim)
            emission[ceil] += light.color[None, :] * panel[:, None]
            glow[ceil] = np.maximum(glow[ceil], 3.0 * panel)

    # Lighting in linear RGB.
    lin = _SRGB_DECODE[(np.clip(alb, 0.0, 1.0) * np.float32(_LUT - 1) + np.float32(0.5)).astype(np.int32)]
    direct = np.zeros_like(lin)
    visibility = _shadow_visibility(result, RayCaster(mesh, backend), lights, g) \
        if shadows and lights else [None] * len(lights)
    for light, vis in zip(lights, visibility):
        L = light.position.astype(np.float32)[None, :] - P
        d2 = np.einsum("ij,ij->i", L, L)
        cos = np.einsum("ij,ij->i", Nrm, L) / np.sqrt(np.maximum(d2, np.float32(1e-12)))
        lit = np.flatnonzero(cos > 0)
        w = np.float32(light.intensity) * cos[lit] / (1 + d2[lit])
        if vis is not None:
            w *= vis[flat][lit]
        direct[lit] += w[:, None] * light.color[None, :]
    mean_direct = float(direct.mean()) if direct.size else 0.0
    amb = np.float32(ambient * (mean_direct if mean_direct > 0 else 1.0))
    irr = direct + amb * (0.85 + 0.15 * Nrm[:, 2:3])
    radiance = lin * irr
    if radiance.size:
        bright = float(np.percentile(radiance @ _LUMA, 97)) or 1.0
        radiance += emission * (glow * np.float32(bright))[:, None]
        scale = np.float32(0.85 / bright * post.exposure)
    else:
        scale = np.float32(post.exposure)

    img = np.empty((H * W, 3), np.float32)
    img[:] = bg ** np.float32(2.2)
    img[flat] = radiance * scale
    img = img.reshape(H, W, 3) * post.white_balance
    if post.blur_sigma > 0:
        img = _blur_wrap(img, post.blur_sigma)
    if post.noise_sigma > 0:
        sigma = np.float32(post.noise_sigma) * (0.5 + np.sqrt(np.clip(img, 0, None)))
        img = img + sigma * g.standard_normal(img.shape, dtype=np.float32)
    # Gamma encoding through a table: linear [0, 1] in _LUT steps -> uint8.
    encode = (np.linspace(0.0, 1.0, _LUT) ** (1.0 / post.gamma) * 255.0 + 0.5).astype(np.uint8)
    return encode[(np.clip(img, 0.0, 1.0) * np.float32(_LUT - 1) + np.float32(0.5)).astype(np.int32)]


def _shadow_visibility(result: "RenderResult", caster, lights: Sequence[PointLight],
                       g: np.random.Generator) -> list[F32]:
    """Per light, the fraction of the light visible from each pixel's hit point, ``(H*W,)``.

    One shadow ray per pixel (on a grid of at most 1024 columns: every
    ``W // 1024``-th pixel) towards a random point of the light's cube, all
    lights in one batch; the visibility image is smoothed (soft lights) and
    brought back to full size.
    """
    H, W = result.height, result.width
    stride = max(1, W // 1024)
    rows = np.arange(H // stride) * stride + stride // 2
    cols = np.arange(W // stride) * stride + stride // 2
    P = result.points[rows][:, cols].reshape(-1, 3)
    Nrm = result.normals[rows][:, cols].reshape(-1, 3)
    hit = result.face_ids[rows][:, cols].ravel() >= 0
    origins, dirs, sel = [], [], []
    for light in lights:
        lp = light.position.astype(np.float32)
        lit = np.flatnonzero(hit)
        lit = lit[np.einsum("ij,ij->i", Nrm[lit], lp - P[lit]) > 0]
        o = P[lit] + np.float32(1e-3) * Nrm[lit]
        target = lp + np.float32(light.radius) * (2 * g.random((lit.size, 3), dtype=np.float32) - 1)
        origins.append(o)
        dirs.append(target - o)
        sel.append(lit)
    n = [len(s) for s in sel]
    if sum(n):
        visible = (caster.cast(np.concatenate(origins), np.concatenate(dirs)).t >= 0.999).astype(np.float32)
    else:
        visible = np.zeros(0, np.float32)
    out = []
    for light, lit, vis in zip(lights, sel, np.split(visible, np.cumsum(n)[:-1])):
        img = np.ones(len(P), np.float32)
        img[lit] = vis
        img = img.reshape(len(rows), len(cols))
        if light.radius > 0:
            img = _blur_wrap(img, 1.2)  # one sample per pixel is noisy in the penumbra
        if stride > 1:
            img = _cv2().resize(img, (W, H), interpolation=_cv2().INTER_LINEAR)
        out.append(img.ravel())
    return out
