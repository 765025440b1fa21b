"""How often the model choice retrieves the true library model, and what a wrong one costs in position.

Run::

    pano2cad eval --data out/tune7000 --out out/RUN7000 --detector builtin --samples 3000
    (the same for out/tune8000)
    .venv/bin/python benchmarks/eval_model_choice.py NAME=out/RUN7000:out/tune7000,out/RUN8000:out/tune8000 \\
        [NAME=...] [--init]

Each ``NAME=RUN:DATA[,RUN:DATA...]`` is one variant: ``pano2cad eval`` output folders (one ``scene.json`` per
room) and the synthetic sets they ran on (``gt.json`` per room, whose objects name their library model). The
objects of each room are matched to the ground truth as the eval matches them
(:func:`layout.objectmetrics.match_pairs`, Hungarian per class on floor distance, 1.5 m gate). Per class and
variant: matched objects, the share whose model is the true one, and the mean floor-position error (cm) of those
with the true model and of those with another. ``--init`` reads ``scene_init.json`` (the sampler's start: the
model choice's fit) instead of ``scene.json``. For runs on ground-truth boxes (``--detector gt-boxes``),
``benchmarks/eval_scale.py`` pairs the objects by id instead and gives the share at the sampler's start.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from layout.objectmetrics import ObjectRecord, match_pairs

CLASSES = ("bed", "chair", "tv", "plant", "nightstand", "sofa", "table", "wardrobe")


def model_pairs(run: Path, data: Path, scene_name: str = "scene.json") -> dict[str, list[tuple[bool, float]]]:
    """Per class: ``(true model, position error m)`` of every matched object of every room of one run."""
    out: dict[str, list[tuple[bool, float]]] = {c: [] for c in CLASSES}
    scenes = sorted(run.glob(f"*/{scene_name}"))
    if not scenes:
        raise SystemExit(f"error: no */{scene_name} under {run}")
    n_data = len(list(data.glob("*/gt.json")))
    if n_data != len(scenes):  # the runs record no set id: a different room count is the mix-up this catches
        raise SystemExit(f"error: {run} has {len(scenes)} rooms, {data} has {n_data}: is it the set the run ran on?")
    for sj in scenes:
        gt_path = data / sj.parent.name / "gt.json"
        if not gt_path.is_file():
            raise SystemExit(f"error: {gt_path} missing (is {data} the set {run} ran on?)")
        gt = json.loads(gt_path.read_text())["objects"]
        pred = json.loads(sj.read_text())["objects"]
        pairs = match_pairs([ObjectRecord.from_json(o) for o in pred], [ObjectRecord.from_json(o) for o in gt])
        for cls, matched in pairs.items():
            for gi, pj, dist in matched:
                out.setdefault(cls, []).append((pred[pj].get("model") == gt[gi].get("model"), dist))
    return out


def table(variants: dict[str, dict[str, list[tuple[bool, float]]]]) -> list[str]:
    """Markdown rows: one per class, three columns per variant."""
    names = list(variants)
    head = "| class | " + " | ".join(f"{n}: matched | true model | error, true / other (cm)" for n in names) + " |"
    lines = [head, "|---|" + "---:|---:|---:|" * len(names)]
    for cls in CLASSES:
        cells = []
        for n in names:
            v = variants[n].get(cls, [])
            if not v:
                cells += ["0", "n/a", "n/a"]
                continue
            ok = np.array([a for a, _ in v])
            err = np.array([d for _, d in v]) * 100.0
            true_err, other_err = (f"{err[m].mean():.1f}" if m.any() else "n/a" for m in (ok, ~ok))
            cells += [str(len(v)), f"{100.0 * ok.mean():.0f} %", f"{true_err} / {other_err}"]
        lines.append(f"| {cls} | " + " | ".join(cells) + " |")
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("variants", nargs="+", help="NAME=RUN:DATA[,RUN:DATA...]")
    ap.add_argument("--init", action="store_true", help="read scene_init.json (the sampler's start)")
    args = ap.parse_args(argv)
    variants: dict[str, dict[str, list[tuple[bool, float]]]] = {}
    for spec in args.variants:
        name, sep, rest = spec.partition("=")
        if not sep or not rest:
            ap.error(f"expected NAME=RUN:DATA[,RUN:DATA...], got {spec!r}")
        pooled: dict[str, list[tuple[bool, float]]] = {}
        for item in rest.split(","):
            run, sep, data = item.partition(":")
            if not sep:
                ap.error(f"expected RUN:DATA, got {item!r}")
            for cls, v in model_pairs(Path(run), Path(data), "scene_init.json" if args.init else "scene.json").items():
                pooled.setdefault(cls, []).extend(v)
        variants[name] = pooled
    print("\n".join(table(variants)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
