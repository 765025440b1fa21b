"""The whole pipeline from Python: a panorama in, a scene (room + objects) and all exports out.

Usage:
    python examples/full_pipeline.py [IMAGE] [--out out/examples/pipeline] [--detector builtin]

Without IMAGE, room 0 of the synthetic set with seed 1 is generated and used (with its gt.json,
so the result is scored at the end).
"""

from __future__ import annotations

import argparse
from pathlib import Path


def main() -> None:
    from apps.cmd_run import summary_line, write_outputs
    from apps.imageio import read_panorama
    from apps.pipeline import RunOptions, run_pipeline
    from apps.progress import Progress

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("image", nargs="?", help="equirectangular panorama (default: a generated room)")
    ap.add_argument("--out", default="out/examples/pipeline")
    ap.add_argument("--detector", default="builtin", help="builtin | tflite | onnx:FILE | annotations:FILE")
    ap.add_argument("--camera-height", type=float, default=None)
    ap.add_argument("--size", type=int, default=1024)
    args = ap.parse_args()

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    gt = None
    if args.image:
        image = read_panorama(args.image, max_width=args.size).image
        name = Path(args.image).name
    else:
        from apps.synth import make_room

        room = make_room(0, seed=1, width=args.size)
        image, gt, name = room.rgb, room.gt, "generated.png"

    options = RunOptions(camera_height=args.camera_height, detector=args.detector, samples=200, seed=0)
    result = run_pipeline(image, options, Progress())
    files = write_outputs(result, out, name)
    print(summary_line(result.scene, sum(v for k, v in result.scene.timing.items() if k != "total")))
    for w in result.warnings:
        print("warning:", w)
    if gt is not None:
        from layout.metrics import score_layout

        s = score_layout(result.scene.floor, result.scene.ceiling_z, gt["room"]["floor"], gt["room"]["ceiling_z"])
        print(f"3D IoU against the generated room's ground truth: {s.iou_3d:.3f}")
    for p in sorted(files.values()):
        print(p)


if __name__ == "__main__":
    main()
