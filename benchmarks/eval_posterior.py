"""Unit-level accuracy of the MAP sampler (layout.sampler, issue 9) on synthetic rooms.

Run:  .venv/bin/python benchmarks/eval_posterior.py [--split test] [--rooms 30] [--samples 3000]
      [--write-docs] [--json out/eval_posterior.json]

Each room: :func:`layout.rooms.generate_room` (the paper's templates, wall
height N(2.7, 0.2) m, wall offsets), bedroom contents drawn with
:func:`layout.placement.sample_class_counts` (one bed, 1-3 chairs, one TV,
0-2 plants, 1-3 clutter objects) as random models of the built-in library
(:func:`posecrf.library.builtin_library`; their exact sizes are the "known
metric sizes of the retrieved models"), placed with
:func:`layout.placement.place_objects` (context-prior sampling, camera 1.3-1.8 m
high, 0.5 m from the walls).

Observation: the room and the objects' model meshes are ray cast into a
1024 x 512 label panorama (:func:`panogeom.raycast.raycast_equirect`, an
independent renderer) with the objects labelled 0 (clutter, what a surface
labeller says of furniture); the detection boxes are the ground-truth boxes
(extent of the projected 3D box, :func:`panogeom.project.world_box_to_pano`).

What the sampler gets: the room up to scale (the true floor polygon, ceiling
and camera height multiplied by ``1.6 / camera_height``: what the labels give
with the default camera height 1.6 m), for each object its class, box, exact
model size and a pose estimate = true yaw + N(0, 3 deg), and
``E_o(yaw) = 1 - cos(yaw - pose estimate)`` (none for plants). Scale and
distances are unknown.

Columns: "init" = the initial hypothesis (paper scheme: distance from the
box width and the model size, wall height 2.5 m; improved scheme: camera
height and positions fitted to all four box edges, see
:func:`layout.sampler.fit_boxes`); then each scheme after ``N_S`` samples.
Errors as in the paper: wall height |estimated - true|, position = distance
of the box centres on the floor plane, orientation = smallest angle between
the yaws (none for plants).

Seeds: ``--split tune`` (base 5000) was used while developing; ``--split
test`` (base 800000, the default) only for the figures written to the docs.
A first test split (base 700000) was spent: its run failed on two
initialisation bugs (a box across the seam, a distance from the width of an
object seen edge-on), which were then fixed; the figures come from the fresh
split.
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import json
import math
import os
import platform
import re
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from layout.likelihood import observe_labels, surface_likelihood  # noqa: E402
from layout.placement import ObjectSpec, place_objects, sample_class_counts  # noqa: E402
from layout.rooms import generate_room  # noqa: E402
from layout.sampler import DetectedObject, SamplerConfig, map_estimate  # noqa: E402
from panogeom.project import world_box_to_pano  # noqa: E402
from panogeom.raycast import RenderMesh, raycast_equirect, room_meshes  # noqa: E402

SPLITS = {"tune": 5000, "test": 800000}
CLASSES = ("bed", "chair", "tv", "plant")
H0 = 1.6  # the default camera height the room geometry is computed with
DOC = Path(__file__).resolve().parents[1] / "docs" / "EVALUATION.md"
SECTION = "## Posterior sampling (layout)"


def _library():
    from posecrf.library import builtin_library

    return builtin_library()


def object_mesh(model, center, yaw: float, label: int = 0) -> RenderMesh:
    """The library model placed with its box centre at ``center`` and turned by ``yaw``."""
    v = np.asarray(model.vertices, dtype=np.float64)
    lo, hi = v.min(axis=0), v.max(axis=0)
    v = v - 0.5 * (lo + hi)
    c, s = math.cos(yaw), math.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return RenderMesh(v @ R.T + np.asarray(center), np.asarray(model.faces), labels=label)


def box_mesh(center, size, yaw: float, label: int = 0) -> RenderMesh:
    from panogeom.project import world_box_corners

    v = world_box_corners(center, size, yaw)
    f = [[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6], [0, 4, 5], [0, 5, 1], [1, 5, 6], [1, 6, 2], [2, 6, 7],
         [2, 7, 3], [3, 7, 4], [3, 4, 0]]
    return RenderMesh(v, np.array(f), labels=label)


def make_room(seed: int, lib, *, width: int, observed: str):
    """One synthetic room: ground truth, label panorama, boxes and the sampler's inputs."""
    rng = np.random.default_rng(seed)
    room = generate_room(rng)
    counts = sample_class_counts(rng)
    specs, models = [], []
    for name, k in counts.items():
        pool = lib.by_class(name)
        for i in range(k):
            m = pool[int(rng.integers(len(pool)))]
            specs.append(ObjectSpec(name, tuple(float(v) for v in m.size), m.id, symmetric=(name == "plant")))
            models.append(m)
    pl = place_objects(room, specs, rng).centered_on_camera()
    by_id = {m.id: m for m in models}
    cam_h = pl.camera_height
    meshes = [room_meshes(pl.room.floor, pl.room.ceiling_z)]
    for o in pl.objects:
        if observed == "mesh":
            meshes.append(object_mesh(by_id[o.model_id], o.center, o.yaw))
        else:
            meshes.append(box_mesh(o.center, o.size, o.yaw))
    labels = raycast_equirect(meshes, width, [0.0, 0.0, cam_h]).labels
    h = width // 2
    dets, eo_terms = [], []
    for j, o in enumerate(pl.objects):
        box = world_box_to_pano(o.center, o.size, o.yaw, width, h, camera_height=cam_h).extent
        sym = o.symmetric
        yaw_est = o.yaw + (0.0 if sym else math.radians(3.0) * rng.normal())
        dets.append(DetectedObject(o.class_name, box, o.size, yaw_est, model_id=o.model_id, id=f"{o.class_name}-{j}",
                                   symmetric=sym))
        eo_terms.append(None if sym else (lambda y, m=yaw_est: 1.0 - np.cos(y - m)))
    f = H0 / cam_h
    return {"placement": pl, "labels": labels, "detections": dets, "eo": eo_terms,
            "floor0": pl.room.floor * f, "ceiling0": pl.room.ceiling_z * f, "seed": seed}


def _yaw_error(a: float, b: float) -> float:
    return abs(math.degrees(math.atan2(math.sin(a - b), math.cos(a - b))))


def score(scene, pl) -> dict:
    """Errors of a scene against the placement (ground truth): wall height (cm), per object pos (cm), yaw (deg)."""
    out = {"wall_cm": abs(scene.wall_height - pl.room.ceiling_z) * 100.0, "objects": []}
    for o, g in zip(scene.objects, pl.objects):
        pos = float(np.hypot(*(np.asarray(o.center[:2]) - np.asarray(g.center[:2])))) * 100.0
        yaw = None if g.symmetric else _yaw_error(o.yaw, g.yaw)
        out["objects"].append({"cls": g.class_name, "pos_cm": pos, "yaw_deg": yaw})
    return out


def run(args) -> dict:
    lib = _library()
    base = SPLITS[args.split]
    schemes = {
        "paper": (SamplerConfig(n_samples=args.samples), "masked"),
        "improved_search": (SamplerConfig.improved(n_samples=args.samples, surface_weight=1.0, keep_in_box=False),
                            "masked"),
        "improved": (SamplerConfig.improved(n_samples=args.samples, surface_weight=args.surface_weight),
                     args.improved_pixels),
    }
    if args.schemes:
        schemes = {k: v for k, v in schemes.items() if k in args.schemes}
    results: dict[str, list] = {"init_paper": [], "init_improved": []}
    results.update({k: [] for k in schemes})
    times: dict[str, list] = {k: [] for k in schemes}
    for r in range(args.rooms):
        data = make_room(base + r, lib, width=args.render_width, observed=args.observed)
        pl = data["placement"]
        for name, (cfg, pixels) in schemes.items():
            obs = observe_labels(data["labels"], [d.bbox_pano for d in data["detections"]], width=args.width,
                                 object_pixels=pixels)
            lik = surface_likelihood(obs, data["floor0"], data["ceiling0"], H0)
            c0 = time.process_time()
            res = map_estimate(lik, data["detections"], image_width=args.render_width,
                               image_height=args.render_width // 2, orientation=data["eo"], config=cfg,
                               rng=base + r)
            times[name].append(time.process_time() - c0)
            results[name].append(score(res.scene, pl))
            init_key = "init_paper" if name == "paper" else "init_improved"  # both improved runs start alike
            if name != "improved_search" or "improved" not in schemes:
                results[init_key].append(score(res.initial, pl))
        if not args.quiet:
            msg = " ".join(f"{k} {results[k][-1]['wall_cm']:5.1f}cm/"
                           f"{np.mean([o['pos_cm'] for o in results[k][-1]['objects']]):5.1f}cm"
                           for k in results if results[k])
            print(f"room {r:2d} ({pl.room.template}, {len(pl.objects)} obj): {msg}", file=sys.stderr, flush=True)
    return {"results": results, "cpu_s": times, "args": vars(args)}


def summarise(out: dict) -> dict:
    summary = {}
    for name, rows in out["results"].items():
        if not rows:
            continue
        wall = np.array([r["wall_cm"] for r in rows])
        objs = [o for r in rows for o in r["objects"]]
        per = {}
        for cls in CLASSES + ("other",):
            sel = [o for o in objs if (o["cls"] == cls if cls != "other" else o["cls"] not in CLASSES)]
            pos = np.array([o["pos_cm"] for o in sel])
            yaw = np.array([o["yaw_deg"] for o in sel if o["yaw_deg"] is not None])
            per[cls] = {"n": len(sel), "pos": (float(pos.mean()), float(pos.std())) if len(pos) else None,
                        "yaw": (float(yaw.mean()), float(yaw.std())) if len(yaw) else None}
        allpos = np.array([o["pos_cm"] for o in objs])
        room_mean = np.array([np.mean([o["pos_cm"] for o in r["objects"]]) for r in rows if r["objects"]])
        summary[name] = {"wall": (float(wall.mean()), float(wall.std())), "per_class": per,
                         "outliers_50cm": int(np.count_nonzero(allpos > 50.0)),
                         "pos_all": (float(allpos.mean()), float(allpos.std())),
                         "pos_median": float(np.median(allpos)),
                         "rooms_wall_within_5cm": int(np.count_nonzero(wall <= 5.0)),
                         "rooms_pos_within_10cm": int(np.count_nonzero(room_mean <= 10.0)), "rooms": len(rows)}
    return summary


def _pm(v) -> str:
    return "-" if v is None else f"{v[0]:.1f} ± {v[1]:.1f}"


def markdown(out: dict, summary: dict) -> str:
    a = out["args"]
    names = [k for k in ("init_paper", "paper", "init_improved", "improved_search", "improved") if k in summary]
    label = {"init_paper": "init (paper: wall 2.5 m)", "paper": f"paper, N_S = {a['samples']}",
             "init_improved": "init (scale fitted to the boxes)",
             "improved_search": "improved search, paper energy",
             "improved": f"improved, N_S = {a['samples']}"}
    lines = [SECTION, "",
             f"`.venv/bin/python benchmarks/eval_posterior.py --split {a['split']} --rooms {a['rooms']} "
             f"--samples {a['samples']} --write-docs` (this section is written by the script). "
             f"{a['rooms']} synthetic rooms (`layout.rooms` + `layout.placement`, built-in library models), "
             f"observed labels ray cast at {a['render_width']} x {a['render_width'] // 2} with the objects' "
             f"{'model meshes' if a['observed'] == 'mesh' else 'boxes'} as clutter (label 0), ground-truth boxes, "
             f"room known up to scale (camera height assumed 1.6 m), exact model sizes, pose = truth + N(0, 3 deg), "
             f"E_o = 1 - cos(yaw - pose). Working resolution {a['width']} x {a['width'] // 2}. "
             "Mean ± std over rooms (wall height) or objects (position, orientation); seeds of the "
             f"`{a['split']}` split, not used while developing (a first test split was spent on finding two "
             "initialisation bugs, see the script's docstring). \"improved search, paper energy\": the improved "
             "scheme's initialisation and moves with the paper's energy (w_s = 1, boxes masked, no box constraint) - "
             "what the better search alone does.", "",
             "| | " + " | ".join(label[k] for k in names) + " |",
             "|---|" + "---:|" * len(names)]
    lines.append("| wall height error (cm) | " + " | ".join(_pm(summary[k]["wall"]) for k in names) + " |")
    lines.append("| rooms with wall height within 5 cm | "
                 + " | ".join(f"{summary[k]['rooms_wall_within_5cm']} / {summary[k]['rooms']}" for k in names) + " |")
    lines.append("| position error, all objects (cm) | " + " | ".join(_pm(summary[k]["pos_all"]) for k in names)
                 + " |")
    lines.append("| position error, median (cm) | " + " | ".join(f"{summary[k]['pos_median']:.1f}" for k in names)
                 + " |")
    lines.append("| rooms with mean position error within 10 cm | "
                 + " | ".join(f"{summary[k]['rooms_pos_within_10cm']} / {summary[k]['rooms']}" for k in names)
                 + " |")
    for cls in CLASSES + ("other",):
        n = summary[names[0]]["per_class"][cls]["n"]
        lines.append(f"| {cls} position (cm), n = {n} | "
                     + " | ".join(_pm(summary[k]["per_class"][cls]["pos"]) for k in names) + " |")
    for cls in CLASSES + ("other",):
        if cls == "plant":
            continue
        lines.append(f"| {cls} orientation (deg) | "
                     + " | ".join(_pm(summary[k]["per_class"][cls]["yaw"]) for k in names) + " |")
    lines.append("| objects off by more than 50 cm | "
                 + " | ".join(str(summary[k]["outliers_50cm"]) for k in names) + " |")
    lines.append("")
    for k in ("paper", "improved_search", "improved"):
        if k in summary:
            wall, pos = summary[k]["wall"][0], summary[k]["pos_all"][0]
            met = "met" if wall <= 5.0 and pos <= 10.0 else "missed"
            lines.append(f"- Acceptance (mean wall-height error <= 5 cm and mean position error <= 10 cm), "
                         f"{label[k]}: {wall:.1f} cm and {pos:.1f} cm, {met}.")
    if "init_improved" in summary and "improved" in summary:
        i_pos, s_pos = summary["init_improved"]["pos_all"][0], summary["improved"]["pos_all"][0]
        i_med, s_med = summary["init_improved"]["pos_median"], summary["improved"]["pos_median"]
        better = "more" if i_pos < s_pos else "less"
        lines.append(f"- With ground-truth boxes and exact model sizes the improved initialisation (each object "
                     f"fitted to all four box edges at the fitted camera height) is {better} accurate in position "
                     f"than the sampled result (mean {i_pos:.1f} vs {s_pos:.1f} cm, median {i_med:.1f} vs "
                     f"{s_med:.1f} cm): the context prior moves objects towards walls and into alignment, which "
                     "fixes the orientations, and drags objects with little image evidence (partly hidden) "
                     "away (the outlier row).")
    cpu = out["cpu_s"]
    lines += ["", "CPU seconds per room (one process, 2-core machine shared with other jobs): "
              + ", ".join(f"{k} {np.mean(v):.2f} (max {np.max(v):.2f})" for k, v in cpu.items() if v) + ".",
              f"Environment: python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} CPUs."]
    return "\n".join(lines) + "\n"


def write_section(text: str, path: Path = DOC) -> None:
    """Replace this script's section of docs/EVALUATION.md (benchmarks/_docs.py)."""
    replace_section(path, text, "## Posterior sampling (layout)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--split", choices=sorted(SPLITS), default="test")
    ap.add_argument("--rooms", type=int, default=30)
    ap.add_argument("--samples", type=int, default=3000, help="N_S per room and scheme")
    ap.add_argument("--width", type=int, default=512, help="working width of E_s")
    ap.add_argument("--render-width", type=int, default=1024)
    ap.add_argument("--observed", choices=("mesh", "box"), default="mesh")
    ap.add_argument("--improved-pixels", choices=("masked", "matched"), default="matched")
    ap.add_argument("--surface-weight", type=float, default=SamplerConfig.improved().surface_weight)
    ap.add_argument("--schemes", nargs="*", choices=("paper", "improved_search", "improved"))
    ap.add_argument("--write-docs", action="store_true")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--quiet", action="store_true")
    args = ap.parse_args(argv)
    out = run(args)
    summary = summarise(out)
    text = markdown(out, summary)
    print(text)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"summary": summary, **out}, indent=1, default=str))
    if args.write_docs:
        write_section(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
