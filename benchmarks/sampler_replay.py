"""The MAP sampler alone, replayed on what the pipeline gave it: change a sampler option, score in a minute.

Run::

    .venv/bin/python benchmarks/sampler_replay.py capture --data out/tune7000 --out out/cap7000 --samples 3000
    .venv/bin/python benchmarks/sampler_replay.py replay out/tune7000 out/cap7000 --set turn_eo_margin=0.2
    .venv/bin/python benchmarks/sampler_replay.py replay out/tune7000,out/tune8000 out/cap7000,out/cap8000 \\
        --seeds 1,2,3 --hook my_hook.py --json rows.json

``capture`` is ``pano2cad eval`` (same options after ``--data`` / ``--out``; every room's outputs and table2.md
as usual) that also pickles, per room, the last call of :func:`layout.sampler.map_estimate` (likelihood, objects,
orientation terms, config, seed) with the rectification's heading and the final scene into
``<out>/<room>/capture.pkl``. The whole pipeline runs once: on the 88 seed-0 rooms about 9 minutes on 2 cores.

``replay`` runs the sampler alone on the captures with config overrides (``--set name=value``, values read as
Python literals), other sampler seeds (``--seeds``) or a hook file (``--hook``: Python run once before the replay;
it may patch :mod:`layout.sampler`, and a function ``before(args, kwargs, room)`` it defines may change each call's
inputs), turns the result into the input's world frame as the pipeline does, and scores it against ``gt.json``
with :func:`apps.evaluation.score_room` (the same matching as ``pano2cad eval``). Without overrides it gives the
captured scenes exactly. It prints the mean position (cm) and orientation (deg) error per class, the matched count,
the wall-height error and the layout 3D IoU; ``--init`` scores the initial hypothesis instead, ``--json`` writes
one row per matched object ``[run/room, seed, class, position m, orientation deg or null]``. About 2 minutes for
the 88 seed-0 rooms on 2 cores (session 43's machine).

Only the sampler's inputs are replayed: a change before the sampler (labels, room step, detections, model choice)
needs a new capture. What the pipeline does when the sampler fails (drop objects one by one) is not replayed: such a
room is reported on stderr and left out.
"""

from __future__ import annotations

import argparse
import ast
import copyreg
import json
import os
import pickle
import sys
import time
import types
from dataclasses import replace
from pathlib import Path

import numpy as np

CLASSES = ("bed", "chair", "tv", "plant")


def _reduce_mapping_proxy(m: types.MappingProxyType) -> tuple:
    return dict, (dict(m),)


def capture(argv: list[str]) -> int:
    """``pano2cad eval`` with the sampler's last call per room pickled (module docstring)."""
    import apps.cmd_eval as cmd_eval
    import apps.pipeline as pipeline
    import layout.sampler as sampler
    from apps.cli import main

    copyreg.pickle(types.MappingProxyType, _reduce_mapping_proxy)  # read-only config mappings pickle as dicts
    state: dict = {"dir": None, "calls": []}
    map_estimate, run_pipeline, run_room = sampler.map_estimate, pipeline.run_pipeline, cmd_eval._run_room

    def recording_map_estimate(*args, **kwargs):
        state["calls"].append((args, kwargs))
        return map_estimate(*args, **kwargs)

    def capturing_run_pipeline(*args, **kwargs):
        state["calls"] = []
        res = run_pipeline(*args, **kwargs)
        rect = res.extra.get("rectification")
        call = state["calls"][-1] if state["calls"] else (None, None)
        cap = {"args": call[0], "kwargs": call[1], "heading": rect.heading if rect is not None else 0.0,
               "scene": res.scene}
        out = Path(state["dir"])
        out.mkdir(parents=True, exist_ok=True)
        tmp = out / "capture.pkl.part"
        with open(tmp, "wb") as f:
            pickle.dump(cap, f)
        os.replace(tmp, out / "capture.pkl")
        return res

    def capturing_run_room(room, out, opts, force):
        state["dir"] = Path(out) / Path(room).name
        return run_room(room, out, opts, force)

    # the rooms run in forked workers, which inherit these patches
    sampler.map_estimate, pipeline.run_pipeline, cmd_eval._run_room = (
        recording_map_estimate, capturing_run_pipeline, capturing_run_room)
    return main(["eval"] + argv)


def to_world(scene, final, heading: float):
    """``scene`` (the sampler's, in the wall-aligned frame) in the input's world frame, on the pipeline's final
    scene ``final``: :func:`apps.pipeline.turned_to_input`, as the pipeline turns it (the boxes stay in the
    rectified frame: scoring does not read them)."""
    from apps.pipeline import turned_to_input

    objs, floor = turned_to_input(scene.objects, scene.floor, heading)
    return replace(final, floor=floor, ceiling_z=scene.ceiling_z, camera_height=scene.camera_height,
                   objects=tuple(objs), scale=scene.scale)


def _literal(text: str):
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError):
        return text


def replay(data: list[Path], runs: list[Path], overrides: dict, seeds: list[int | None], hook: dict,
           initial: bool = False) -> tuple[list, list]:
    """Replay every capture of ``runs`` (room folders of the matching ``data`` sets); returns the room scores and
    the per-object rows ``(run/room, seed, class, position m, orientation deg or None)``."""
    import layout.sampler as sampler
    from apps.evaluation import score_room

    scores, rows = [], []
    for data_dir, run in zip(data, runs):
        for cap_path in sorted(run.glob("*/capture.pkl")):
            name = cap_path.parent.name
            cap = pickle.loads(cap_path.read_bytes())
            if cap["args"] is None:  # no sampler call (the pipeline failed before it)
                continue
            gt = json.loads((data_dir / name / "gt.json").read_text())
            for seed in seeds:
                args, kwargs = cap["args"], dict(cap["kwargs"])
                kwargs["config"] = replace(kwargs["config"], **overrides)
                if seed is not None:
                    kwargs["rng"] = seed
                if "before" in hook:
                    args, kwargs = hook["before"](args, kwargs, name)
                try:
                    post = sampler.map_estimate(*args, **kwargs)
                except sampler.PosteriorError as exc:
                    print(f"{run.name}/{name} seed {seed}: the sampler failed: {exc}", file=sys.stderr)
                    continue
                world = to_world(post.initial if initial else post.scene, cap["scene"], cap["heading"])
                s = score_room(f"{run.name}/{name}", world.to_json_dict(), gt)
                scores.append(s)
                for cls, e in s.objects.items():
                    orient = e["orient"] if len(e["orient"]) == len(e["pos"]) else [None] * len(e["pos"])
                    rows += [(s.name, seed, cls, float(p), None if o is None else float(o))
                             for p, o in zip(e["pos"], orient)]
    return scores, rows


def summary_line(scores: list, rows: list) -> str:
    parts = []
    for cls in CLASSES:
        pos = [r[3] for r in rows if r[2] == cls]
        ori = [r[4] for r in rows if r[2] == cls and r[4] is not None]
        p = f"{100 * np.mean(pos):.1f} cm" if pos else "n/a"
        o = f"{np.mean(ori):.2f} deg" if ori else "n/a"
        parts.append(f"{cls} {p} / {o} ({len(pos)})")
    if scores:
        parts.append(f"wall height {100 * np.mean([s.layout['wall_height_err'] for s in scores]):.2f} cm")
        parts.append(f"3D IoU {np.mean([s.layout['iou_3d'] for s in scores]):.3f}")
    return " | ".join(parts)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["capture"]:
        return capture(argv[1:])
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("capture", help="pano2cad eval, capturing the sampler's inputs (its options follow)")
    rp = sub.add_parser("replay", help="the sampler alone on captures, scored")
    rp.add_argument("data", help="synthetic set(s), comma-separated")
    rp.add_argument("runs", help="capture folder(s), comma-separated, one per set")
    rp.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE", help="SamplerConfig overrides")
    rp.add_argument("--seeds", default="", help="sampler seeds, comma-separated (default: the captured one)")
    rp.add_argument("--hook", help="Python file run first (may patch layout.sampler, may define before())")
    rp.add_argument("--init", action="store_true", help="score the initial hypothesis")
    rp.add_argument("--json", help="write the per-object rows here")
    a = ap.parse_args(argv)
    data, runs = [Path(p) for p in a.data.split(",")], [Path(p) for p in a.runs.split(",")]
    if len(data) != len(runs):
        ap.error(f"expected as many capture folders as sets, got {len(runs)} and {len(data)}")
    overrides = {}
    for item in a.set:
        name, sep, value = item.partition("=")
        if not sep:
            ap.error(f"--set: expected NAME=VALUE, got {item!r}")
        overrides[name] = _literal(value)
    hook: dict = {}
    if a.hook:
        exec(compile(Path(a.hook).read_text(), a.hook, "exec"), hook)
    seeds = [int(s) for s in a.seeds.split(",")] if a.seeds else [None]
    t0 = time.perf_counter()
    scores, rows = replay(data, runs, overrides, seeds, hook, initial=a.init)
    print(f"# {len(scores)} room runs in {time.perf_counter() - t0:.0f} s; overrides {overrides}; hook {a.hook}")
    print(summary_line(scores, rows))
    if a.json:
        Path(a.json).write_text(json.dumps(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
