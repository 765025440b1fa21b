"""``pano2cad run IMAGE --out DIR``: the whole pipeline on one panorama, with all exports."""

from __future__ import annotations

import math
from pathlib import Path

from .errors import UserError
from .outdir import prepare_out_dir
from .progress import Progress


def check_options(args) -> None:
    """Usage errors before any work is done."""
    if args.camera_height is not None and not (0.3 <= args.camera_height <= 5.0):
        raise UserError(f"--camera-height: expected metres in [0.3, 5], got {args.camera_height}")
    if args.samples < 1:
        raise UserError(f"--samples: expected at least 1, got {args.samples}")
    if args.size < 256 or args.size % 2:
        raise UserError(f"--size: expected an even working width >= 256, got {args.size}")


def options_from_args(args):
    from .pipeline import RunOptions

    return RunOptions(camera_height=args.camera_height, detector=args.detector, samples=args.samples,
                      seed=args.seed, objects=not args.no_objects, sampler_mode=args.sampler,
                      model_choice=args.models, crop=args.crop,
                      orientation=args.orientation, box_edges=args.box_edges, ceiling=args.ceiling,
                      walls=args.walls, object_mask=args.object_mask)


def write_outputs(result, out: Path, image_name: str) -> dict[str, Path]:
    """Every output of a run, each atomically; scene.json after the exports, then report.html (built from them)."""
    from .atomic import write_json
    from .export import export_all
    from .report import write_report

    files = export_all(result.scene, out, image=result.image, labels=result.labels_input)
    doc = result.scene.to_json_dict()
    doc["image"] = {"file": image_name, "width": int(result.image.shape[1]), "height": int(result.image.shape[0])}
    doc["warnings"] = list(result.warnings)
    files["scene.json"] = write_json(out / "scene.json", doc)
    files["report.html"] = write_report(out)
    return files


def summary_line(scene, seconds: float) -> str:
    from layout.polygon import signed_area

    xy = scene.floor
    ext = xy.max(0) - xy.min(0)
    counts: dict[str, int] = {}
    for o in scene.objects:
        counts[o.cls] = counts.get(o.cls, 0) + 1
    objs = ", ".join(f"{n} {c}" for c, n in sorted(counts.items())) or "no objects"
    wall = scene.wall_height
    return (f"room {ext[0]:.2f} x {ext[1]:.2f} m ({abs(float(signed_area(xy))):.1f} m2, {len(xy)} corners), "
            f"wall height {wall:.2f} m, camera {scene.camera_height:.2f} m, {objs}, {seconds:.1f} s"
            if wall is not None and math.isfinite(wall) else f"room of {len(xy)} corners, {objs}, {seconds:.1f} s")


def run(args) -> int:
    from .imageio import read_panorama
    from .pipeline import run_pipeline

    check_options(args)
    prog = Progress(args.quiet)
    with prog.stage("read", "reading the panorama"):
        pano = read_panorama(args.image, max_width=args.size)
    out = prepare_out_dir(args.out)
    result = run_pipeline(pano.image, options_from_args(args), prog)
    with prog.stage("export", "writing scene.json, scene.glb/.obj, floor plan, overlay, labels"):
        files = write_outputs(result, out, Path(args.image).name)
    for w in result.warnings:
        prog.say(f"warning: {w}")
    prog.say(summary_line(result.scene, prog.total()))
    for name in sorted(files):
        print(files[name])
    return 0
