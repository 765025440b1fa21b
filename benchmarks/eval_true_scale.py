"""How much of a run's object position error is the shared scale: positions as estimated and at the true scale.

Run::

    pano2cad eval --data out/tune7000 --out out/s7/views_tune7000 --detector builtin --samples 3000
    .venv/bin/python benchmarks/eval_true_scale.py out/tune7000,out/tune8000 \\
        out/s7/views_tune7000,out/s7/views_tune8000 [--scene scene_init.json]

A room's whole scene scales with its camera height (positions are metres from the camera, on the floor): each
room's predicted object centres are multiplied by ``true / estimated camera height``. The objects of each class are
paired with the room's ground-truth objects (those visible in the panorama) by a Hungarian assignment on floor
distance in both cases, without a distance gate (so the means are larger than those of ``pano2cad eval``, which
leaves far pairs unmatched). Printed per class: pairs, mean and median error as estimated and at the true scale.
A run with the scale given (``--camera-height``, ``--gt-scale``) shows no difference.

Also printed, per set: the layout 3D IoU of the rooms (:func:`layout.metrics.score_layout`, as ``pano2cad eval``)
as estimated and with the room (floor polygon and ceiling) scaled the same way, with the camera height's relative
error (median, mean, rooms more than 5 % off): what the scale alone costs the layout; and the mean wall-height
error of answering one constant wall height for every room (``--constant-wall``, default 2.7 m, the mean of the
generator's N(2.7, 0.2) m; paper Sec. 5), the floor any scale estimate has to beat.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path
from typing import Iterator

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

CLASSES = ("bed", "chair", "tv", "plant")
FloatArray = NDArray[np.float64]


def room_dirs(data: Path, run: Path, scene: str = "scene.json") -> list[Path]:
    """The room folders of ``run`` holding ``scene`` whose room has a gt.json in ``data``, sorted."""
    return sorted(p for p in run.iterdir() if (p / scene).is_file() and (data / p.name / "gt.json").is_file())


def scaled_rooms(data: Path, run: Path, scene: str = "scene.json") -> Iterator[tuple[dict, dict, float]]:
    """Per room of :func:`room_dirs`: (gt, predicted scene, true / estimated camera height)."""
    for room in room_dirs(data, run, scene):
        gt = json.loads((data / room.name / "gt.json").read_text())
        sc = json.loads((room / scene).read_text())
        yield gt, sc, float(gt["camera_height_m"]) / float(sc["camera"]["height_m"])


def sets_and_runs(ap: argparse.ArgumentParser, argv: list[str] | None) -> tuple[argparse.Namespace, list[Path],
                                                                                  list[Path]]:
    """Parse ``data runs [--scene]`` (and whatever else ``ap`` has); the comma-separated sets and runs."""
    ap.add_argument("data", help="synthetic sets (pano2cad synth output), comma-separated")
    ap.add_argument("runs", help="pano2cad eval --out folders of those sets, comma-separated, same order")
    ap.add_argument("--scene", default="scene.json", help="scene.json (with context) or scene_init.json")
    args = ap.parse_args(argv)
    data, runs = [Path(p) for p in args.data.split(",")], [Path(p) for p in args.runs.split(",")]
    if len(data) != len(runs):
        ap.error(f"expected as many runs as sets, got {len(runs)} and {len(data)}")
    return args, data, runs


def position_errors(data: Path, run: Path, scene: str = "scene.json") -> dict[str, dict[str, list[float]]]:
    """Per mode ('estimated', 'true scale') and class: the paired floor distances, metres."""
    out: dict[str, dict[str, list[float]]] = {"estimated": defaultdict(list), "true scale": defaultdict(list)}
    for gt, sc, k in scaled_rooms(data, run, scene):
        for c in CLASSES:
            g = np.array([o["center"][:2] for o in gt["objects"] if o["class"] == c and o["bbox_pano"] is not None],
                         dtype=np.float64).reshape(-1, 2)
            p = np.array([o["center"][:2] for o in sc["objects"] if o["class"] == c], dtype=np.float64).reshape(-1, 2)
            if not len(g) or not len(p):
                continue
            for mode, s in (("estimated", 1.0), ("true scale", k)):
                d = np.linalg.norm(g[:, None] - s * p[None], axis=-1)
                i, j = linear_sum_assignment(d)
                out[mode][c].extend(d[i, j].tolist())
    return out


def layout_at_true_scale(data: Path, run: Path, scene: str = "scene.json") -> dict[str, FloatArray]:
    """Per room with a scene (R rooms): ``iou_est`` and ``iou_true`` (R,), the 3D IoU as estimated and at the true
    scale; ``camera`` (R,), the camera height's relative error ``estimated / true - 1``; ``ratio`` (R,), that of the
    wall-to-camera-height ratio (which no scale changes)."""
    from layout.metrics import score_layout

    rows: dict[str, list] = defaultdict(list)
    for gt, sc, k in scaled_rooms(data, run, scene):
        floor, ceil = np.asarray(sc["room"]["floor"], dtype=np.float64), float(sc["room"]["ceiling_z"])
        g_floor, g_ceil = gt["room"]["floor"], float(gt["room"]["ceiling_z"])
        for key, s in (("iou_est", 1.0), ("iou_true", k)):
            rows[key].append(score_layout(s * floor, s * ceil, g_floor, g_ceil,
                                          camera_height=float(gt["camera_height_m"]),
                                          width=int(gt["image"]["width"])).iou_3d)
        rows["camera"].append(1.0 / k - 1.0)
        rows["ratio"].append(ceil / float(sc["camera"]["height_m"]) / (g_ceil / float(gt["camera_height_m"])) - 1.0)
    return {key: np.array(v) for key, v in rows.items()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--constant-wall", type=float, default=2.7, help="the constant wall height guessed, metres")
    args, data, runs = sets_and_runs(ap, argv)
    pooled: dict[str, dict[str, list[float]]] = {"estimated": defaultdict(list), "true scale": defaultdict(list)}
    for d, r in zip(data, runs):
        for mode, per in position_errors(d, r, args.scene).items():
            for c, v in per.items():
                pooled[mode][c].extend(v)
    print(f"    .venv/bin/python benchmarks/eval_true_scale.py {args.data} {args.runs} --scene {args.scene}\n")
    print("| class | pairs | estimated scale: mean / median (cm) | true scale: mean / median (cm) |")
    print("|---|---:|---:|---:|")
    for c in CLASSES:
        a, b = np.array(pooled["estimated"][c]), np.array(pooled["true scale"][c])
        if a.size:
            print(f"| {c} | {a.size} | {100 * a.mean():.1f} / {100 * np.median(a):.1f} | "
                  f"{100 * b.mean():.1f} / {100 * np.median(b):.1f} |")
    per_set: dict[str, tuple[list[Path], dict[str, FloatArray]]] = {}
    print("\n| set | rooms | layout 3D IoU estimated: mean / median | at the true scale: mean / median | "
          "camera height error: median / mean | rooms > 5 % |\n|---|---:|---:|---:|---:|---:|")
    for d, r in zip(data, runs):
        lay = layout_at_true_scale(d, r, args.scene)
        if lay:  # empty where the run has no scene of the set's rooms
            est, true, a = lay["iou_est"], lay["iou_true"], np.abs(lay["camera"])
            print(f"| {d} | {est.size} | {est.mean():.3f} / {np.median(est):.3f} | {true.mean():.3f} / "
                  f"{np.median(true):.3f} | {100 * np.median(a):.1f} % / {100 * a.mean():.1f} % | "
                  f"{int(np.count_nonzero(a > 0.05))} |")
            per_set[str(r)] = (room_dirs(d, r, args.scene), lay)
    print("\nrooms whose camera height is more than 5 % off: camera height error, wall-to-camera-height ratio error, "
          "3D IoU estimated -> at the true scale")
    for run_name, (dirs, lay) in per_set.items():
        for k in np.flatnonzero(np.abs(lay["camera"]) > 0.05):
            print(f"    {run_name}/{dirs[k].name}: camera {100 * lay['camera'][k]:+.1f} %, ratio "
                  f"{100 * lay['ratio'][k]:+.1f} %, 3D IoU {lay['iou_est'][k]:.3f} -> {lay['iou_true'][k]:.3f}")
    for d in data:
        walls = np.array([json.loads(f.read_text())["room"]["ceiling_z"] for f in sorted(d.glob("*/gt.json"))])
        if walls.size:
            print(f"\n{d}: {walls.size} rooms, wall height {walls.mean():.3f} +- {walls.std():.3f} m; answering "
                  f"{args.constant_wall:g} m for every room: mean error "
                  f"{100 * np.abs(walls - args.constant_wall).mean():.1f} cm")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
