"""Surface labels of a panorama, drawn for people: fused labels, GC, OM and layout overlays.

Give a panorama file (any upright-ish 360 image, W == 2*H; it is rectified
with panogeom.rectify in "walls" mode first, and the labels are rotated back
into the input's pixel geometry), or nothing to render a room of the
project's generator (layout.rooms, no furniture) from ``--seed``. Writes
into ``--out`` (default out/examples/surfaces/):

- ``<name>_surfaces.png``: stacked overlays (fused labels, geometric
  context, orientation map, clutter-free layout; the reference labels for a
  generated room) in the rectified frame;
- ``<name>_labels.png``: the label ids (0..5) in the input's pixel geometry.

Run: ``.venv/bin/python examples/layout_surfaces.py [PANO] [--seed 7] [--width 1024]``
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

from layout.surfaces import estimate_surfaces, surfaces_figure
from panogeom.rectify import estimate_rectification
from panogeom.transform import rotate_pano
from panogeom.vanishing import VanishingPointError


def generated_room(seed: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """An empty room of the generator, rendered: (RGB panorama, reference labels)."""
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("pano", nargs="?", help="panorama image (W == 2*H); omitted: a generated room")
    ap.add_argument("--seed", type=int, default=7, help="room of the generator when no panorama is given")
    ap.add_argument("--width", type=int, default=1024, help="working width (panoramas are resized to it)")
    ap.add_argument("--out", default="out/examples/surfaces")
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    truth = None
    if args.pano:
        bgr = cv2.imread(args.pano, cv2.IMREAD_COLOR)
        if bgr is None or bgr.shape[1] != 2 * bgr.shape[0]:
            print(f"layout_surfaces: {args.pano}: expected a readable image with W == 2*H, got "
                  f"{None if bgr is None else bgr.shape}", file=sys.stderr)
            return 2
        small = cv2.resize(bgr, (args.width, args.width // 2), interpolation=cv2.INTER_AREA)
        pano = np.ascontiguousarray(small[..., ::-1])
        name = Path(args.pano).parent.name if Path(args.pano).stem == "pano" else Path(args.pano).stem
    else:
        pano, truth = generated_room(args.seed, args.width)
        name = f"room-seed{args.seed}"
    try:
        rect = estimate_rectification(pano, "walls")
        upright = rect.apply(pano)
        s = estimate_surfaces(upright, rect.segments.rotated(rect.rotation))
        back = rect.rotation.T
        print(f"{name}: rectified, tilt {np.rad2deg(rect.tilt):.2f} deg, heading {np.rad2deg(rect.heading):.2f} deg")
    except VanishingPointError as err:
        print(f"{name}: no Manhattan frame ({err}); labelling the panorama as it is")
        upright, back = pano, np.eye(3)
        s = estimate_surfaces(upright)
    for w in s.warnings:
        print(f"warning: {w}")
    fig = surfaces_figure(upright, s, None if truth is None else rotate_pano(truth, back.T, "nearest"))
    cv2.imwrite(str(out / f"{name}_surfaces.png"), fig[..., ::-1])
    cv2.imwrite(str(out / f"{name}_labels.png"), rotate_pano(s.labels, back, "nearest"))
    counts = np.bincount(s.labels.ravel(), minlength=6) / s.labels.size
    print("label shares: " + ", ".join(f"{n} {100 * c:.1f}%" for n, c in
                                      zip(("unknown", "floor", "ceiling", "wall x", "wall y", "object"), counts)))
    if truth is not None:
        lab_in = rotate_pano(s.labels, back, "nearest")
        print(f"pixel accuracy against the generator's labels: {100 * np.mean(lab_in == truth):.1f}%")
    print(f"wrote {out / f'{name}_surfaces.png'} and {out / f'{name}_labels.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
