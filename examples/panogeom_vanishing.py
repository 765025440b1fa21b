"""Line segments, Manhattan vanishing points and upright rectification of a panorama.

Run:  .venv/bin/python examples/panogeom_vanishing.py [PANO] [--mode level|walls] [--out out/examples/vanishing]

Without PANO a tiled box room is rendered with a tilted camera. Writes to
the output folder:

- ``overlay.png``: the input panorama with its line segments drawn as
  great-circle arcs, coloured by vanishing point (red: Manhattan x, green:
  Manhattan y, blue: vertical, grey: none);
- ``rectified.png``: the upright panorama (``Rectification.apply``) with the
  same arcs carried into it and the horizon drawn in white: vertical arcs
  become vertical image lines;
- ``rectification.json``: ``camera.rotation`` (input camera frame -> upright
  frame), tilt and heading in degrees, segment counts.

Convention: CONVENTIONS.md; ``rotation`` maps input-camera directions into the
upright frame; degrees only in the printed/JSON output (``_deg``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np


def tiled_room(height: int = 512, tilt_deg: tuple[float, float, float] = (25.0, 8.0, -6.0)) -> np.ndarray:
    """A box room with tiled walls, floor and ceiling, seen by a camera turned by (yaw, pitch, roll) degrees."""
    import cv2

    from panogeom.rotation import rot_x, rot_y, rot_z
    from panogeom.transform import pano_from_directions

    lo, hi, cam = np.array([-2.1, -1.7, 0.0]), np.array([2.9, 2.3, 2.7]), np.array([0.0, 0.0, 1.5])
    colours = np.array([[200, 170, 140], [160, 190, 200], [190, 200, 150], [210, 170, 190], [140, 120, 100],
                        [235, 235, 230]], float)
    spacing = np.array([0.6, 0.6, 0.45])  # tile size along x, y, z

    def shade(d: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (np.where(d > 0, hi, lo) - cam) / d
        t[~np.isfinite(t) | (t <= 0)] = np.inf
        axis = np.argmin(t, axis=1)
        p = cam + t[np.arange(len(d)), axis, None] * d
        face = 2 * axis + (d[np.arange(len(d)), axis] > 0)
        col = colours[face].copy()
        frac = np.abs((p / spacing + 0.5) % 1.0 - 0.5) * spacing  # distance to the nearest grid line, metres
        frac[np.arange(len(d)), axis] = 1.0  # no lines across the face's own normal
        col[frac.min(axis=1) < 0.012] *= 0.35
        return col

    R = rot_z(np.deg2rad(tilt_deg[0])) @ rot_y(-np.deg2rad(tilt_deg[1])) @ rot_x(np.deg2rad(tilt_deg[2]))
    big = pano_from_directions(shade, 2 * height, rotation=R.T)  # pixel ray d sees the room along R @ d
    return cv2.resize(big.astype(np.float32), (2 * height, height), interpolation=cv2.INTER_AREA).round().astype(
        np.uint8)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("pano", nargs="?", help="equirectangular panorama (W == 2H); a synthetic room when omitted")
    ap.add_argument("--mode", choices=["level", "walls"], default="level",
                    help="keep the input's heading, or also turn x/y onto the walls")
    ap.add_argument("--out", default="out/examples/vanishing", help="output folder")
    args = ap.parse_args(argv)

    import cv2

    from panogeom.coords import ray_to_pixel
    from panogeom.lines import draw_segments
    from panogeom.rectify import estimate_rectification
    from panogeom.vanishing import VanishingPointError

    if args.pano:
        bgr = cv2.imread(args.pano, cv2.IMREAD_COLOR)
        if bgr is None:
            print(f"{args.pano}: cannot read the image", file=sys.stderr)
            return 2
        pano = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        if pano.shape[1] != 2 * pano.shape[0]:
            print(f"{args.pano}: expected an equirectangular panorama with W == 2*H, got "
                  f"{pano.shape[1]}x{pano.shape[0]}", file=sys.stderr)
            return 2
    else:
        pano = tiled_room()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    t0 = time.perf_counter()
    try:
        rect = estimate_rectification(pano, args.mode)
    except VanishingPointError as err:
        print(f"{args.pano or 'synthetic room'}: no upright rotation: {err}", file=sys.stderr)
        return 2  # the image has no usable Manhattan structure: bad input
    t_est = time.perf_counter() - t0
    upright = rect.apply(pano)
    t_all = time.perf_counter() - t0

    labels = rect.frame.labels
    cv2.imwrite(str(out / "overlay.png"), cv2.cvtColor(draw_segments(pano, rect.segments, labels), cv2.COLOR_RGB2BGR))
    h, w = pano.shape[:2]
    view = draw_segments(upright, rect.segments.rotated(rect.rotation), labels)
    cv2.line(view, (0, h // 2), (w - 1, h // 2), (255, 255, 255), 1)
    cv2.imwrite(str(out / "rectified.png"), cv2.cvtColor(view, cv2.COLOR_RGB2BGR))
    centre = ray_to_pixel(rect.rays_to_rectified([1.0, 0.0, 0.0]), w, h)
    info = {
        "image": args.pano or "synthetic tiled room",
        "mode": rect.mode,
        "camera": {"rotation": np.round(rect.rotation, 9).tolist()},
        "tilt_deg": round(float(np.rad2deg(rect.tilt)), 4),
        "heading_deg": round(float(np.rad2deg(rect.heading)), 4) + 0.0,
        "input_centre_column_in_rectified_px": np.round(centre, 2).tolist(),
        "segments": len(rect.segments),
        "segments_per_axis": {"x": int(rect.frame.counts[0]), "y": int(rect.frame.counts[1]),
                              "vertical": int(rect.frame.counts[2])},
        "inlier_fraction": round(rect.frame.inlier_fraction, 4),
        "rmse_deg": round(float(np.rad2deg(rect.frame.rmse)), 4),
        "time_s": {"estimate": round(t_est, 3), "with_resampling": round(t_all, 3)},
    }
    (out / "rectification.json").write_text(json.dumps(info, indent=1) + "\n")
    c = rect.frame.counts
    print(f"{info['image']}: mode {rect.mode}, tilt {info['tilt_deg']:.2f} deg, heading {info['heading_deg']:.2f} deg, "
          f"{len(rect.segments)} segments (x {c[0]}, y {c[1]}, vertical {c[2]}), "
          f"{t_est:.2f} s ({t_all:.2f} s with resampling)")
    print("camera.rotation =", np.array2string(rect.rotation, precision=6, suppress_small=True))
    print(f"wrote {out / 'overlay.png'}, {out / 'rectified.png'}, {out / 'rectification.json'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
