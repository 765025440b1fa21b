"""Time the surface labelling (layout.surfaces): orientation map, geometric context, fusion.

Target (issue 5): OM + GC + fusion < 3 s at 1024x512 on 2 cores. The line
segments come from the rectification step in the pipeline
(``Rectification.segments``), so the target total is timed with segments
given; line detection is timed separately, and a total including it is
given too.

Panoramas: room-0000 of a synthetic set at 1024x512 (``--synth``, default
out/train/surfaces/test, made with ``pano2cad synth --seed 2500 --rooms 40
--size 1024``; without it an empty room is rendered with layout.rooms and
panogeom's ray caster) and the real panoramas of ../shared/data/real when
present. Medians of ``--repeat`` runs after a warm-up; CPU time of the
process and wall-clock time (the machine is shared: CPU time is the fairer
figure). torch runs with its default thread count and, in a second row, one
thread.

Run: ``.venv/bin/python benchmarks/bench_surfaces.py [--update-docs]``
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
REAL = REPO.parent / "shared" / "data" / "real"
SECTION = "## Surface labels (layout.surfaces)"


def med(fn, repeat: int) -> tuple[float, float]:
    """Median (CPU s, wall s) of ``repeat`` calls after one warm-up call."""
    fn()
    cpu, wall = [], []
    for _ in range(repeat):
        c, w = time.process_time(), time.perf_counter()
        fn()
        cpu.append(time.process_time() - c)
        wall.append(time.perf_counter() - w)
    return statistics.median(cpu), statistics.median(wall)


def load_pano(path: Path, width: int = 1024) -> np.ndarray:
    bgr = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if bgr is None:
        raise SystemExit(f"bench_surfaces: cannot read {path}")
    if bgr.shape[1] != width:
        bgr = cv2.resize(bgr, (width, width // 2), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(bgr[..., ::-1])


def rendered_room(width: int = 1024) -> np.ndarray:
    from layout.labelmap import sample_camera_xy
    from layout.rooms import generate_room
    from panogeom.raycast import raycast_equirect, room_meshes
    from panogeom.texture import sample_post, sample_styles, shade

    rng = np.random.default_rng([2500, 0])
    room = generate_room(rng)
    room = room.translated(-sample_camera_xy(room.floor, rng, margin=0.6))
    meshes = [room_meshes(room.floor, room.ceiling_z)]
    res = raycast_equirect(meshes, width, camera_position=(0.0, 0.0, 1.5))
    return shade(res, meshes, materials=sample_styles(rng), rng=rng, post=sample_post(rng))


def update_docs(text: str, path: Path) -> None:
    """Replace this script's section (benchmarks/_docs.py)."""
    replace_section(path, text, SECTION)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--synth", default=str(REPO / "out" / "train" / "surfaces" / "test"))
    ap.add_argument("--update-docs", action="store_true", help="write the section into docs/BENCHMARKS.md")
    args = ap.parse_args(argv)
    import torch

    from layout.surfaces import estimate_surfaces, fuse_surfaces, load_gc_net, orientation_map
    from panogeom.lines import detect_line_segments

    cases = []
    synth_room = Path(args.synth) / "room-0000" / "pano.png"
    if synth_room.is_file():
        cases.append((f"synthetic {Path(args.synth).name}/room-0000", load_pano(synth_room)))
    else:
        cases.append(("rendered empty room (no synth set found)", rendered_room()))
    if REAL.is_dir():
        for d in sorted(REAL.iterdir()):
            gt = d / "gt.json"
            if gt.is_file():
                cases.append((d.name, load_pano(d / json.loads(gt.read_text())["image"]["file"])))
    gc = load_gc_net()
    default_threads = torch.get_num_threads()
    rows = []
    for name, pano in cases:
        W = pano.shape[1]
        segs = detect_line_segments(pano)
        probs = gc(pano)
        om = orientation_map(segs, W)
        torch.set_num_threads(default_threads)
        t_lines = med(lambda: detect_line_segments(pano), args.repeat)
        t_om = med(lambda: orientation_map(segs, W), args.repeat)
        t_gc = med(lambda: gc(pano), args.repeat)
        t_fuse = med(lambda: fuse_surfaces(probs, om), args.repeat)
        t_total = med(lambda: estimate_surfaces(pano, segs, gc=gc), args.repeat)
        t_all = med(lambda: estimate_surfaces(pano, gc=gc), args.repeat)
        torch.set_num_threads(1)
        t_gc1 = med(lambda: gc(pano), args.repeat)
        t_total1 = med(lambda: estimate_surfaces(pano, segs, gc=gc), args.repeat)
        torch.set_num_threads(default_threads)
        rows.append((name, f"{W}x{W // 2}", len(segs), t_lines, t_om, t_gc, t_gc1, t_fuse, t_total, t_total1, t_all))

    def f(t):
        return f"{t[0] * 1000:.0f} ({t[1] * 1000:.0f})"

    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    lines = [SECTION, "",
             "`.venv/bin/python benchmarks/bench_surfaces.py --update-docs` (this section is written by the "
             "script). Stages of `layout.surfaces.estimate_surfaces`: orientation map (line sweeps on the sphere, "
             "512x256 sweep rasters), geometric context (the committed network at its 512x256 working size, "
             "probabilities resized to the panorama), fusion (column boundaries, wall-orientation chain, "
             "per-pixel labels). Target: OM + GC + fusion < 3 s at 1024x512 on 2 cores, with the line segments "
             "given (they come from the rectification). "
             f"Medians of {args.repeat} runs after a warm-up; CPU ms of the process, wall ms in brackets.", "",
             f"| panorama | size | segments | lines (reference) | OM | GC, torch {default_threads} threads | "
             "GC, 1 thread | fusion | **OM + GC + fusion** | same, torch 1 thread | with line detection |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r[0]} | {r[1]} | {r[2]} | {f(r[3])} | {f(r[4])} | {f(r[5])} | {f(r[6])} | {f(r[7])} | "
                     f"**{f(r[8])}** | {f(r[9])} | {f(r[10])} |")
    lines += ["", f"Environment: python {platform.python_version()}, numpy {np.__version__}, "
                  f"torch {torch.__version__}, opencv {cv2.__version__}, {os.cpu_count()} CPUs, {platform.machine()}, "
                  f"load average {load:.1f} at the end of the run (the machine is shared with other jobs).", ""]
    text = "\n".join(lines)
    print(text)
    if args.update_docs:
        update_docs(text, REPO / "docs" / "BENCHMARKS.md")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
