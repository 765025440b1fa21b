"""floorplan.png and floorplan.svg: the room seen from above, drawn once with matplotlib and saved twice.

The drawing: a metric grid (every metre, every half metre when the room's
larger side is under :data:`SMALL_ROOM_M` metres), a scale bar, the floor
filled and the walls as thick lines, each wall's length in metres written
outside the room beside it, the object footprints filled in their class
colour (:func:`apps.export.colors.class_color`) with the class name and an
arrow towards the object's front, the camera position, and a title with
the floor area in m² and the wall height.

Convention:
    World x to the right, world y up (seen from above, z towards the
    viewer), metres, equal aspect; the camera is at the origin of x, y.
    The SVG keeps its texts as ``<text>`` elements (``svg.fonttype: none``),
    so they can be searched and edited.
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from apps.atomic import write_bytes
from layout.polygon import signed_area
from layout.scene import Scene

from .colors import FLOOR_RGB, class_color

if TYPE_CHECKING:  # pragma: no cover - typing only
    from matplotlib.figure import Figure

__all__ = ["SMALL_ROOM_M", "grid_step", "format_length", "floorplan_figure", "write_floorplan"]

#: Rooms whose larger side is shorter than this (metres) get a 0.5 m grid.
SMALL_ROOM_M = 4.0

_WALL_COLOR = "#2e3436"
_TEXT_OFFSET_M = 0.22  # wall-length labels sit this far outside the wall


def grid_step(extent_m: float) -> float:
    """Grid spacing in metres for a room whose larger side is ``extent_m`` metres.

    Examples
    --------
    >>> grid_step(5.6), grid_step(3.2)
    (1.0, 0.5)
    """
    if not (math.isfinite(extent_m) and extent_m > 0):
        raise ValueError(f"extent_m: expected a room size > 0 in metres, got {extent_m!r}")
    return 0.5 if extent_m < SMALL_ROOM_M else 1.0


def format_length(length_m: float) -> str:
    """The label of a wall length, e.g. ``"3.42 m"`` (centimetre precision).

    >>> format_length(3.4187)
    '3.42 m'
    """
    return f"{length_m:.2f} m"


def _rgb(c: tuple[int, int, int], alpha: float = 1.0) -> tuple[float, float, float, float]:
    return (c[0] / 255.0, c[1] / 255.0, c[2] / 255.0, alpha)


def _upright_deg(dx: float, dy: float) -> float:
    """Text angle along (dx, dy) in degrees, turned so the text never reads upside down."""
    a = math.degrees(math.atan2(dy, dx))
    if a > 90.0:
        a -= 180.0
    elif a <= -90.0:
        a += 180.0
    return a


def floorplan_figure(scene: Scene, *, width_in: float = 8.0) -> "Figure":
    """Draw the floor plan of ``scene`` into a new matplotlib figure (Agg canvas, no pyplot state).

    Parameters
    ----------
    scene : Scene
    width_in : float
        Figure width in inches; the height follows the room's aspect.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> s = Scene([[-2, -1.5], [2, -1.5], [2, 1.5], [-2, 1.5]], 2.6, 1.6)
    >>> ax = floorplan_figure(s).axes[0]
    >>> ax.get_title()
    'Floor plan: area 12.0 m², wall height 2.60 m'
    >>> sorted(t.get_text() for t in ax.texts if t.get_text().endswith(" m"))
    ['3.00 m', '3.00 m', '4.00 m', '4.00 m']
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import FancyArrow, Polygon
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    if not isinstance(scene, Scene):
        raise ValueError(f"scene: expected a layout.scene.Scene, got {type(scene).__name__}")
    if not (math.isfinite(width_in) and width_in > 0):
        raise ValueError(f"width_in: expected a figure width > 0 in inches, got {width_in!r}")
    floor = scene.floor
    pts = [floor, np.zeros((1, 2))] + [o.footprint for o in scene.objects]
    lo, hi = np.min([p.min(axis=0) for p in pts], axis=0), np.max([p.max(axis=0) for p in pts], axis=0)
    room = float(np.max(floor.max(axis=0) - floor.min(axis=0)))
    step = grid_step(room)
    margin = max(0.6, 0.12 * room)
    lo, hi = lo - margin, hi + margin
    aspect = (hi[1] - lo[1]) / (hi[0] - lo[0])
    fig = Figure(figsize=(width_in, min(max(width_in * aspect, 3.0), 3.0 * width_in) + 0.6))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    ax.set_aspect("equal")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_xticks(np.arange(math.ceil(lo[0] / step), math.floor(hi[0] / step) + 1) * step)
    ax.set_yticks(np.arange(math.ceil(lo[1] / step), math.floor(hi[1] / step) + 1) * step)
    ax.grid(True, color="#c8c8c8", linewidth=0.6, zorder=0)
    ax.set_axisbelow(True)
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x (m)", fontsize=8)
    ax.set_ylabel("y (m)", fontsize=8)

    ax.add_patch(Polygon(floor, closed=True, facecolor=_rgb(FLOOR_RGB, 0.18), edgecolor="none", zorder=1))
    ax.add_patch(Polygon(floor, closed=True, fill=False, edgecolor=_WALL_COLOR, linewidth=4.0,
                         joinstyle="miter", zorder=4))
    # A light box behind each label keeps it readable over lines (path effects would turn
    # the SVG's <text> elements into outlines).
    halo = {"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": "none", "alpha": 0.75}
    for wall in scene.walls:
        d = wall.end - wall.start
        at = wall.midpoint - _TEXT_OFFSET_M * wall.normal  # normals point into the room
        ax.text(at[0], at[1], format_length(wall.length), rotation=_upright_deg(d[0], d[1]),
                rotation_mode="anchor", ha="center", va="center", fontsize=8, color=_WALL_COLOR,
                bbox=halo, zorder=6)

    for obj in scene.objects:
        color = class_color(obj.cls)
        ax.add_patch(Polygon(obj.footprint, closed=True, facecolor=_rgb(color, 0.35),
                             edgecolor=_rgb(color), linewidth=1.5, zorder=2))
        front = np.array([math.cos(obj.yaw), math.sin(obj.yaw)])
        length = 0.5 * float(obj.size[0]) + 0.15
        head = min(0.18, 0.5 * length)
        ax.add_patch(FancyArrow(obj.center[0], obj.center[1], *(front * (length - head)), width=0.03,
                                head_width=1.1 * head, head_length=head, color=_rgb(color), zorder=3))
        ax.text(obj.center[0], obj.center[1], obj.cls, ha="center", va="center", fontsize=7,
                color="black", bbox=halo, zorder=5)

    ax.plot([0.0], [0.0], marker="o", markersize=7, color="black", markerfacecolor="white",
            markeredgewidth=1.8, zorder=7)
    ax.annotate("camera", (0.0, 0.0), xytext=(6, -10), textcoords="offset points", fontsize=7, zorder=7,
                bbox=halo)

    bar = 1.0 if room < 8.0 else 2.0
    ax.add_artist(AnchoredSizeBar(ax.transData, bar, format_length(bar).replace(".00", ""), loc="lower right",
                                  pad=0.4, borderpad=0.6, sep=3, size_vertical=0.05 * bar,
                                  frameon=True, fontproperties={"size": 8}))

    area = float(signed_area(floor))
    height = scene.wall_height
    h_text = "unknown" if height is None else format_length(height)
    ax.set_title(f"Floor plan: area {area:.1f} m², wall height {h_text}", fontsize=10)
    fig.tight_layout()
    return fig


def write_floorplan(scene: Scene, png_path: str | os.PathLike[str],
                    svg_path: str | os.PathLike[str] | None = None, *, dpi: int = 150) -> tuple[Path, ...]:
    """Write floorplan.png (and floorplan.svg when ``svg_path`` is given) from one drawing, atomically.

    Parameters
    ----------
    scene : Scene
    png_path : str or PathLike
    svg_path : str or PathLike, optional
    dpi : int
        Resolution of the PNG.

    Returns
    -------
    tuple of Path
        The files written, PNG first.
    """
    from matplotlib import rc_context

    targets = [(Path(png_path), ".png")] + ([] if svg_path is None else [(Path(svg_path), ".svg")])
    for p, suffix in targets:
        if p.suffix.lower() != suffix:
            raise ValueError(f"{p}: expected a {suffix} file name")
    if not (isinstance(dpi, int) and dpi > 0):
        raise ValueError(f"dpi: expected a positive integer, got {dpi!r}")
    # Fixed SVG ids and no dates, so the same scene gives the same bytes.
    with rc_context({"svg.fonttype": "none", "svg.hashsalt": "pano2cad"}):
        fig = floorplan_figure(scene)
        data = []
        for _, suffix in targets:
            buf = io.BytesIO()
            if suffix == ".png":
                fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": None})
            else:
                fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None})
            data.append(buf.getvalue())
    return tuple(write_bytes(p, d) for (p, _), d in zip(targets, data))
