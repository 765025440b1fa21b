"""Time and check the upright rectification step (panogeom.lines, .vanishing, .rectify).

Timing: line segments, Manhattan vanishing points and the upright rotation
(the whole estimation step), and separately the resampling of the panorama
into the rectified frame, at 1024x512 and 2048x1024, on a synthetic textured
room (tests/panogeom/synthetic_rooms.py) and on the real panoramas of
../shared/data/real when present. Median of ``--repeats`` runs after one
warm-up run.

Accuracy (``--accuracy``, the figures of docs/EVALUATION.md):
- synthetic: ``--rooms`` random box rooms at 1024x512, camera tilted by
  roll and pitch uniform in +-15 degrees and any yaw; error of the recovered
  vertical and of the horizontal axes (modulo 90 degrees);
- real: for each panorama with gt.json, the tilt of each ground-truth
  vertical wall edge (the great circle through its ceiling and floor corner)
  from the vertical, as given, after rectification, and after rectifying the
  same panorama turned by five fixed rotations (tilts 5..15 degrees).

Prints Markdown. Run: ``.venv/bin/python benchmarks/bench_vanishing.py [--accuracy]``
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import cv2
import numpy as np

from panogeom.coords import pixel_to_ray
from panogeom.lines import detect_line_segments
from panogeom.rectify import estimate_rectification, upright_rotation
from panogeom.rotation import rot_x, rot_y, rot_z
from panogeom.transform import rotate_pano
from panogeom.vanishing import estimate_manhattan_frame

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "data" / "real"
sys.path.insert(0, str(ROOT / "tests" / "panogeom"))
from synthetic_rooms import make_room, random_rotation, render_room  # noqa: E402


def run_times(fn, repeats: int) -> tuple[np.ndarray, object]:
    out = fn()  # warm-up
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return np.array(times), out


def median_time(fn, repeats: int) -> tuple[float, object]:
    times, out = run_times(fn, repeats)
    return float(np.median(times)), out


def time_case(name: str, pano: np.ndarray, repeats: int) -> str:
    t_lines, segs = median_time(lambda: detect_line_segments(pano), repeats)
    t_vp, frame = median_time(lambda: estimate_manhattan_frame(segs), repeats)
    t_rot, R = median_time(lambda: upright_rotation(frame.axes, "walls"), repeats)
    steps, rect = run_times(lambda: estimate_rectification(pano, "walls"), repeats)
    t_step = float(np.median(steps))
    t_resample, _ = median_time(lambda: rect.apply(pano), repeats)
    h, w = pano.shape[:2]
    return (f"| {name} | {w}x{h} | {len(segs)} | {1e3 * t_lines:.0f} | {1e3 * t_vp:.0f} | {1e3 * t_rot:.2f} "
            f"| **{1e3 * t_step:.0f}** | {1e3 * steps.min():.0f} | {1e3 * t_resample:.0f} "
            f"| {1e3 * (t_step + t_resample):.0f} |")


def load_real() -> list[tuple[str, np.ndarray, dict]]:
    out = []
    if REAL.is_dir():
        for d in sorted(REAL.iterdir()):
            if (d / "gt.json").is_file():
                gt = json.loads((d / "gt.json").read_text())
                img = cv2.cvtColor(cv2.imread(str(d / gt["image"]["file"])), cv2.COLOR_BGR2RGB)
                out.append((d.name, img, gt))
    return out


def edge_tilts_deg(gt: dict, R: np.ndarray) -> np.ndarray:
    w, h = gt["image"]["width"], gt["image"]["height"]
    cp = np.asarray(gt["corners_px"], float)
    c, f = pixel_to_ray(cp[:, :2], w, h) @ R.T, pixel_to_ray(cp[:, 2:], w, h) @ R.T
    n = np.cross(c, f)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return np.rad2deg(np.arcsin(np.abs(n[:, 2])))


def synthetic_accuracy(n_rooms: int) -> list[str]:
    rng = np.random.default_rng(12345)
    ev, eh, tilt, times = [], [], [], []
    for k in range(n_rooms):
        R = random_rotation(rng, 15.0)
        pano = render_room(make_room(5000 + k), R, 1024)
        t = time.perf_counter()
        r = estimate_rectification(pano, "walls")
        times.append(time.perf_counter() - t)
        up = r.frame.axes[2]
        ev.append(np.rad2deg(np.arctan2(np.linalg.norm(np.cross(up, R[2])), up @ R[2])))
        Q = r.frame.axes @ R.T
        a = np.rad2deg(np.arctan2(Q[1, 0], Q[0, 0]))
        eh.append(abs((a + 45.0) % 90.0 - 45.0))
        tilt.append(np.rad2deg(np.arccos(R[2, 2])))
    ev, eh = np.array(ev), np.array(eh)
    return [
        f"Synthetic: {n_rooms} textured box rooms at 1024x512, camera off-centre, roll and pitch uniform in "
        f"+-15 deg, any yaw (true tilt {min(tilt):.1f}..{max(tilt):.1f} deg).",
        "",
        "| error (deg) | median | 95th percentile | max | target |",
        "|---|---|---|---|---|",
        f"| vertical | {np.median(ev):.3f} | {np.percentile(ev, 95):.3f} | {ev.max():.3f} | median < 0.3, p95 < 1 |",
        f"| horizontal axes (mod 90) | {np.median(eh):.3f} | {np.percentile(eh, 95):.3f} | {eh.max():.3f} "
        f"| median < 0.5 |",
        "",
        f"Estimation time per room: median {np.median(times):.2f} s.",
    ]


def real_accuracy(real) -> list[str]:
    turns = [rot_z(0.3 + k) @ rot_y(np.deg2rad(p)) @ rot_x(np.deg2rad(r))
             for k, (p, r) in enumerate([(5, 0), (0, -8), (9, -6), (-12, 4), (10, 11)])]
    lines = [
        "Real: tilt from the vertical (deg) of each ground-truth vertical wall edge, i.e. of the great circle "
        "through its ceiling and floor corner (gt.json corners_px), in the rectified frame ('level' mode). "
        "'turned': the panorama is first rotated by five fixed rotations (tilts "
        f"{', '.join(f'{np.rad2deg(np.arccos(T[2, 2])):.1f}' for T in turns)} deg) and rectified again; the "
        "corners are carried along by the known rotation.",
        "",
        "| panorama | corners | as given: max | rectified: recovered tilt | rectified: per corner "
        "| turned: recovered tilts | turned: max over corners and turns |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, img, gt in real:
        r = estimate_rectification(img, "level")
        per = edge_tilts_deg(gt, r.rotation)
        tt, worst = [], 0.0
        for T in turns:
            rt = estimate_rectification(rotate_pano(img, T), "level")
            tt.append(np.rad2deg(rt.tilt))
            worst = max(worst, float(edge_tilts_deg(gt, rt.rotation @ T).max()))
        lines.append(f"| {name} | {len(per)} | {edge_tilts_deg(gt, np.eye(3)).max():.3f} | "
                     f"{np.rad2deg(r.tilt):.2f} | {', '.join(f'{x:.2f}' for x in per)} | "
                     f"{', '.join(f'{x:.2f}' for x in tt)} | {worst:.2f} |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="timed runs per case")
    ap.add_argument("--accuracy", action="store_true", help="also print the accuracy tables")
    ap.add_argument("--rooms", type=int, default=40, help="synthetic rooms for --accuracy")
    args = ap.parse_args(argv)

    print("## Vanishing points and rectification\n")
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores (load average "
          f"{load:.1f} at the start), OpenCV {cv2.__version__} ({cv2.getNumThreads()} threads), numpy "
          f"{np.__version__}. Median of {args.repeats} runs after a warm-up (and the best run of the step), "
          f"milliseconds.\n")
    print("| scene | size | segments | lines | VPs | rotation | step (lines + VPs + rotation) | step, best run "
          "| resampling | step + resampling |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(7)
    R = random_rotation(rng, 15.0)
    room = make_room(77)
    for w in (1024, 2048):
        print(time_case("synthetic room, tilted", render_room(room, R, w), args.repeats), flush=True)
    for name, img, _ in load_real():
        print(time_case(name, img, args.repeats), flush=True)
        big = cv2.resize(img, (2 * img.shape[1], 2 * img.shape[0]), interpolation=cv2.INTER_CUBIC)
        print(time_case(name + " (upscaled x2)", big, args.repeats), flush=True)
    print(f"\nLoad average at the end of the timings: "
          f"{os.getloadavg()[0] if hasattr(os, 'getloadavg') else float('nan'):.1f}.")
    if args.accuracy:
        print()
        print("\n".join(synthetic_accuracy(args.rooms)))
        real = load_real()
        if real:
            print()
            print("\n".join(real_accuracy(real)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
