"""Benchmark of the detect package: panorama driver stages, spherical NMS, grab-cut, TFLite backend.

Run: ``python benchmarks/bench_detect.py [--update-docs]`` (prints a Markdown section; medians of
``--repeat`` runs; with ``--update-docs`` it also replaces its own section of docs/BENCHMARKS.md).
Both CPU time of the process and wall-clock time are given: on a shared machine
the CPU time is the fairer figure.

The driver is timed with a cheap detector (connected components of saturated
pixels, OpenCV), so the figures are the cost of tiling, back-projection and
NMS that every backend pays; the TFLite row (when the model is fetched) adds a
real network.
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import os
import platform
import statistics
import time
from pathlib import Path

import cv2
import numpy as np

from detect import (ImageDetection, detect_panorama, get_detector, merge_sphere, nms_sphere, segment_detections,
                    tile_consensus, to_panorama)
from detect.tiles import PanoramaTiler, _tiler, render_tiles, tile_detections
from panogeom.perspective import detection_views

REPO = Path(__file__).resolve().parents[1]


class SaturatedBlobs:
    """Cheap detector: one box per connected blob of saturated pixels (area >= 16 px)."""

    def detect(self, image):
        hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
        m = (hsv[..., 1] > 150).astype(np.uint8)
        n, _, stats, _ = cv2.connectedComponentsWithStats(m)
        return [ImageDetection("chair", 0.9, [x, y, x + w, y + h]) for x, y, w, h, a in stats[1:] if a >= 16]


def synthetic_pano(width: int = 2048, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    h = width // 2
    pano = (rng.integers(80, 160, (h, width, 1)) * np.ones((1, 1, 3))).astype(np.uint8)
    for k in range(12):  # coloured "objects" around the room, one across the seam
        u = int((k * width / 12 + rng.integers(0, 40)) % width)
        v = int(h * 0.55 + rng.integers(0, h // 6))
        w, hh = int(rng.integers(40, 120)), int(rng.integers(40, 100))
        cols = np.arange(u, u + w) % width
        pano[v:v + hh][:, cols] = rng.integers(0, 255, 3) * np.array([1, 0, 0]) + np.array([0, 30, 30])
    return pano


SECTION = "## detect: panorama driver, spherical NMS, grab-cut"


def med(f, repeat: int) -> tuple[float, float]:
    """Median (CPU seconds, wall seconds) of ``repeat`` calls."""
    cpu, wall = [], []
    for _ in range(repeat):
        c, t = time.process_time(), time.perf_counter()
        f()
        cpu.append(time.process_time() - c)
        wall.append(time.perf_counter() - t)
    return statistics.median(cpu), statistics.median(wall)


def once(f) -> tuple[float, float]:
    return med(f, 1)


def update_docs(text: str, path: Path) -> None:
    """Replace this script's section of docs/BENCHMARKS.md (benchmarks/_docs.py)."""
    replace_section(path, text, SECTION)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--width", type=int, default=2048)
    ap.add_argument("--update-docs", action="store_true", help="write the section into docs/BENCHMARKS.md")
    args = ap.parse_args(argv)
    cv2.setNumThreads(2)
    pano = synthetic_pano(args.width)
    W, H = pano.shape[1], pano.shape[0]
    det = SaturatedBlobs()
    views = tuple(detection_views(416))
    rows = []

    rows.append(("tiler set-up (sampling maps of 18 tiles, once per panorama size)",
                 once(lambda: PanoramaTiler(views, W, H))))
    render_tiles(pano, views)  # warm the cache
    rows.append(("render 18 tiles 416x416", med(lambda: render_tiles(pano, views), args.repeat)))
    _, tiles = render_tiles(pano, views)
    rows.append(("cheap detector on 18 tiles", med(lambda: [det.detect(x) for x in tiles], args.repeat)))
    raw_img = [(k, d) for k, x in enumerate(tiles) for d in det.detect(x)]
    rows.append((f"back-projection of {len(raw_img)} tile boxes",
                 med(lambda: [to_panorama(d, views[k], W, H, k) for k, d in raw_img], args.repeat)))
    raw = tile_detections(pano, det, views)
    merged = nms_sphere(raw)
    rows.append((f"spherical NMS {len(raw)} -> {len(merged)}", med(lambda: nms_sphere(raw), args.repeat)))
    groups = merge_sphere(raw)
    rows.append((f"tile consensus score of {len(groups)} merged detections",
                 med(lambda: tile_consensus(groups, views), args.repeat)))
    total = med(lambda: detect_panorama(pano, det, views), args.repeat)
    rows.append((f"**18 tiles + NMS at {W}x{H}, total (cheap detector)**", total))

    def cold():
        _tiler.cache_clear()
        detect_panorama(pano, det, views)
    rows.append(("same, first call at a new panorama size (set-up included)", once(cold)))

    rng = np.random.default_rng(1)
    for n in (100, 300):
        many = []
        for _ in range(n):
            k = int(rng.integers(0, 18))
            x, y = rng.uniform(0, 330, 2)
            many.append(to_panorama(ImageDetection("chair", float(rng.uniform(0.3, 1)), [x, y, x + 80, y + 80]),
                                    views[k], W, H, k))
        rows.append((f"spherical NMS of {n} random boxes, one class", med(lambda: nms_sphere(many), args.repeat)))

    k = max(1, len(merged[:4]))
    per = med(lambda: segment_detections(pano, merged[:4]), max(1, args.repeat // 2))
    rows.append(("grab-cut mask, per detection (crop <= 256 px, 5 iterations)", (per[0] / k, per[1] / k)))

    model = REPO / "detect" / "models" / "objectron_ssd.tflite"
    real = REPO.parent / "shared" / "data" / "real" / "panocontext_pano_asmasuxybohhcj" / "pano.png"
    try:
        tfl = get_detector("tflite") if model.is_file() else None
    except ImportError:
        tfl = None
    if tfl is not None:
        img = cv2.cvtColor(cv2.imread(str(real)), cv2.COLOR_BGR2RGB) if real.is_file() else pano
        img = cv2.resize(img, (W, H), interpolation=cv2.INTER_LINEAR)
        detect_panorama(img, tfl, views)
        _, real_tiles = render_tiles(img, views)
        rows.append(("tflite SSD on 18 tiles only", med(lambda: [tfl.detect(x) for x in real_tiles], args.repeat)))
        rows.append((f"**18 tiles + NMS at {W}x{H}, total (tflite SSD)**",
                     med(lambda: detect_panorama(img, tfl, views), args.repeat)))

    room = REPO / "tests" / "detect" / "data" / "builtin_room" / "pano.jpg"
    try:
        from detect.builtin import BuiltinDetector, builtin_views

        blt = BuiltinDetector(num_threads=2)
    except ImportError:
        blt = None
    if blt is not None and room.is_file():  # the builtin network on a synthetic room (never trained on)
        img = cv2.resize(cv2.cvtColor(cv2.imread(str(room)), cv2.COLOR_BGR2RGB), (W, H),
                         interpolation=cv2.INTER_LINEAR)
        paper, own = tuple(builtin_views(2 * blt.input_size, wide=False)), tuple(blt.views())
        detect_panorama(img, blt, paper), detect_panorama(img, blt, own)  # warm the tilers
        _, btiles = render_tiles(img, paper)
        rows.append((f"builtin network on 18 tiles ({btiles[0].shape[0]} px, reduced to {blt.input_size}), one batch",
                     med(lambda: blt.detect_batch(btiles), args.repeat)))
        rows.append((f"**18 tiles + NMS at {W}x{H}, total (builtin)**",
                     med(lambda: detect_panorama(img, blt, paper), args.repeat)))
        rows.append((f"**{len(own)} tiles (its default views) + NMS at {W}x{H}, total (builtin)**",
                     med(lambda: detect_panorama(img, blt, own), args.repeat)))

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [SECTION, "",
             "`.venv/bin/python benchmarks/bench_detect.py --update-docs` (this section is written by the script). "
             f"Synthetic {W}x{H} panorama with 12 coloured patches, the paper's 18 tiles of 416x416 "
             "(panogeom `detection_views`); the cheap detector boxes connected saturated pixels, so the "
             "driver's own cost (tiling, back-projection, NMS on the sphere) is what is measured. "
             f"Medians of {args.repeat} runs; CPU time of the process, wall-clock time in brackets. "
             "The builtin rows run on tests/detect/data/builtin_room (a synthetic room, upscaled).", "",
             "| stage | CPU ms (wall ms) |", "|---|---:|"]
    lines += [f"| {name} | {c * 1000:.1f} ({w * 1000:.1f}) |" for name, (c, w) in rows]
    lines += ["", f"Environment: python {platform.python_version()}, numpy {np.__version__}, "
                  f"opencv {cv2.__version__}, {os.cpu_count()} CPUs, {platform.machine()}, "
                  f"load average {load:.1f} at the end of the run (the machine is shared).", ""]
    text = "\n".join(lines)
    print(text)
    if args.update_docs:
        update_docs(text, REPO / "docs" / "BENCHMARKS.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
