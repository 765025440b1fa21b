"""Side by side: the Table-2 figures of several ``pano2cad eval`` runs, pooled over the sets each one ran on.

Run::

    pano2cad eval --data out/tune7000 --out out/crop_box/tune7000 --detector builtin --samples 3000 --crop box
    pano2cad eval --data out/tune7000 --out out/crop_tile/tune7000 --detector builtin --samples 3000
    (the same for out/tune8000)
    .venv/bin/python benchmarks/compare_evals.py box=out/crop_box/tune7000,out/crop_box/tune8000 \\
        tile=out/crop_tile/tune7000,out/crop_tile/tune8000 [--update-docs --heading "## ..."]

Each ``NAME=RUN[,RUN...]`` is one variant; its figures pool the rooms of all its runs (the per-room records of
each run's eval.json): mean position and orientation error with the context term per class over every matched
object, the share of orientations more than 45 degrees off, matched / ground-truth objects, mean wall-height error,
mean absolute camera-height error and mean layout 3D IoU over the rooms. The variants must have run on the same
rooms (checked: the same room names per set).

``--changed CLASS`` also prints (not into the docs) the rooms where the matched objects of CLASS differ between
the first two variants: their position errors (cm) and orientation errors (deg) in each, rooms ordered by how
much the summed position error grew. ``--changed layout`` prints instead the rooms whose layout 3D IoU differs
by more than 0.01, ordered by the change.
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import EVALUATION_MD, publish  # noqa: E402

import argparse
import json
import shlex
from pathlib import Path

import numpy as np

CLASSES = ("bed", "chair", "tv", "plant")


def pooled(runs: list[Path]) -> tuple[dict, list[str]]:
    """Figures of one variant over the rooms of its runs, and the room names (``set/room``)."""
    pos: dict[str, list[float]] = {c: [] for c in CLASSES}
    ori: dict[str, list[float]] = {c: [] for c in CLASSES}
    n_gt = {c: 0 for c in CLASSES}
    wall, cam, iou, names = [], [], [], []
    for run in runs:
        ev = json.loads((run / "eval.json").read_text())
        for r in ev["rooms"]:
            names.append(f"{run.name}/{r['name']}")
            lay = r.get("layout") or {}
            iou.append(float(lay.get("iou_3d", 0.0)))
            if lay.get("wall_height_err") is not None:
                wall.append(100.0 * float(lay["wall_height_err"]))
            if lay.get("camera_height_err") is not None:
                cam.append(float(lay["camera_height_err"]))
            for c in CLASSES:
                o = (r.get("objects") or {}).get(c)
                if o:
                    n_gt[c] += int(o["n_gt"])
                    pos[c] += [100.0 * p for p in o["pos"]]
                    ori[c] += list(o["orient"])
    fig = {"pos": {c: np.array(pos[c]) for c in CLASSES}, "ori": {c: np.array(ori[c]) for c in CLASSES},
           "n_gt": n_gt, "wall": np.array(wall), "cam": np.array(cam), "iou": np.array(iou)}
    return fig, sorted(names)


def _m(a: np.ndarray) -> str:
    return f"{a.mean():.1f}" if len(a) else "n/a"


def table(variants: dict[str, dict]) -> list[str]:
    names = list(variants)
    lines = ["| figure (with context term) | " + " | ".join(names) + " |", "|---|" + "---:|" * len(names)]
    for c in CLASSES:
        lines.append(f"| position {c} (cm, mean) | " + " | ".join(_m(v["pos"][c]) for v in variants.values()) + " |")
    for c in CLASSES[:3]:
        lines.append(f"| orientation {c} (deg, mean) | " + " | ".join(_m(v["ori"][c]) for v in variants.values()) + " |")
        lines.append(f"| orientation {c} > 45 deg off | " + " | ".join(
            f"{100.0 * np.mean(v['ori'][c] > 45.0):.0f} %" if len(v["ori"][c]) else "n/a" for v in variants.values())
            + " |")
    for c in CLASSES:
        lines.append(f"| matched {c} | " + " | ".join(f"{len(v['pos'][c])} / {v['n_gt'][c]}" for v in variants.values())
                     + " |")
    lines.append("| wall height (cm, mean) | " + " | ".join(_m(v["wall"]) for v in variants.values()) + " |")
    lines.append("| camera height (m, mean abs error) | " + " | ".join(
        f"{v['cam'].mean():.3f}" if len(v["cam"]) else "n/a" for v in variants.values()) + " |")
    lines.append("| layout 3D IoU (mean) | " + " | ".join(f"{v['iou'].mean():.3f}" for v in variants.values()) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("variants", nargs="+", help="NAME=RUN[,RUN...] (pano2cad eval output folders)")
    ap.add_argument("--update-docs", action="store_true", help="write the table into docs/EVALUATION.md")
    ap.add_argument("--heading", default="## Variants of the pipeline compared (compare_evals.py)",
                    help="the docs section ('## ...') the table goes to")
    ap.add_argument("--note", default="", help="a line written under the command in the docs section")
    ap.add_argument("--changed", metavar="CLASS", help="print the rooms where CLASS (or 'layout': the layout 3D IoU) "
                                                        "differs between the first two variants")
    args = ap.parse_args(argv)
    variants, rooms = {}, None
    for spec in args.variants:
        name, _, paths = spec.partition("=")
        if not name or not paths:
            raise SystemExit(f"{spec}: expected NAME=RUN[,RUN...]")
        runs = [Path(p) for p in paths.split(",")]
        for r in runs:
            if not (r / "eval.json").is_file():
                raise SystemExit(f"{r}: no eval.json (run pano2cad eval --out {r} first)")
        fig, names = pooled(runs)
        if rooms is not None and [n.split("/", 1)[1] for n in names] != [n.split("/", 1)[1] for n in rooms]:
            raise SystemExit(f"{name}: its runs cover other rooms than the first variant's")
        rooms = rooms or names
        variants[name] = fig
    cmd = "    .venv/bin/python benchmarks/compare_evals.py " + " ".join(shlex.quote(v) for v in args.variants)
    lines = [args.heading, "", cmd, ""] + ([args.note, ""] if args.note else [])
    lines += [f"{len(rooms)} rooms per variant.", ""] + table(variants)
    publish(lines, args.update_docs, EVALUATION_MD, args.heading)
    if args.changed:
        if len(args.variants) < 2:
            raise SystemExit("--changed: expected two variants or more")
        print("\n".join(changed_rooms(*[[Path(p) for p in v.partition("=")[2].split(",")] for v in args.variants[:2]],
                                       args.changed)))
    return 0


def changed_rooms(first: list[Path], second: list[Path], cls: str) -> list[str]:
    """Lines ``room: pos [cm...] -> [cm...], orient [deg...] -> [deg...]`` where ``cls`` differs (``--changed``)."""
    def per_room(runs: list[Path]) -> dict[str, dict]:
        out = {}
        for run in runs:
            for r in json.loads((run / "eval.json").read_text())["rooms"]:
                out[f"{run.name}/{r['name']}"] = (r.get("objects") or {}).get(cls, {})
        return out

    if cls == "layout":
        return changed_layouts(first, second)
    a, b = per_room(first), per_room(second)
    rows = []
    for (name, x), y in zip(a.items(), b.values()):
        pa, pb = x.get("pos", []), y.get("pos", [])
        oa, ob = x.get("orient", []), y.get("orient", [])
        if pa != pb or oa != ob:
            rows.append((sum(pb) - sum(pa), f"{name}: position {[round(100 * v) for v in pa]} -> "
                         f"{[round(100 * v) for v in pb]} cm, orientation {[round(v) for v in oa]} -> "
                         f"{[round(v) for v in ob]} deg"))
    return [f"{len(rows)} rooms where {cls} differs, by growth of the summed position error:"] + \
        [line for _, line in sorted(rows, key=lambda t: -t[0])]


def changed_layouts(first: list[Path], second: list[Path], min_change: float = 0.01) -> list[str]:
    """Lines ``room: 3D IoU a -> b`` where the layout 3D IoU moved by more than ``min_change`` (``--changed layout``)."""
    def per_room(runs: list[Path]) -> dict[str, float]:
        return {f"{run.name}/{r['name']}": float((r.get("layout") or {}).get("iou_3d", 0.0))
                for run in runs for r in json.loads((run / "eval.json").read_text())["rooms"]}

    # the variants ran on the same rooms in the same order (checked by main); names from the first variant
    rows = sorted(((y - x, n, x, y) for (n, x), y in zip(per_room(first).items(), per_room(second).values())
                   if abs(y - x) > min_change), reverse=True)
    return [f"{len(rows)} rooms whose layout 3D IoU moved by more than {min_change}:"] + \
        [f"{n}: 3D IoU {x:.3f} -> {y:.3f}" for _, n, x, y in rows]


if __name__ == "__main__":
    raise SystemExit(main())
