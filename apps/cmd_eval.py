"""``pano2cad eval --data DIR``: run (or score) every room with a gt.json and print the paper's Table 2.

Rooms are the sub-folders of DIR holding ``gt.json`` (a synthetic set of
``pano2cad synth`` or ../shared/data/real). With ``--pred DIR`` existing
predictions (``DIR/<room>/scene.json``) are scored; otherwise the pipeline
runs on each room into ``--out/<room>/`` (rooms whose scene.json is already
there are reused unless ``--force``). Ground truth with ``scale_known:
false`` (real panoramas in units of the camera height) is run with that
camera height, so the layout can be compared.
"""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import os
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from .errors import UserError
from .outdir import prepare_out_dir
from .progress import Progress


#: ``--detector gt-boxes``: each room's own ground-truth boxes (separates detection from pose and sampling).
GT_BOXES = "gt-boxes"


def _rooms(data: Path) -> list[Path]:
    if not data.is_dir():
        raise UserError(f"{data}: --data must be a folder of rooms with gt.json")
    rooms = sorted(p for p in data.iterdir() if (p / "gt.json").is_file())
    if not rooms:
        raise UserError(f"{data}: no room folders with a gt.json inside")
    return rooms


def _run_room(room: str, out: str, opts: dict, force: bool) -> tuple[str, str | None]:
    """Run the pipeline on one room; returns (name, error or None). Writes out/<name>/."""
    from .atomic import write_json
    from .cmd_run import write_outputs
    from .evaluation import load_json
    from .imageio import read_panorama
    from .pipeline import RunOptions, run_pipeline
    from .progress import Progress

    room_p, out_p = Path(room), Path(out) / Path(room).name
    if not force and (out_p / "scene.json").is_file():
        return room_p.name, None
    gt = load_json(room_p / "gt.json") or {}
    o = dict(opts)
    gt_scale = bool(o.pop("gt_scale", False))
    if (gt_scale or gt.get("scale_known") is False) and o.get("camera_height") is None:
        if not isinstance(gt.get("camera_height_m"), (int, float)):
            return room_p.name, f"--gt-scale: {room_p / 'gt.json'} has no camera_height_m"
        o["camera_height"] = float(gt["camera_height_m"])
    if o.get("detector") == GT_BOXES:
        o["detector"] = f"annotations:{room_p / 'gt.json'}"
    try:
        img_name = gt.get("image", {}).get("file", "pano.png")
        pano = read_panorama(room_p / img_name, max_width=o.pop("size"))
        out_p.mkdir(parents=True, exist_ok=True)
        res = run_pipeline(pano.image, RunOptions(**o), Progress(quiet=True))
        write_outputs(res, out_p, img_name)
        post = res.extra.get("posterior")
        if post is not None:
            write_json(out_p / "scene_init.json", post.initial.to_json_dict())
        rect = res.extra.get("rectification")
        H, W = res.image.shape[:2]
        dets = []
        used = {id(d) for d in res.detections}
        # Every candidate down to the pipeline's CANDIDATE_SCORE, so that AP ranks the whole list; "used" marks
        # the ones above the backend's threshold that went on to the pose and posterior stages.
        for d in res.extra.get("candidates") or res.detections:  # in the input panorama's pixels, like gt.json
            j = d.to_json()
            if rect is not None:
                j["bbox_pano"] = [float(b) for b in rect.box_to_input(d.box, W, H)]
            j["used"] = id(d) in used
            dets.append(j)
        write_json(out_p / "detections.json", {"width": W, "height": H, "detections": dets})
        return room_p.name, None
    except Exception as exc:  # a failed room is recorded and scored zero, the evaluation goes on
        return room_p.name, f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}"


def _detection_ap(rooms: list) -> dict[str, float]:
    """Panorama-level AP@0.5 per class of the saved detections against gt.json (detect's evaluation)."""
    from detect.builtin.evaluate import evaluate, load_ground_truth
    from detect.detection import Detection

    truths, detections = [], {}
    for room, dets in rooms:
        W, H = int(dets["width"]), int(dets["height"])
        gt = load_ground_truth(room, width=W)
        truths.append(gt)
        detections[gt.name] = [Detection(d["class"], float(d["score"]), tuple(d["bbox_pano"]), W, H)
                               for d in dets["detections"]]
    res = evaluate(detections, truths, iou_threshold=0.5)
    return {c: float(r.ap) for c, r in res.classes.items()}


def run(args) -> int:
    from .atomic import write_json, write_text
    from .cmd_run import check_options, options_from_args
    from .evaluation import jsonable, load_json, markdown_table2, score_room, summarize

    if args.limit < 0:
        raise UserError(f"--limit: expected a number of rooms >= 0 (0: all), got {args.limit}")
    data = Path(args.data)
    rooms = _rooms(data)[: args.limit or None]
    prog = Progress(args.quiet)
    errors: dict[str, str] = {}
    if args.pred:
        pred = Path(args.pred)
        out = prepare_out_dir(args.out) if args.out else None
    else:
        check_options(args)
        if args.detector != GT_BOXES and args.detector.startswith("annotations:"):
            raise UserError("--detector annotations:FILE names one file; for each room's gt.json use --detector gt-boxes")
        out = pred = prepare_out_dir(args.out or "out/eval")
        o = options_from_args(args)
        opts = {**dataclasses.asdict(o), "size": args.size, "gt_scale": bool(getattr(args, "gt_scale", False))}
        if opts["gt_scale"] and o.camera_height is not None:
            raise UserError("--gt-scale and --camera-height both fix the scale: give one")
        jobs = max(1, min(args.jobs or os.cpu_count() or 1, len(rooms)))
        prog.say(f"eval: running the pipeline on {len(rooms)} rooms of {data} into {out} ({jobs} processes)")
        with prog.stage("run"):
            if jobs == 1:
                results = [_run_room(str(r), str(out), opts, args.force) for r in prog.bar(rooms, desc="rooms")]
            else:
                with ProcessPoolExecutor(jobs, mp_context=mp.get_context("fork")) as ex:
                    futs = [ex.submit(_run_room, str(r), str(out), opts, args.force) for r in rooms]
                    results = [f.result() for f in prog.bar(as_completed(futs), total=len(futs), desc="rooms")]
        errors = {name: err for name, err in results if err}
    scores, truths, detections = [], [], {}
    for r in rooms:
        gt = load_json(r / "gt.json")
        scene = load_json(pred / r.name / "scene.json")
        init = load_json(pred / r.name / "scene_init.json")
        scores.append(score_room(r.name, scene, gt, init, errors.get(r.name)))
        dets = load_json(pred / r.name / "detections.json")
        if (gt.get("objects") and isinstance(dets, dict) and args.detector != GT_BOXES
                and not getattr(args, "no_objects", False)):
            truths.append((r, dets))
    ap = _detection_ap(truths) if truths else None
    summary = summarize(scores, ap)
    table = markdown_table2(summary)
    print(table)
    for s in scores:
        if not s.ok:
            prog.say(f"failed: {s.name}: {s.error.splitlines()[0] if s.error else 'no scene.json'}")
    if out is not None:
        write_json(out / "eval.json", jsonable({"summary": summary, "rooms": [s.__dict__ for s in scores]}))
        write_text(out / "table2.md", table)
        prog.say(f"eval: wrote {out / 'eval.json'} and {out / 'table2.md'}")
    return 0
