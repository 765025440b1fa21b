"""panogeom: spherical geometry primitives for 360-degree panoramas.

Owns every formula for pixels, rays and frames (CONVENTIONS.md): pixel <->
(lon, lat) <-> unit ray (:mod:`panogeom.coords`), rotations
(:mod:`panogeom.rotation`), seam- and pole-correct resampling
(:mod:`panogeom.sampling`), equirect <-> cubemap (:mod:`panogeom.cubemap`),
perspective views and back-projection of points, segments and boxes
(:mod:`panogeom.perspective`), rotation of whole panoramas
(:mod:`panogeom.transform`), projection of 3D geometry
(:mod:`panogeom.project`), line segments as great-circle arcs
(:mod:`panogeom.lines`), Manhattan vanishing points
(:mod:`panogeom.vanishing`), upright rectification (:mod:`panogeom.rectify`)
and ray casting of meshes into equirect images (:mod:`panogeom.raycast`,
:mod:`panogeom.texture`).

Imports none of the other pano2cad packages; heavy libraries (Open3D, libigl)
are imported lazily inside the functions that need them.
"""

from .coords import (
    DEFAULT_CAMERA_HEIGHT,
    lonlat_to_pixel,
    lonlat_to_ray,
    pixel_grid,
    pixel_grid_rays,
    pixel_to_lonlat,
    pixel_to_ray,
    ray_to_lonlat,
    ray_to_pixel,
    world_to_pixel,
    wrap_u,
)
from .rotation import check_rotation, matrix_to_ypr, ypr_to_matrix

__all__ = [
    "DEFAULT_CAMERA_HEIGHT",
    "check_rotation",
    "lonlat_to_pixel",
    "lonlat_to_ray",
    "matrix_to_ypr",
    "pixel_grid",
    "pixel_grid_rays",
    "pixel_to_lonlat",
    "pixel_to_ray",
    "ray_to_lonlat",
    "ray_to_pixel",
    "world_to_pixel",
    "wrap_u",
    "ypr_to_matrix",
]
