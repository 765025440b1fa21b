"""``pano2cad synth``: a synthetic set of rooms with ground truth (see :mod:`apps.synth`)."""

from __future__ import annotations

import multiprocessing as mp
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from .errors import UserError
from .outdir import prepare_out_dir
from .progress import Progress

_LIB = None


def _work(index: int, seed: int, size: int, out: str) -> dict:
    global _LIB
    from posecrf.library import builtin_library

    from .synth import make_room, write_room

    if _LIB is None:
        _LIB = builtin_library()
    room = make_room(index, seed, size, _LIB)
    write_room(room, out)
    return _summary(room.name, room.gt)


def _summary(name: str, gt: dict) -> dict:
    counts: dict[str, int] = {}
    for o in gt["objects"]:
        counts[o["class"]] = counts.get(o["class"], 0) + 1
    return {"name": name, "template": gt.get("template"), "n_corners": gt["n_corners"],
            "ceiling_z": gt["room"]["ceiling_z"], "camera_height_m": gt["camera_height_m"], "objects": counts}


def run(args) -> int:
    import json

    from .atomic import write_json
    from .synth import room_is_complete

    if args.rooms < 1:
        raise UserError(f"--rooms: expected at least 1, got {args.rooms}")
    if args.size < 64 or args.size % 2:
        raise UserError(f"--size: expected an even panorama width >= 64, got {args.size}")
    out = prepare_out_dir(args.out)
    prog = Progress(args.quiet)
    jobs = max(1, min(args.jobs or os.cpu_count() or 1, args.rooms))
    todo, summaries = [], {}
    for i in range(args.rooms):
        d = out / f"room-{i:04d}"
        if not args.force and room_is_complete(d):
            summaries[i] = _summary(d.name, json.loads((d / "gt.json").read_text()))
        else:
            todo.append(i)
    prog.say(f"synth: {args.rooms} rooms at {args.size}x{args.size // 2} into {out} "
             f"({len(todo)} to make, {args.rooms - len(todo)} already there, {jobs} processes)")
    with prog.stage("render"):
        if jobs == 1:
            for i in prog.bar(todo, total=len(todo), desc="rooms"):
                summaries[i] = _work(i, args.seed, args.size, str(out))
        else:
            ctx = mp.get_context("fork")
            with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as ex:
                futs = {ex.submit(_work, i, args.seed, args.size, str(out)): i for i in todo}
                for f in prog.bar(as_completed(futs), total=len(futs), desc="rooms"):
                    summaries[futs[f]] = f.result()
    index = {"schema": "pano2cad/synth-index@1", "seed": args.seed, "size": [args.size, args.size // 2],
             "rooms": [summaries[i] for i in range(args.rooms)]}
    write_json(out / "index.json", index)
    prog.say(f"synth: wrote {args.rooms} rooms and index.json to {out} in {prog.total():.1f} s")
    return 0
