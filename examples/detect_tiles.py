"""Detect objects in panoramas through perspective tiles and draw them (detect package example).

Usage::

    python examples/detect_tiles.py PANO.png [PANO2.png ...] [--detector tflite] [--out DIR]
        [--score 0.3] [--masks] [--prefix P]

For each panorama it runs :func:`detect.detect_panorama` (18 perspective
tiles, detector, back-projection, NMS on the sphere), prints the detections
and writes ``OUT/<prefix><folder>.png``: every detection's region on the sphere (the
footprint of its tile box, curved in the panorama, split at the seam) with
class and score, and with ``--masks`` its grab-cut mask tinted.
Output names are ``<prefix><parent folder name>.png``.

Needs ``python -m detect.fetch_models`` for the default ``tflite`` detector.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from detect import Detection, detect_panorama, get_detector
from detect.nms import region_boundary
from panogeom.coords import ray_to_pixel

COLORS = {"chair": (230, 60, 60), "table": (60, 160, 255), "tv": (255, 200, 0), "bed": (200, 80, 255),
          "sofa": (0, 200, 120), "plant": (40, 220, 40)}


def draw_detections(pano: np.ndarray, dets: list[Detection], thickness: int = 2) -> np.ndarray:
    """Panorama (RGB) with each detection's spherical outline, class and score drawn on it."""
    out = pano.copy()
    H, W = pano.shape[:2]
    for d in dets:
        color = COLORS.get(d.label, (200, 200, 200))
        if d.mask is not None:
            out[d.mask] = (0.5 * out[d.mask] + 0.5 * np.array(color)).astype(np.uint8)
        uv = ray_to_pixel(region_boundary(d, 48), W, H)
        # split the closed outline where it jumps across the seam
        pts = np.vstack([uv, uv[:1]])
        cuts = np.flatnonzero(np.abs(np.diff(pts[:, 0])) > W / 2) + 1
        for seg in np.split(pts, cuts):
            if len(seg) > 1:
                cv2.polylines(out, [np.round(seg * 4).astype(np.int32)], False, color, thickness, cv2.LINE_AA, shift=2)
        text = f"{d.label} {d.score:.2f}"
        u0, v0 = int(d.box[0]), int(d.box[1])
        (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.45, 1)
        u0 = min(u0, W - tw - 2)
        v0 = max(v0, th + 4)
        cv2.rectangle(out, (u0, v0 - th - 4), (u0 + tw + 2, v0), color, -1)
        cv2.putText(out, text, (u0 + 1, v0 - 3), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("panos", nargs="+", type=Path, help="equirectangular panoramas (W == 2*H)")
    ap.add_argument("--detector", default="tflite", help="detector spec (see detect.backends)")
    ap.add_argument("--score", type=float, default=0.3, help="minimum score")
    ap.add_argument("--out", type=Path, default=Path("out/detect"), help="output folder")
    ap.add_argument("--masks", action="store_true", help="also segment each detection by grab-cut")
    ap.add_argument("--prefix", default="", help="prefix of the output file names")
    ap.add_argument("--markdown", type=Path, default=None, help="also write the detections as a Markdown table")
    args = ap.parse_args(argv)
    names = [args.prefix + p.parent.name for p in args.panos]
    detector = get_detector(args.detector)
    args.out.mkdir(parents=True, exist_ok=True)
    table = ["| image | class | score | bbox_pano (u0, v0, u1, v1) | tiles merged |", "|---|---|---:|---|---:|"]
    for path, name in zip(args.panos, names):
        bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
        if bgr is None:
            print(f"error: {path}: cannot read the image", file=sys.stderr)
            return 2
        pano = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB)
        t = time.perf_counter()
        dets = detect_panorama(pano, detector, score_threshold=args.score, masks=args.masks)
        dt = time.perf_counter() - t
        counts = {c: sum(d.label == c for d in dets) for c in sorted({d.label for d in dets})}
        print(f"{name}: {pano.shape[1]}x{pano.shape[0]}, {len(dets)} detections {counts} in {dt:.2f} s")
        for d in dets:
            box = np.round(d.box).astype(int).tolist()
            print(f"  {d.label:8s} {d.score:.2f}  bbox_pano {box}  tiles merged {d.support}")
            table.append(f"| {path.parent.name} | {d.label} | {d.score:.2f} | {box} | {d.support} |")
        if not dets:
            table.append(f"| {path.parent.name} | (none) | | | |")
        dst = args.out / f"{name}.png"
        cv2.imwrite(str(dst), cv2.cvtColor(draw_detections(pano, dets), cv2.COLOR_RGB2BGR))
        print(f"  wrote {dst}")
    if args.markdown is not None:
        args.markdown.write_text("\n".join(table) + "\n", encoding="utf-8")
        print(f"wrote {args.markdown}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
