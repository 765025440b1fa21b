"""Which objects the posterior sampler turns right and which it turns wrong: orientation before and after it.

Run::

    pano2cad eval --data out/tune7000 --out out/RUN7000 --detector builtin --samples 3000
    .venv/bin/python benchmarks/eval_turns.py out/RUN7000 out/tune7000 [RUN DATA ...] [--off 45]

Each object of each room is followed by its id from ``scene_init.json`` (the sampler's initial hypothesis: the
model choice's yaw, box fit at the shared camera height) to ``scene.json`` (the sampler's result). It is paired
with a ground-truth object of its class by Hungarian assignment on the floor distance of its FINAL position
(:func:`layout.objectmetrics.match_pairs`, the pairing of Table 2, gate 1.5 m). Per class, the paired objects are
counted by whether their yaw is within ``--off`` degrees of the truth before and after the sampler: ``ok -> ok``,
``ok -> off`` (the sampler turned a right yaw wrong), ``off -> ok`` (it repaired one) and ``off -> off``.
Rotationally symmetric classes (plant) have no orientation and are left out.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from layout.objectmetrics import SYMMETRIC_CLASSES, TWO_FOLD_CLASSES, ObjectRecord, match_pairs, yaw_error

CLASSES = ("bed", "chair", "tv")
KINDS = ("ok -> ok", "ok -> off", "off -> ok", "off -> off")


def room_turns(init: dict, final: dict, gt: dict, off_deg: float, gate: float = 1.5) -> list[tuple[str, str]]:
    """``(class, kind)`` per paired object of one room (``kind`` one of :data:`KINDS`)."""
    start = {o["id"]: o for o in init.get("objects", [])}
    kept = [o for o in final.get("objects", []) if o["id"] in start]
    truth = [ObjectRecord.from_json(o) for o in gt.get("objects", [])]
    out = []
    for cls, pairs in match_pairs([ObjectRecord.from_json(o) for o in kept], truth, gate).items():
        if cls in SYMMETRIC_CLASSES:
            continue
        fold = 2 if cls in TWO_FOLD_CLASSES else 1
        for i, j, _ in pairs:
            before = float(np.degrees(yaw_error(ObjectRecord.from_json(start[kept[j]["id"]]).yaw, truth[i].yaw, fold)))
            after = float(np.degrees(yaw_error(ObjectRecord.from_json(kept[j]).yaw, truth[i].yaw, fold)))
            out.append((cls, f"{'off' if before > off_deg else 'ok'} -> {'off' if after > off_deg else 'ok'}"))
    return out


def count_turns(pairs: list[tuple[Path, Path]], off_deg: float) -> dict[str, dict[str, int]]:
    """Per class, the number of paired objects of each kind over the rooms of the ``(run, data)`` pairs."""
    counts = {c: {k: 0 for k in KINDS} for c in CLASSES}
    for run, data in pairs:
        for room in sorted(p for p in run.iterdir() if (p / "scene.json").is_file()):
            if not (room / "scene_init.json").is_file() or not (data / room.name / "gt.json").is_file():
                continue
            init = json.loads((room / "scene_init.json").read_text())
            final = json.loads((room / "scene.json").read_text())
            gt = json.loads((data / room.name / "gt.json").read_text())
            for cls, kind in room_turns(init, final, gt, off_deg):
                if cls in counts:
                    counts[cls][kind] += 1
    return counts


def markdown(counts: dict[str, dict[str, int]], off_deg: float) -> str:
    rows = [f"| class | {' | '.join(KINDS)} | net repaired |", "|---|" + "---:|" * (len(KINDS) + 1)]
    for cls, c in counts.items():
        rows.append(f"| {cls} | " + " | ".join(str(c[k]) for k in KINDS) + f" | {c['off -> ok'] - c['ok -> off']:+d} |")
    return (f"Objects paired with the truth, yaw more than {off_deg:g} deg off ('off') or not ('ok') before -> after "
            "the sampler.\n\n" + "\n".join(rows))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", nargs="+", type=Path, help="RUN DATA [RUN DATA ...]: eval output and its data set")
    ap.add_argument("--off", type=float, default=45.0, help="degrees: a yaw farther than this is 'off'")
    args = ap.parse_args(argv)
    if len(args.paths) % 2:
        ap.error("expected pairs RUN DATA")
    pairs = list(zip(args.paths[::2], args.paths[1::2]))
    for run, data in pairs:
        if not run.is_dir() or not data.is_dir():
            ap.error(f"not a folder: {run if not run.is_dir() else data}")
    print(markdown(count_turns(pairs, args.off), args.off))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
