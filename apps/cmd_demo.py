"""``pano2cad demo``: the whole pipeline on an embedded generated panorama (what ``make demo`` runs).

The panorama is room 0 of the synthetic set with the given seed
(:mod:`apps.synth`), generated on the fly: deterministic, no download, and
with ground truth, so the demo ends by scoring itself.
"""

from __future__ import annotations

from .outdir import prepare_out_dir
from .progress import Progress


def run(args) -> int:
    from layout.metrics import score_layout

    from .atomic import write_image, write_json
    from .cmd_run import summary_line, write_outputs
    from .pipeline import RunOptions, run_pipeline
    from .synth import make_room

    if args.size < 256 or args.size % 2:
        from .errors import UserError

        raise UserError(f"--size: expected an even panorama width >= 256, got {args.size}")
    prog = Progress(args.quiet)
    out = prepare_out_dir(args.out)
    with prog.stage("generate", f"generating the demo room (seed {args.seed}, {args.size}x{args.size // 2})"):
        room = make_room(0, args.seed, args.size)
        inputs = out / "input"
        inputs.mkdir(exist_ok=True)
        write_image(inputs / "pano.png", room.rgb)
        write_json(inputs / "gt.json", room.gt)
    result = run_pipeline(room.rgb, RunOptions(seed=args.seed), prog)
    with prog.stage("export", "writing scene.json, scene.glb/.obj, floor plan, overlay, labels"):
        files = write_outputs(result, out, "input/pano.png")
    s, gt = result.scene, room.gt
    score = score_layout(s.floor, s.ceiling_z, gt["room"]["floor"], gt["room"]["ceiling_z"])
    for w in result.warnings:
        prog.say(f"warning: {w}")
    print(summary_line(s, prog.total()))
    print(f"against the ground truth: 3D IoU {score.iou_3d:.3f}, 2D IoU {score.iou_2d:.3f}, "
          f"wall height {s.wall_height:.2f} m (true {gt['room']['ceiling_z']:.2f} m), "
          f"camera {s.camera_height:.2f} m (true {gt['camera_height_m']:.2f} m)")
    print(f"files written to {out}:")
    for name in sorted(files):
        print(f"  {files[name]}")
    print(f"  {inputs / 'pano.png'}\n  {inputs / 'gt.json'}")
    return 0
