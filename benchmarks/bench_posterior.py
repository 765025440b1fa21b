"""Time E_s (layout.likelihood) and the MAP sampler (layout.sampler).

Scene: a 10-wall room with 8 objects placed by layout.placement (the scene
of bench_context.py), its label panorama rendered analytically at 1024 x 512
with the objects as clutter, true detection boxes, ``object_pixels="matched"``.

Prints, at working widths 256 and 512:
* one hypothesis: E_s alone, and the whole posterior energy the sampler
  evaluates (E_s, E_o, context prior, hard constraints), median process CPU
  time of single calls;
* the peer: the same comparison on a label image ray cast per hypothesis
  (:func:`panogeom.raycast.raycast_equirect`, Open3D, room and box meshes),
  the way a renderer-based evaluation works (the paper: about 30 s per
  hypothesis), and the ratio;
* a batch of 3000 hypotheses evaluated at once, per hypothesis, and the
  speed-up over one-by-one calls;
* whole MAP runs with N_S = 3000 (paper and improved schemes).

Run: ``.venv/bin/python benchmarks/bench_posterior.py [--repeats 200] [--write-docs]``
"""

from __future__ import annotations

import argparse
import os
import platform
import re
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from layout.likelihood import observe_labels, render_scene_labels, surface_likelihood  # noqa: E402
from layout.placement import ObjectSpec, place_objects  # noqa: E402
from layout.polygon import validate_floor_polygon  # noqa: E402
from layout.rooms import Room  # noqa: E402
from layout.sampler import DetectedObject, SamplerConfig, _Problem, _unique_ids, map_estimate  # noqa: E402
from layout.likelihood import orientation_likelihood  # noqa: E402
from panogeom.project import world_box_corners, world_box_to_pano  # noqa: E402
from panogeom.raycast import RenderMesh, raycast_equirect, room_meshes  # noqa: E402

BOX_FACES = np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6], [0, 4, 5], [0, 5, 1], [1, 5, 6], [1, 6, 2],
                      [2, 6, 7], [2, 7, 3], [3, 7, 4], [3, 4, 0]])

FLOOR = np.array(
    [[0, 0], [6.2, 0], [6.2, 2.4], [4.0, 2.4], [4.0, 5.1], [2.3, 5.1], [2.3, 4.5], [1.1, 4.5], [1.1, 5.1], [0, 5.1]],
    float,
)
SPECS = [
    ObjectSpec("bed", (2.05, 1.6, 0.55), "bed"),
    ObjectSpec("wardrobe", (0.6, 1.5, 2.0), "wardrobe"),
    ObjectSpec("sofa", (0.9, 2.0, 0.85), "sofa"),
    ObjectSpec("tv", (0.25, 1.1, 0.7), "tv"),
    ObjectSpec("nightstand", (0.4, 0.45, 0.55), "nightstand"),
    ObjectSpec("chair", (0.5, 0.5, 0.9), "chair-0"),
    ObjectSpec("chair", (0.5, 0.5, 0.9), "chair-1"),
    ObjectSpec("plant", (0.4, 0.4, 0.9), "plant", symmetric=True),
]
DOC = Path(__file__).resolve().parents[1] / "docs" / "BENCHMARKS.md"
SECTION = "## Posterior: E_s and the MAP sampler (layout)"


def cpu_median(fn, repeats: int) -> float:
    """Median process CPU seconds of ``fn()`` (fairer than wall time on a shared machine)."""
    out = []
    for _ in range(repeats):
        c0 = time.process_time()
        fn()
        out.append(time.process_time() - c0)
    return float(np.median(out))


def setup(seed: int):
    floor = validate_floor_polygon(FLOOR)
    room = Room(floor, 2.7, "bench", floor, np.zeros(len(floor)), np.zeros(len(floor), bool))
    pl = place_objects(room, SPECS, seed).centered_on_camera()
    assert len(pl.objects) == 8, pl.dropped
    cam = pl.camera_height
    c, s, y = pl.centers, np.array([o.size for o in pl.objects]), pl.yaws
    labels = render_scene_labels(pl.room.floor, pl.room.ceiling_z, cam, c, s, y, width=1024, object_label=0)
    boxes = np.array([world_box_to_pano(o.center, o.size, o.yaw, 1024, 512, camera_height=cam).extent
                      for o in pl.objects])
    dets = [DetectedObject(o.class_name, b, o.size, o.yaw, symmetric=o.symmetric) for o, b in zip(pl.objects, boxes)]
    f = 1.6 / cam
    return pl, labels, boxes, dets, pl.room.floor * f, pl.room.ceiling_z * f


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--batch", type=int, default=3000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--write-docs", action="store_true")
    args = ap.parse_args(argv)

    pl, labels, boxes, dets, floor0, ceil0 = setup(args.seed)
    rng = np.random.default_rng(args.seed)
    n = len(dets)
    lam = pl.camera_height / 1.6
    c_true = pl.centers
    sizes = np.array([o.size for o in pl.objects])
    c_b = c_true[None] + rng.normal(0, 0.1, (args.batch, n, 3)) * [1, 1, 0]
    y_b = pl.yaws[None] + rng.normal(0, 0.1, (args.batch, n))
    lam_b = lam * rng.uniform(0.9, 1.1, args.batch)
    rows = []
    for width in (256, 512):
        obs = observe_labels(labels, boxes, width=width, object_pixels="matched")
        es = surface_likelihood(obs, floor0, ceil0, 1.6)
        objs = _unique_ids(dets)
        prob = _Problem(es, objs, orientation_likelihood(None, [o.cls for o in objs]),
                        SamplerConfig.improved(), 1024, 512)
        k = [0]

        def one_es() -> None:
            i = k[0] % args.batch
            k[0] += 1
            es(c_b[i], sizes, y_b[i], lam_b[i])

        def one_posterior() -> None:
            i = k[0] % args.batch
            k[0] += 1
            prob.evaluate(lam_b[i:i + 1], c_b[i:i + 1, :, :2], y_b[i:i + 1])

        clutter = (obs.labels == 0) | (obs.labels == 5)

        def one_raster() -> None:  # the peer: ray cast the hypothesis (Open3D), compare pixels
            i = k[0] % args.batch
            k[0] += 1
            meshes = [room_meshes(floor0 * lam_b[i], ceil0 * lam_b[i])]
            meshes += [RenderMesh(world_box_corners(c, sz, yw), BOX_FACES, labels=5)
                       for c, sz, yw in zip(c_b[i], sizes, y_b[i])]
            lab = raycast_equirect(meshes, width, [0.0, 0.0, 1.6 * lam_b[i]]).labels
            cover = lab == 5
            np.count_nonzero(obs.valid & ~cover & (obs.labels == lab)) + np.count_nonzero(clutter & cover)

        t_es = cpu_median(one_es, args.repeats)
        t_post = cpu_median(one_posterior, args.repeats)
        t_raster = cpu_median(one_raster, max(args.repeats // 4, 5))
        t_batch = cpu_median(lambda: es(c_b, sizes, y_b, lam_b), 3) / args.batch
        t_batch_post = cpu_median(lambda: prob.evaluate(lam_b, c_b[..., :2], y_b), 3) / args.batch
        rows.append((width, t_es, t_post, t_raster, t_batch, t_batch_post))
    # whole MAP runs
    runs = []
    for name, cfg, pixels in (("paper", SamplerConfig(n_samples=3000), "masked"),
                              ("improved", SamplerConfig.improved(n_samples=3000), "matched")):
        for width in (256, 512):
            obs = observe_labels(labels, boxes, width=width, object_pixels=pixels)
            es = surface_likelihood(obs, floor0, ceil0, 1.6)
            res = [None]

            def run() -> None:
                res[0] = map_estimate(es, dets, image_width=1024, image_height=512, config=cfg, rng=args.seed)

            t = cpu_median(run, 3)
            w0 = time.perf_counter()
            run()
            wall = time.perf_counter() - w0
            runs.append((name, width, t, wall, res[0].n_samples))

    lines = [SECTION, "",
             "`.venv/bin/python benchmarks/bench_posterior.py --write-docs` (this section is written by the script). "
             "A 10-wall room with 8 objects (the scene of the context-prior benchmark), labels rendered at 1024 x 512 "
             "with the objects as clutter, true boxes, `object_pixels=\"matched\"`. Hypotheses: the true scene with "
             "positions moved by N(0, 10 cm), yaws by N(0, 0.1 rad), scale by U[0.9, 1.1]. Process CPU time, medians "
             f"({args.repeats} single calls, 3 batches of {args.batch}). Peer: the same comparison on a label image "
             "ray cast per hypothesis (`panogeom.raycast.raycast_equirect`, Open3D, room and box meshes); the paper "
             "reports about 30 s per hypothesis evaluation.", "",
             "| working resolution | E_s, one hypothesis (ms) | posterior energy, one hypothesis (ms) | "
             "ray-casting peer (ms) | peer / E_s | E_s per hypothesis in a batch of 3000 (us) | one-by-one / batch | "
             "posterior per hypothesis in a batch (us) |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for width, t_es, t_post, t_raster, t_batch, t_batch_post in rows:
        lines.append(f"| {width} x {width // 2} | {t_es * 1e3:.2f} | {t_post * 1e3:.2f} | {t_raster * 1e3:.1f} | "
                     f"{t_raster / t_es:.1f} | {t_batch * 1e6:.0f} | {t_es / t_batch:.1f} | {t_batch_post * 1e6:.0f} |")
    lines += ["", "| MAP run, N_S = 3000 | working resolution | CPU s | wall s | hypotheses evaluated |",
              "|---|---|---:|---:|---:|"]
    for name, width, t, wall, ns in runs:
        lines.append(f"| {name} | {width} x {width // 2} | {t:.2f} | {wall:.2f} | {ns} |")
    lines += ["", f"Environment: python {platform.python_version()}, numpy {np.__version__}, {os.cpu_count()} CPUs, "
              f"{platform.machine()}; load average {os.getloadavg()[0]:.1f} at the end of the run."]
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write_docs:
        doc = DOC.read_text() if DOC.exists() else "# Benchmarks\n"
        pat = re.compile(r"^## Posterior: E_s and the MAP sampler \(layout\)\n.*?(?=^## |\Z)", re.S | re.M)
        doc = pat.sub(lambda _: text + "\n", doc) if pat.search(doc) else doc.rstrip("\n") + "\n\n" + text
        tmp = DOC.with_suffix(".md.tmp")
        tmp.write_text(doc)
        os.replace(tmp, DOC)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
