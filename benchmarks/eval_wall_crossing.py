"""Where the object position error comes from: objects whose true footprint the estimated walls cut, and the
error along the camera ray.

Run::

    pano2cad eval --data out/tune7000 --out out/s10/run3_tune7000 --detector builtin --samples 3000
    .venv/bin/python benchmarks/eval_wall_crossing.py out/tune7000,out/tune8000 \\
        out/s10/run3_tune7000,out/s10/run3_tune8000 [--scene scene_init.json]

Every room's predicted scene is first brought to the true scale (object centres and floor polygon multiplied by
``true / estimated camera height``, as in ``benchmarks/eval_true_scale.py``), so what is left is not the shared
scale. The objects of each class are paired with the room's visible ground-truth objects by a Hungarian assignment
on floor distance (no distance gate). For each pair:

* ``cut``: more than ``--share`` (default 10 %) of the TRUE footprint lies outside the PREDICTED floor polygon by
  more than ``--margin`` (default 5 cm; :func:`layout.polygon.outside_fraction`). The sampler keeps every footprint
  inside the estimated room, so such an object cannot be placed where it is;
* ``radial``: the signed error along the camera-object ray (negative: placed nearer the camera than it is),
  ``tangential`` the unsigned error across it.

Printed per class: pairs, the share cut, mean / median error of cut and uncut pairs, the median signed radial and
unsigned tangential error, and (the ceiling of a perfect room step) the mean error if the cut pairs had the uncut
pairs' mean error.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from layout.polygon import oriented_rectangles, outside_fraction

sys.path.insert(0, str(Path(__file__).resolve().parent))
from eval_true_scale import scaled_rooms, sets_and_runs  # noqa: E402

CLASSES = ("bed", "chair", "tv", "plant")


def _footprint(o: dict) -> np.ndarray:
    return oriented_rectangles(np.array(o["center"][:2], dtype=np.float64), np.radians(float(o["yaw_deg"])),
                               np.array(o["size"][:2], dtype=np.float64))


def pairs(data: Path, run: Path, scene: str, margin: float) -> dict[str, list[tuple[float, float, float, float]]]:
    """Per class: (error, radial, tangential, outside share of the true footprint) per pair, metres."""
    out: dict[str, list[tuple[float, float, float, float]]] = {c: [] for c in CLASSES}
    for gt, sc, k in scaled_rooms(data, run, scene):
        floor = k * np.array(sc["room"]["floor"], dtype=np.float64)
        for c in CLASSES:
            g_objs = [o for o in gt["objects"] if o["class"] == c and o["bbox_pano"] is not None]
            p_objs = [o for o in sc["objects"] if o["class"] == c]
            if not g_objs or not p_objs:
                continue
            g = np.array([o["center"][:2] for o in g_objs], dtype=np.float64)
            p = k * np.array([o["center"][:2] for o in p_objs], dtype=np.float64)
            d = np.linalg.norm(g[:, None] - p[None], axis=-1)
            for i, j in zip(*linear_sum_assignment(d)):
                e = p[j] - g[i]
                u = g[i] / max(float(np.linalg.norm(g[i])), 1e-9)
                share = float(outside_fraction(_footprint(g_objs[i]), floor, margin=margin))
                out[c].append((float(d[i, j]), float(e @ u), float(abs(e @ np.array([-u[1], u[0]]))), share))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--margin", type=float, default=0.05, help="wall tolerance, metres")
    ap.add_argument("--share", type=float, default=0.1, help="outside share above which a footprint is cut")
    args, data, runs = sets_and_runs(ap, argv)
    pooled: dict[str, list[tuple[float, float, float, float]]] = {c: [] for c in CLASSES}
    for d, r in zip(data, runs):
        for c, v in pairs(d, r, args.scene, args.margin).items():
            pooled[c].extend(v)
    print(f"    .venv/bin/python benchmarks/eval_wall_crossing.py {args.data} {args.runs} --scene {args.scene}\n")
    print("At the true scale. cut: the estimated walls leave more than "
          f"{100 * args.share:.0f} % of the true footprint outside (margin {100 * args.margin:.0f} cm).\n")
    print("| class | pairs | cut | error cut: mean / median (cm) | error uncut: mean / median (cm) | "
          "radial, signed median (cm) | tangential median (cm) | mean error (cm) | mean, cut pairs at the uncut "
          "mean (cm) |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for c in CLASSES:
        a = np.array(pooled[c]).reshape(-1, 4)
        if not len(a):
            continue
        cut = a[:, 3] > args.share
        err = 100 * a[:, 0]

        def mm(x: np.ndarray) -> str:
            return f"{x.mean():.1f} / {np.median(x):.1f}" if x.size else "-"

        ideal = np.where(cut, err[~cut].mean() if (~cut).any() else np.nan, err).mean()
        print(f"| {c} | {len(a)} | {100 * cut.mean():.0f} % | {mm(err[cut])} | {mm(err[~cut])} | "
              f"{100 * np.median(a[:, 1]):+.1f} | {100 * np.median(a[:, 2]):.1f} | {err.mean():.1f} | {ideal:.1f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
