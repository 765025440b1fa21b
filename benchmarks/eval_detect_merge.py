"""How the panorama driver merges tile detections: AP of the merge rules on the same raw tile detections.

Run::

    pano2cad synth --rooms 30 --seed 7000 --size 1024 --out out/tune7000
    pano2cad synth --rooms 60 --seed 8000 --size 1024 --out out/tune8000
    .venv/bin/python benchmarks/eval_detect_merge.py out/tune7000 out/tune8000 [--update-docs]

The builtin detector runs once on the tiles of every room (its own view set,
:func:`detect.tiles.tile_detections`); the raw tile detections are then merged
by each rule and scored by panorama AP@0.5 (:mod:`detect.builtin.evaluate`):

- *tile centre, max score*: the rule before session 4, kept here as the peer:
  the representative is the untruncated member scoring within 0.1 of the best
  that is seen closest to its tile's centre, the score the group's best;
- *medoid, max score*: :func:`detect.nms.merge_sphere` (the group's medoid
  box), the group's best score;
- *medoid, tile consensus*: the driver's default,
  :func:`detect.tiles.tile_consensus` with weight 0.5.

These seeds are the tuning sets of the merge rules (the evaluation set, seed
0, is scored by ``benchmarks/eval_detect.py`` and ``pano2cad eval``).
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import EVALUATION_MD, publish  # noqa: E402

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

SECTION = "## How tile detections are merged (detect.nms, detect.tiles)"


def _centre_rule(groups):
    """The pre-session-4 representative: near-best untruncated member closest to its tile's centre."""
    out = []
    for merged, members in groups:
        whole = [m for m in members if m.tile is not None and not m.tile.truncated]
        if whole:
            best = max(m.score for m in whole)
            near = [m for m in whole if m.score >= best - 0.1]

            def off_axis(m):
                return float(np.arccos(np.clip(m.tile.centre_ray() @ m.tile.view.direction, -1.0, 1.0)))

            rep = min(near, key=off_axis)
            merged = replace(rep, score=merged.score, support=merged.support)
        out.append(merged)
    return out


def main(argv: list[str] | None = None) -> int:
    import cv2

    from detect.builtin import BuiltinDetector
    from detect.builtin.data import room_folders
    from detect.builtin.evaluate import evaluate, load_ground_truth
    from detect.nms import merge_sphere
    from detect.tiles import tile_consensus, tile_detections

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("sets", nargs="+", type=Path, help="folders of synthetic rooms (pano2cad synth output)")
    ap.add_argument("--update-docs", action="store_true", help="write the section into docs/EVALUATION.md")
    args = ap.parse_args(argv)

    det = BuiltinDetector(score_threshold=0.05)
    views = det.views()
    raw, truths = {}, []
    t0 = time.perf_counter()
    for root in args.sets:
        idx = root / "index.json"
        if idx.is_file() and json.loads(idx.read_text()).get("seed") == 0:
            raise SystemExit(f"{root}: seed 0 is the evaluation set, not a tuning set")
        for f in room_folders(root):
            name = f"{root.name}/{f.name}"
            rgb = cv2.cvtColor(cv2.imread(str(f / "pano.png")), cv2.COLOR_BGR2RGB)
            raw[name] = tile_detections(rgb, det, views)
            truths.append(replace(load_ground_truth(f), name=name))
    secs = time.perf_counter() - t0
    groups = {k: merge_sphere(v) for k, v in raw.items()}
    rules = {
        "tile centre, max score (before)": {k: _centre_rule(g) for k, g in groups.items()},
        "medoid, max score": {k: [m for m, _ in g] for k, g in groups.items()},
        "medoid, tile consensus 0.5 (default)": {k: tile_consensus(g, views) for k, g in groups.items()},
    }
    classes = list(det.classes)
    paper = ["bed", "chair", "tv", "plant"]
    lines = [SECTION, "",
             "`.venv/bin/python benchmarks/eval_detect_merge.py " + " ".join(str(s) for s in args.sets) +
             " --update-docs` (this section is written by the script; see its docstring). "
             f"{len(truths)} rooms of the tuning seeds, the builtin detector on its {len(views)} views, "
             f"raw tile detections computed once ({secs:.0f} s) and merged by each rule; panorama AP@0.5.", "",
             "| merge rule | " + " | ".join(classes) + " | mean of bed, chair, TV, plant | mean |",
             "|---|" + "---:|" * (len(classes) + 2)]
    for name, dets in rules.items():
        res = evaluate(dets, truths, classes)
        aps = [res.ap(c) for c in classes]
        lines.append(f"| {name} | " + " | ".join(f"{a:.3f}" for a in aps) +
                     f" | {np.mean([res.ap(c) for c in paper]):.3f} | {np.mean(aps):.3f} |")
    publish(lines, args.update_docs, EVALUATION_MD, SECTION)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
