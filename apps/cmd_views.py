"""``pano2cad views``: a cubemap (dice layout) and perspective views of a panorama."""

from __future__ import annotations

import math

from .errors import UserError
from .outdir import prepare_out_dir
from .progress import Progress


def run(args) -> int:
    from panogeom.cubemap import equirect_to_cubemap
    from panogeom.perspective import equirect_to_perspective, ring_views

    from .atomic import write_image
    from .imageio import read_panorama

    if not 0.0 < args.fov_deg < 180.0:
        raise UserError(f"--fov-deg: expected a field of view in (0, 180) degrees, got {args.fov_deg}")
    if args.face < 8 or args.view_size < 8 or args.views < 1:
        raise UserError("--face and --view-size: expected at least 8 pixels; --views: at least 1")
    prog = Progress(args.quiet)
    pano = read_panorama(args.image)
    out = prepare_out_dir(args.out)
    written = []
    with prog.stage("cubemap", f"cubemap, faces of {args.face} px"):
        written.append(write_image(out / "cubemap_dice.png", equirect_to_cubemap(pano.image, args.face, "dice")))
    views = ring_views(args.views, math.radians(args.fov_deg), args.view_size)
    with prog.stage("views", f"{len(views)} perspective views of {args.fov_deg:g} deg"):
        for k, view in enumerate(views):
            img = equirect_to_perspective(pano.image, view)
            written.append(write_image(out / f"view_{k:02d}_yaw{math.degrees(view.yaw):05.1f}.png", img))
    for p in written:
        print(p)
    return 0
