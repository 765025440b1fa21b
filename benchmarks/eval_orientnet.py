"""The orientation network (posecrf.orientnet) on its own: held-out rooms, and against E_o on gt-box crops.

Run::

    pano2cad synth --rooms 1600 --seed 3000 --size 1024 --out out/train3000
    .venv/bin/python benchmarks/eval_orientnet.py held-out out/train3000 --first 1440 --last 1600 WEIGHTS.pt [...]

(rooms 1440-1599 of train3000 are the held-out rooms of the committed weights, which were trained on
``out/train5000`` and rooms 0-1439 of ``out/train3000``: :mod:`posecrf.train_orientation`)
    pano2cad synth --rooms 30 --seed 7000 --size 1024 --out out/tune7000
    .venv/bin/python benchmarks/eval_orientnet.py vs-hog out/tune7000 WEIGHTS.pt --weights 0 0.05 0.1 0.2 0.5

``held-out``: every object of rooms ``[first, last)`` of a synthetic set (the crops and labels of
:func:`posecrf.train_orientation.crops_from_rooms`, exact gt boxes), scored per class for each weights file, on
the crops alone and averaged with their mirrors (:func:`posecrf.orientnet.mirror_average`, what the pipeline uses):
the share whose most likely bin is within 45 deg of the truth (:func:`posecrf.train_orientation.score`).

``views``: the builtin detector's detections of the classes with a head in every room of a synthetic set, each
matched to the gt object of its class whose box it overlaps most (IoU >= 0.3): the network's most likely world yaw
(on a 5-degree grid) from the pose crop alone (:func:`apps.pipeline.object_crop`) and from the crops of every tile
that sees the object whole, their costs added on the world yaw (:func:`posecrf.orientnet.orientation_costs` with
``shifts``; ``pano2cad run --orientation net`` against ``net-tile``): per class, the objects more than 45 deg off
and the mean error. The network alone: the pipeline adds E_o, the model choice and the sampler.

    .venv/bin/python benchmarks/eval_orientnet.py views out/tune7000

``vs-hog``: every object with at least 300 visible pixels of a class with a network head, cropped at its gt box
(:func:`posecrf.crops.extract_crop`), through the pose CRF (:func:`posecrf.pose.estimate_poses`, per room and
class as the pipeline does). For each weight ``w``, the yaw of least ``E_o + w * cost`` over the pose grid (E_o
of the object's TRUE model at its best pitch; cost :func:`posecrf.orientnet.orientation_costs`): the share of
objects more than 45 deg off, per class; also the CRF's own yaw, and the median spread (max - min over the yaws)
of E_o and of the network's cost, which sets the scale of ``w``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from panogeom.rotation import angle_difference


def _err_deg(a, b) -> np.ndarray:
    return np.degrees(angle_difference(a, b))


def held_out(rooms_dir: str, first: int, last: int, weights: list[str]) -> None:
    from posecrf.orientnet import head_probabilities, load_orientation_net
    from posecrf.train_orientation import crops_from_rooms, score

    rooms = sorted(p for p in Path(rooms_dir).glob("room-*") if (p / "gt.json").is_file())[first:last]
    x, c, y = crops_from_rooms(rooms, 1, 0.0, 300, np.random.default_rng(0))
    print(f"{len(x)} crops of {len(rooms)} rooms ({rooms_dir}, rooms {first}-{first + len(rooms) - 1}); "
          "within 45 deg:\n")
    print("| weights | " + " | ".join(n for n in _classes()) + " |")
    print("|---|" + "---:|" * len(_classes()))
    for w, mirror in ((w, m) for w in weights for m in (False, True)):
        # mirror: the pipeline's test-time mirror (OrientationNet.probabilities)
        s = score(head_probabilities(load_orientation_net(w).module, x, c, mirror=mirror), y, c)
        print(f"| {w}{', mirror averaged' if mirror else ''} | "
              + " | ".join(f"{100 * s[n]['within_45_deg']:.0f} % ({s[n]['crops']})" if n in s else ""
                           for n in _classes()) + " |")


def _classes() -> tuple[str, ...]:
    from posecrf.orientnet import ORIENT_CLASSES

    return ORIENT_CLASSES


def vs_hog(rooms_dir: str, weights_file: str, ws: list[float]) -> None:
    from posecrf.cache import library_renders
    from posecrf.crops import extract_crop, relative_yaw
    from posecrf.library import builtin_library
    from posecrf.orientnet import load_orientation_net, orientation_costs
    from posecrf.pose import estimate_poses
    from posecrf.render import PoseGrid, RenderSettings
    from posecrf.train_orientation import read_rgb

    lib = builtin_library()
    grid = PoseGrid()
    renders = library_renders(lib, grid=grid, settings=RenderSettings())
    net = load_orientation_net(weights_file)
    rows = []  # (class, true yaw_rel, CRF yaw_rel, E_o over yaws, net cost over yaws)
    for room in sorted(Path(rooms_dir).glob("room-*")):
        gt = json.loads((room / "gt.json").read_text())
        pano = read_rgb(room / "pano.png")
        by_class: dict[str, list] = {}
        for o in gt["objects"]:
            if o["class"] not in net.classes or o["visible_px"] < 300:
                continue
            try:
                crop, view = extract_crop(pano, o["bbox_pano"])
            except ValueError:
                continue
            truth = float(relative_yaw(math.radians(o["yaw_deg"]), view.direction))
            by_class.setdefault(o["class"], []).append((crop, truth, o["model"]))
        for cls, items in by_class.items():
            crops = [i[0] for i in items]
            res = estimate_poses(renders, cls, crops)
            probs = net.probabilities(crops, [cls] * len(crops))
            for (_, truth, mid), est, p in zip(items, res.estimates, probs):
                table = est.e_o_models[est.model_ids.index(mid)] if mid in est.model_ids else est.e_o
                rows.append((cls, truth, est.yaw_rel, table.min(axis=1), orientation_costs(p, grid.yaws)))
    print(f"{len(rows)} objects of {rooms_dir}, weights {weights_file}")
    print(f"median spread over the yaws: E_o {np.median([r[3].max() - r[3].min() for r in rows]):.2f}, "
          f"network cost {np.median([r[4].max() - r[4].min() for r in rows]):.2f}\n")
    print("| class | objects | CRF yaw | " + " | ".join(f"E_o + {w} x net" for w in ws) + " |")
    print("|---|---:|---:|" + "---:|" * len(ws))
    for cls in net.classes:
        r = [x for x in rows if x[0] == cls]
        if not r:
            continue
        crf = np.mean([_err_deg(x[2], x[1]) > 45 for x in r if x[2] is not None])
        cells = [np.mean([_err_deg(grid.yaws[np.argmin(x[3] + w * x[4])], x[1]) > 45 for x in r]) for w in ws]
        print(f"| {cls} | {len(r)} | {100 * crf:.0f} % | " + " | ".join(f"{100 * c:.0f} %" for c in cells) + " |")


def views(rooms_dir: str) -> None:
    # the pipeline's own rectification and detection (apps.pipeline: the same code path as pano2cad run)
    from apps.pipeline import _detect, _rectify, object_crop, other_tile_crops
    from apps.progress import Progress
    from detect.nms import pano_box_iou
    from posecrf.crops import relative_yaw, relative_yaw_shifts
    from posecrf.orientnet import load_orientation_net, orientation_costs
    from posecrf.train_orientation import read_rgb

    net = load_orientation_net()
    quiet = Progress(quiet=True)
    world = np.radians(np.arange(72) * 5.0)
    rows = []  # (class, error of the pose crop alone, error of all the views, number of views)
    for room in sorted(Path(rooms_dir).glob("room-*")):
        gt = json.loads((room / "gt.json").read_text())
        heads = [o for o in gt["objects"] if o["class"] in net.classes and o.get("bbox_pano")
                 and o.get("symmetry", "none") == "none"]
        if not heads:
            continue
        pano = read_rgb(room / "pano.png")
        # the gt stays in its frame: the rectification of a synthetic room turns it by a few hundredths of a degree
        rect, upright = _rectify(pano, quiet, [])
        for d in _detect(pano, upright, rect, "builtin", quiet)[0]:
            same = [o for o in heads if o["class"] == d.label]
            if d.tile is None or not same:
                continue
            iou = pano_box_iou([d.box], [o["bbox_pano"] for o in same], *upright.shape[1::-1]).reshape(-1)
            if iou.max() < 0.3:
                continue
            truth = same[int(np.argmax(iou))]
            try:
                crop, view = object_crop(upright, d, "tile")
            except ValueError:
                continue
            crops, rays = map(list, zip(*([(crop, view.direction)] + other_tile_crops(upright, d))))
            p = net.probabilities(crops, [d.label] * len(crops))
            rel0 = relative_yaw(world, rays[0])
            one = world[np.argmin(orientation_costs(p[0], rel0))]
            every = world[np.argmin(orientation_costs(p, rel0, shifts=relative_yaw_shifts(rays)))]
            t = math.radians(truth["yaw_deg"])
            rows.append((d.label, float(_err_deg(one, t)), float(_err_deg(every, t)), len(crops)))
    print(f"{len(rows)} detections of {rooms_dir} (builtin detector), "
          f"{np.mean([r[3] for r in rows]):.2f} views per object on average\n")
    print("| class | objects | pose crop: > 45 deg off | mean error | all views: > 45 deg off | mean error |")
    print("|---|---:|---:|---:|---:|---:|")
    for cls in net.classes:
        r = np.array([x[1:3] for x in rows if x[0] == cls]).reshape(-1, 2)
        if len(r):
            print(f"| {cls} | {len(r)} | {int((r[:, 0] > 45).sum())} | {r[:, 0].mean():.1f} deg | "
                  f"{int((r[:, 1] > 45).sum())} | {r[:, 1].mean():.1f} deg |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    h = sub.add_parser("held-out")
    h.add_argument("rooms")
    h.add_argument("weights", nargs="+")
    h.add_argument("--first", type=int, default=0)
    h.add_argument("--last", type=int, default=None)
    v = sub.add_parser("vs-hog")
    v.add_argument("rooms")
    v.add_argument("weights_file")
    v.add_argument("--weights", type=float, nargs="+", default=[0.0, 0.1])
    w = sub.add_parser("views")
    w.add_argument("rooms")
    a = ap.parse_args()
    if a.cmd == "held-out":
        held_out(a.rooms, a.first, a.last if a.last is not None else 10**9, a.weights)
    elif a.cmd == "views":
        views(a.rooms)
    else:
        vs_hog(a.rooms, a.weights_file, a.weights)


if __name__ == "__main__":
    main()
