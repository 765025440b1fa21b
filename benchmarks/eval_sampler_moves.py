"""What the posterior sampler does to the objects it starts from, grouped by how far each starts through a wall.

Run::

    pano2cad eval --data out/tune7000 --out out/RUN7000 --detector builtin --samples 3000
    .venv/bin/python benchmarks/eval_sampler_moves.py out/RUN7000 out/tune7000 [RUN DATA ...] [--update-docs]

For every object of every room of each ``pano2cad eval`` run, ``scene_init.json`` (the sampler's initial
hypothesis: box fit at the shared camera height) is set against ``scene.json`` (its result). The object is
paired with the nearest ground-truth object of its class within 1 m of its initial position (others are left
out). Groups: how far the initial footprint reaches through the walls of the estimated floor polygon (largest
distance of a corner outside it, metres). Per group: objects, share with the true model at the start, share
whose initial yaw is more than 45 degrees off (symmetric classes included, at whatever yaw they have), mean
floor-position error at the start and at the end (cm), the mean radial motion (away from the camera positive,
cm), the mean radial motion that would have reached the true position, and the mean sideways motion.
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import EVALUATION_MD, replace_section  # noqa: E402

import argparse
import json
from pathlib import Path

import numpy as np

from layout.polygon import distance_to_boundary, oriented_rectangles, points_in_polygon

SECTION = "## What the sampler does to the objects it starts from (eval_sampler_moves.py)"
GROUPS = ((0.0, 0.0), (0.0, 0.15), (0.15, 0.4), (0.4, float("inf")))


def _depth(obj: dict, floor: np.ndarray) -> float:
    """Largest distance of a footprint corner outside ``floor`` from its boundary (0 inside), metres."""
    rect = oriented_rectangles(np.array(obj["center"][:2])[None], np.radians([obj["yaw_deg"]]),
                               np.array(obj["size"][:2])[None])[0]
    out = ~points_in_polygon(rect, floor)
    return float(distance_to_boundary(rect[out], floor).max()) if out.any() else 0.0


def object_rows(run: Path, data: Path) -> list[tuple[float, ...]]:
    """(depth, right model, yaw > 45 off, init error, final error, radial move, needed radial, sideways), metres."""
    rows = []
    for room in sorted(p for p in run.glob("room-*") if (p / "scene.json").is_file()):
        final = json.loads((room / "scene.json").read_text())
        init = json.loads((room / "scene_init.json").read_text())
        gt = json.loads((data / room.name / "gt.json").read_text())
        floor = np.array(init["room"]["floor"], dtype=np.float64)
        ends = {o["id"]: o for o in final["objects"]}
        for o in init["objects"]:
            if o["id"] not in ends:
                continue
            c0 = np.array(o["center"][:2])
            c1 = np.array(ends[o["id"]]["center"][:2])
            same = [g for g in gt["objects"] if g["class"] == o["class"]]
            if not same:
                continue
            dist = [float(np.linalg.norm(np.array(g["center"][:2]) - c0)) for g in same]
            k = int(np.argmin(dist))
            if dist[k] > 1.0:
                continue
            g = same[k]
            gc = np.array(g["center"][:2])
            u = c0 / max(float(np.linalg.norm(c0)), 1e-9)
            move = c1 - c0
            radial = float(move @ u)
            yaw_off = abs((o["yaw_deg"] - g["yaw_deg"] + 180.0) % 360.0 - 180.0) > 45.0
            rows.append((_depth(o, floor), float(o.get("model") == g.get("model")), float(yaw_off),
                         float(np.linalg.norm(c0 - gc)), float(np.linalg.norm(c1 - gc)), radial,
                         float((gc - c0) @ u), float(np.linalg.norm(move - radial * u))))
    return rows


def table(rows: list[tuple[float, ...]]) -> str:
    """The Markdown table of the module docstring."""
    r = np.array(rows, dtype=np.float64).reshape(-1, 8)
    lines = ["| start through a wall | objects | true model | yaw > 45 deg off | error at start (cm) | error at end (cm) "
             "| radial move (cm) | radial move to the truth (cm) | sideways move (cm) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for lo, hi in GROUPS:
        m = r[:, 0] == 0.0 if hi == 0.0 else (r[:, 0] > lo) & (r[:, 0] <= hi)
        name = "inside" if hi == 0.0 else (f"> {lo:g} m" if hi == float("inf") else f"{lo:g}-{hi:g} m")
        a = r[m]
        if not len(a):
            lines.append(f"| {name} | 0 | | | | | | | |")
            continue
        lines.append(f"| {name} | {len(a)} | {a[:, 1].mean():.0%} | {a[:, 2].mean():.0%} | {100 * a[:, 3].mean():.1f} "
                     f"| {100 * a[:, 4].mean():.1f} | {100 * a[:, 5].mean():+.1f} | {100 * a[:, 6].mean():+.1f} "
                     f"| {100 * a[:, 7].mean():.1f} |")
    lines.append(f"| all | {len(r)} | {r[:, 1].mean():.0%} | {r[:, 2].mean():.0%} | {100 * r[:, 3].mean():.1f} "
                 f"| {100 * r[:, 4].mean():.1f} | {100 * r[:, 5].mean():+.1f} | {100 * r[:, 6].mean():+.1f} "
                 f"| {100 * r[:, 7].mean():.1f} |")
    return "\n".join(lines).replace("%", " %")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("pairs", nargs="+", help="RUN DATA [RUN DATA ...]: a pano2cad eval output and its synthetic set")
    ap.add_argument("--update-docs", action="store_true", help="write the table into docs/EVALUATION.md")
    args = ap.parse_args(argv)
    if len(args.pairs) % 2:
        ap.error("expected RUN DATA pairs")
    rows: list[tuple[float, ...]] = []
    for run, data in zip(args.pairs[::2], args.pairs[1::2]):
        if not Path(run).is_dir() or not Path(data).is_dir():
            ap.error(f"not a folder: {run if not Path(run).is_dir() else data}")
        rows += object_rows(Path(run), Path(data))
    if not rows:
        ap.error("no object paired with the ground truth")
    cmd = "    .venv/bin/python benchmarks/eval_sampler_moves.py " + " ".join(args.pairs)
    text = "\n".join([SECTION, "", cmd, "", f"`benchmarks/eval_sampler_moves.py` (this section is written by the script; "
                      "see its docstring for the pairing and the groups).", "", table(rows)])
    print(text)
    if args.update_docs:
        replace_section(EVALUATION_MD, text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
