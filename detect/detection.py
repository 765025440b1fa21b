"""Detection records and the detector protocols.

Two records, one per pixel frame, so the frame of a box is carried by its type:

- :class:`ImageDetection`: what a detector finds in one *perspective* image
  (a tile): class, score and an axis-aligned box in that image's pixels.
- :class:`Detection`: an object in the *panorama*: class, score, a seam-aware
  box in panorama pixels, an optional mask and, when it came from a tile, the
  tile view and box it was seen in (:class:`TileBox`).

Three protocols say what a detector can do:

- :class:`Detector`: ``detect(image) -> list[ImageDetection]`` on one
  perspective image.
- :class:`BatchDetector`: also ``detect_batch(images)`` on several images at
  once; the panorama driver (:mod:`detect.tiles`) uses it when present.
- :class:`PanoramaDetector`: ``detect_panorama(pano) -> list[Detection]``,
  for sources that already know panorama boxes (an annotation file).

Convention (CONVENTIONS.md, "Panorama pixels" and "Objects and models"):

- Continuous pixel coordinates, u right, v down, pixel centres at integer +
  0.5; a box is ``(u0, v0, u1, v1)`` with ``v0 < v1``.
- In a perspective image ``u0 < u1``. In the panorama ``u0 > u1`` means the
  box wraps the left/right seam (it covers ``[u0, W) + [0, u1)``); a box
  around a pole spans the full width, ``u0 = 0, u1 = W``.
- Images handed to a detector are ``(h, w, 3) uint8`` in RGB channel order.
- Class names are lowercase words (``chair``, ``table``, ...); several words
  are joined by ``_`` (``computer_mouse``).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panogeom.coords import pixel_to_lonlat, wrap_u
from panogeom.perspective import PinholeView, segment_to_arc

__all__ = [
    "ImageDetection",
    "TileBox",
    "Detection",
    "Detector",
    "BatchDetector",
    "PanoramaDetector",
    "check_label",
    "check_rgb_image",
    "tile_edge_planes",
]

Array = NDArray[np.float64]

_LABEL_RE = re.compile(r"^[a-z][a-z0-9_]*$")


def check_label(label: object) -> str:
    """Return ``label`` if it is a valid class name (a lowercase word), else raise ``ValueError``.

    Examples
    --------
    >>> check_label("chair")
    'chair'
    """
    if not isinstance(label, str) or not _LABEL_RE.match(label):
        raise ValueError(f"label: expected a lowercase word like 'chair' or 'computer_mouse', got {label!r}")
    return label


def check_rgb_image(image: ArrayLike, name: str = "image") -> NDArray[np.uint8]:
    """Check a detector input: ``(h, w, 3) uint8`` (RGB). Returns it unchanged."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8 or img.shape[0] == 0 or img.shape[1] == 0:
        raise ValueError(f"{name}: expected an (h, w, 3) uint8 RGB image, got shape {img.shape} dtype {img.dtype}")
    return img


def _frozen(a: ArrayLike, name: str, shape: tuple[int, ...]) -> Array:
    arr = np.array(a, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: expected finite values, got {arr.tolist()}")
    arr.setflags(write=False)
    return arr


def _check_score(score: object) -> float:
    try:
        s = float(score)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"score: expected a number in [0, 1], got {score!r}") from exc
    if not 0.0 <= s <= 1.0:
        raise ValueError(f"score: expected a number in [0, 1], got {score!r}")
    return s


@dataclass(frozen=True, eq=False)
class ImageDetection:
    """One detection in a perspective image.

    Attributes
    ----------
    label : str
        Class name, a lowercase word.
    score : float
        Confidence in [0, 1].
    box : (4,) float
        ``(u0, v0, u1, v1)`` in the image's continuous pixel coordinates,
        ``u0 < u1`` and ``v0 < v1`` (read-only array).

    Examples
    --------
    >>> d = ImageDetection("chair", 0.9, [10, 20, 50, 80])
    >>> d.box.tolist(), d.area
    ([10.0, 20.0, 50.0, 80.0], 2400.0)
    """

    label: str
    score: float
    box: Array

    def __post_init__(self) -> None:
        check_label(self.label)
        object.__setattr__(self, "score", _check_score(self.score))
        b = _frozen(self.box, "box", (4,))
        if not (b[0] < b[2] and b[1] < b[3]):
            raise ValueError(f"box: expected (u0, v0, u1, v1) with u0 < u1 and v0 < v1, got {b.tolist()}")
        object.__setattr__(self, "box", b)

    @property
    def area(self) -> float:
        """Box area in square pixels."""
        return float((self.box[2] - self.box[0]) * (self.box[3] - self.box[1]))

    def clipped(self, width: int, height: int) -> ImageDetection | None:
        """The detection with its box clipped to a ``width`` x ``height`` image, or None if nothing is left."""
        b = self.box
        c = np.array([max(b[0], 0.0), max(b[1], 0.0), min(b[2], float(width)), min(b[3], float(height))])
        if not (c[0] < c[2] and c[1] < c[3]):
            return None
        return replace(self, box=c)


@dataclass(frozen=True, eq=False)
class TileBox:
    """Where a panorama detection was seen: a box in one perspective tile.

    Attributes
    ----------
    view : PinholeView
        The tile's camera (panogeom).
    box : (4,) float
        ``(u0, v0, u1, v1)`` in the tile's pixels.
    index : int
        Index of the view in the driver's view set (-1 when unknown).
    truncated : bool
        The box touches the tile border: the object may extend beyond it.
    """

    view: PinholeView
    box: Array
    index: int = -1
    truncated: bool = False

    def __post_init__(self) -> None:
        b = _frozen(self.box, "box", (4,))
        if not (b[0] < b[2] and b[1] < b[3]):
            raise ValueError(f"box: expected (u0, v0, u1, v1) with u0 < u1 and v0 < v1, got {b.tolist()}")
        object.__setattr__(self, "box", b)

    def edge_planes(self) -> NDArray[np.float64]:
        """Unit normals of the planes through the camera that hold the box's four edges, pointing into the box.

        The box's region on the sphere is bounded by these great circles (its lon/lat extent, the
        panorama box, is larger whenever the tile is turned or pitched).

        Returns
        -------
        (4, 3) float
            Left, top, right, bottom; in the panorama frame of ``view``.

        Examples
        --------
        >>> from panogeom.perspective import PinholeView
        >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=100, height=100)
        >>> n = TileBox(view, [25, 25, 75, 75]).edge_planes()
        >>> bool(np.all(n @ view.pixel_to_ray([50.0, 50.0]) > 0)), np.abs(n[:, 2]).round(3).tolist()
        (True, [0.0, 0.894, 0.0, 0.894])
        """
        u0, v0, u1, v1 = (float(x) for x in self.box)
        edges = np.array([[u0, v1, u0, v0], [u0, v0, u1, v0], [u1, v0, u1, v1], [u1, v1, u0, v1]])
        _, _, n = segment_to_arc(edges, self.view)
        return n * np.where(n @ self.centre_ray() < 0, -1.0, 1.0)[:, None]

    def centre_ray(self) -> NDArray[np.float64]:
        """Unit ray through the box centre, in the panorama frame of ``view``: (3,) float. With
        ``detect.nms.region_boundary`` (the outline), what a crop of just this box needs
        (``posecrf.crops.outline_view``)."""
        u0, v0, u1, v1 = (float(x) for x in self.box)
        return self.view.pixel_to_ray(np.array([0.5 * (u0 + u1), 0.5 * (v0 + v1)]))

    def border_edges(self, margin: float = 2.0) -> NDArray[np.bool_]:
        """Which of the box's edges (left, top, right, bottom) lie within ``margin`` pixels of the tile border:
        there the object may go on beyond the tile, so the edge is not the object's. (4,) bool."""
        u0, v0, u1, v1 = (float(x) for x in self.box)
        m = float(margin)
        return np.array([u0 <= m, v0 <= m, u1 >= self.view.width - m, v1 >= self.view.height - m])


@dataclass(frozen=True, eq=False)
class Detection:
    """An object detected in an equirectangular panorama.

    Attributes
    ----------
    label : str
        Class name, a lowercase word.
    score : float
        Confidence in [0, 1].
    box : (4,) float
        ``(u0, v0, u1, v1)`` in panorama pixels with ``0 <= u0 < W``,
        ``0 < u1 <= W``, ``0 <= v0 < v1 <= H``; ``u0 > u1`` wraps the seam
        (read-only array). It is the lon/lat extent of the object's region.
    pano_width, pano_height : int
        Size of the panorama the box refers to (W == 2*H).
    mask : (H, W) bool, optional
        Object pixels in the panorama (grab-cut, :mod:`detect.grabcut`).
    tile : TileBox, optional
        The perspective tile and box the detection comes from. When present,
        the object's region on the sphere is that box's footprint (bounded by
        great circles), which ``box`` encloses; otherwise the region is the
        lon/lat rectangle ``box``.
    support : int
        Number of raw tile detections merged into this one by NMS.
    views : tuple of TileBox
        The object seen whole (not cut by the tile border) by other tiles
        too: the tile boxes of the merged members that do, ``tile`` first,
        filled by :func:`detect.nms.merge_sphere`; empty for a single view.
        Each tile's box edges are off by about a degree, partly
        independently: the box fits of :mod:`layout` take each edge's median
        over these views.

    Convention: see the module docstring; ``bbox_pano`` in scene.json is
    ``box`` (``u0 > u1`` wraps).

    Examples
    --------
    >>> d = Detection("table", 0.8, [2000.0, 600.0, 40.0, 700.0], 2048, 1024)
    >>> d.wraps, round(d.width_px, 1)
    (True, 88.0)
    """

    label: str
    score: float
    box: Array
    pano_width: int
    pano_height: int
    mask: NDArray[np.bool_] | None = field(default=None, repr=False)
    tile: TileBox | None = None
    support: int = 1
    views: tuple[TileBox, ...] = field(default=(), repr=False)

    def __post_init__(self) -> None:
        check_label(self.label)
        object.__setattr__(self, "score", _check_score(self.score))
        W, H = int(self.pano_width), int(self.pano_height)
        if W <= 0 or W != 2 * H or W != self.pano_width or H != self.pano_height:
            raise ValueError(f"panorama size: expected integers with W == 2*H, got W={self.pano_width!r}, "
                             f"H={self.pano_height!r}")
        object.__setattr__(self, "pano_width", W)
        object.__setattr__(self, "pano_height", H)
        b = _frozen(self.box, "box", (4,))
        ok = (0.0 <= b[0] < W and 0.0 < b[2] <= W and b[0] != b[2] and 0.0 <= b[1] < b[3] <= H)
        if not ok:
            raise ValueError(f"box: expected (u0, v0, u1, v1) in a {W}x{H} panorama with 0 <= u0 < W, "
                             f"0 < u1 <= W, u0 != u1 and 0 <= v0 < v1 <= H, got {b.tolist()}")
        object.__setattr__(self, "box", b)
        if self.mask is not None:
            m = np.asarray(self.mask)
            if m.shape != (H, W) or m.dtype != np.bool_:
                raise ValueError(f"mask: expected a ({H}, {W}) bool array, got shape {m.shape} dtype {m.dtype}")
            m = m.copy()
            m.setflags(write=False)
            object.__setattr__(self, "mask", m)
        if int(self.support) != self.support or self.support < 1:
            raise ValueError(f"support: expected a positive integer, got {self.support!r}")
        views = tuple(self.views)
        if not all(isinstance(v, TileBox) for v in views):
            raise ValueError("views: expected a tuple of TileBox")
        object.__setattr__(self, "views", views)

    def edge_planes(self) -> NDArray[np.float64] | None:
        """The box edges as planes through the camera, for box fits: :func:`tile_edge_planes` of ``views``
        (or of ``tile`` alone); None without a tile (the region is the lon/lat rectangle ``box``)."""
        if self.tile is None:
            return None
        return tile_edge_planes(self.views or (self.tile,))

    @property
    def wraps(self) -> bool:
        """True when the box crosses the left/right seam."""
        return bool(self.box[0] > self.box[2])

    @property
    def width_px(self) -> float:
        """Horizontal extent in pixels, seam-aware."""
        u0, u1 = self.box[0], self.box[2]
        return float(u1 - u0 if u1 > u0 else u1 + self.pano_width - u0)

    @property
    def center_px(self) -> Array:
        """(2,) centre of the box in panorama pixels, u wrapped into [0, W)."""
        u = wrap_u(self.box[0] + 0.5 * self.width_px, self.pano_width)
        return np.array([float(u), 0.5 * (self.box[1] + self.box[3])])

    @property
    def center_lonlat(self) -> Array:
        """(2,) ``(lon, lat)`` of the box centre, radians."""
        return pixel_to_lonlat(self.center_px, self.pano_width, self.pano_height)

    def with_mask(self, mask: NDArray[np.bool_] | None) -> Detection:
        """A copy with ``mask`` replaced."""
        return replace(self, mask=mask)

    def to_json(self) -> dict[str, object]:
        """``{"class", "score", "bbox_pano"}`` as in scene.json (CONVENTIONS.md)."""
        return {"class": self.label, "score": self.score, "bbox_pano": [float(x) for x in self.box]}


@runtime_checkable
class Detector(Protocol):
    """Anything that finds objects in one perspective image.

    ``detect(image)`` takes an ``(h, w, 3) uint8`` RGB image and returns
    :class:`ImageDetection` records in that image's pixels.
    """

    def detect(self, image: np.ndarray) -> list[ImageDetection]:
        """Detections in ``image``."""
        ...


@runtime_checkable
class BatchDetector(Detector, Protocol):
    """A :class:`Detector` that can also run on several images in one call."""

    def detect_batch(self, images: Sequence[np.ndarray]) -> list[list[ImageDetection]]:
        """One list of detections per image, in order."""
        ...


@runtime_checkable
class PanoramaDetector(Protocol):
    """A source of panorama detections that needs no tiles (e.g. an annotation file)."""

    def detect_panorama(self, pano: np.ndarray) -> list[Detection]:
        """Detections in panorama pixels of ``pano``."""
        ...


def tile_edge_planes(boxes: Sequence[TileBox]) -> NDArray[np.float64]:
    """Edge planes of one object's tile boxes (:meth:`TileBox.edge_planes`): ``(4, 3)`` for one box, else
    ``(V, 4, 3)``, one set per view (the box fits of :mod:`layout` take each edge's median over the views).

    Examples
    --------
    >>> from panogeom.perspective import PinholeView
    >>> view = PinholeView(yaw=0.0, pitch=0.0, roll=0.0, fov=np.pi / 2, width=100, height=100)
    >>> t = TileBox(view, [25, 25, 75, 75])
    >>> tile_edge_planes([t]).shape, tile_edge_planes([t, t]).shape
    ((4, 3), (2, 4, 3))
    """
    boxes = list(boxes)
    if not boxes:
        raise ValueError("boxes: expected at least one TileBox")
    if len(boxes) == 1:
        return boxes[0].edge_planes()
    return np.stack([t.edge_planes() for t in boxes])
