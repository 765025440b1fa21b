"""Evaluation tables of ``pano2cad eval``: the paper's Table 2 plus layout and detection scores.

Composition of the metrics of :mod:`layout.metrics` (rooms) and
:mod:`layout.objectmetrics` (objects); this module only gathers them over
rooms and formats them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

TABLE_CLASSES = ("bed", "chair", "tv", "plant")

#: The paper's Table 2 ("with context term" and "after initialization"), for the side-by-side table.
PAPER_TABLE2 = {
    "with_context": {"orient_deg": {"bed": (0.8, 0.6), "chair": (8.0, 6.4), "tv": (0.8, 0.7)},
                     "pos_cm": {"bed": (21.0, 13.0), "chair": (7.1, 7.3), "tv": (2.0, 7.0), "plant": (6.9, 0.5)},
                     "wall_height_cm": (4.9, 0.1)},
    "after_init": {"orient_deg": {"bed": (5.2, 0.5), "chair": (4.1, 1.8), "tv": (2.8, 1.5)},
                   "pos_cm": {"bed": (197.6, 57.6), "chair": (186.7, 99.6), "tv": (156.21, 73.0),
                              "plant": (174.7, 70.3)}},
}


@dataclass
class RoomScore:
    """Scores of one room (final scene, and the initial one before context sampling when known)."""

    name: str
    ok: bool
    error: str | None = None
    layout: dict = field(default_factory=dict)
    objects: dict = field(default_factory=dict)
    objects_init: dict = field(default_factory=dict)


def _objects(scene: Mapping) -> list:
    from layout.objectmetrics import ObjectRecord

    return [ObjectRecord.from_json(o) for o in scene.get("objects") or []]


def _errors_dict(errs: Mapping) -> dict:
    return {c: {"n_gt": e.n_gt, "n_pred": e.n_pred, "matched": e.matched,
                "pos": e.position.tolist(), "orient": np.rad2deg(e.orientation).tolist()} for c, e in errs.items()}


def score_room(name: str, scene: Mapping | None, gt: Mapping, initial: Mapping | None = None,
               error: str | None = None) -> RoomScore:
    """Score one predicted scene.json dict against its gt.json dict (a missing scene scores 0 IoU)."""
    from layout.metrics import score_layout
    from layout.objectmetrics import match_objects

    g_floor, g_ceil = gt["room"]["floor"], float(gt["room"]["ceiling_z"])
    if scene is None:
        return RoomScore(name, False, error or "no scene", {"iou_2d": 0.0, "iou_3d": 0.0})
    s = score_layout(scene["room"]["floor"], float(scene["room"]["ceiling_z"]), g_floor, g_ceil,
                     camera_height=float(gt["camera_height_m"]), width=int(gt["image"]["width"]))
    cam = scene.get("camera", {}).get("height_m")
    layout = {"iou_2d": s.iou_2d, "iou_3d": s.iou_3d, "corners_ok": bool(s.corners_ok),
              "n_pred": len(scene["room"]["floor"]), "n_gt": len(g_floor),
              "wall_height_err": abs(float(scene["room"]["ceiling_z"]) - float(scene["room"].get("floor_z") or 0.0)
                                     - g_ceil),
              "camera_height_err": None if cam is None else abs(float(cam) - float(gt["camera_height_m"]))}
    objs = _errors_dict(match_objects(_objects(scene), _objects(gt))) if gt.get("objects") else {}
    init = _errors_dict(match_objects(_objects(initial), _objects(gt))) if initial and gt.get("objects") else {}
    return RoomScore(name, True, None, layout, objs, init)


def _mean_std(values: Sequence[float]) -> tuple[float, float, int]:
    v = np.asarray(values, dtype=np.float64)
    return (float(v.mean()), float(v.std()), len(v)) if len(v) else (math.nan, math.nan, 0)


#: An orientation this far off (deg) counts as a flip or a quarter turn in the summary's ``orient_over_deg``.
FLIP_DEG = 45.0


def _median(values: Sequence[float]) -> float:
    return float(np.median(values)) if len(values) else math.nan


def _share_over(values: Sequence[float], limit: float) -> float:
    return float(np.mean(np.asarray(values, dtype=np.float64) > limit)) if len(values) else math.nan


def summarize(scores: Sequence[RoomScore], ap: Mapping[str, float] | None = None) -> dict:
    """Means and spreads over rooms: layout, Table 2 object errors (cm, deg) before and after context.

    Besides the paper's mean and std (``pos_cm``, ``orient_deg``: (mean, std, n) per class), the medians
    (``pos_median_cm``, ``orient_median_deg``) and the share of objects more than :data:`FLIP_DEG` off
    (``orient_over_deg``): a few flipped or quarter-turned objects make most of a mean orientation error.
    """
    ok = [s for s in scores if s.ok]
    lay = {"n_rooms": len(scores), "failed": len(scores) - len(ok),
           "iou_3d": float(np.mean([s.layout.get("iou_3d", 0.0) for s in scores])) if scores else math.nan,
           "iou_2d": float(np.mean([s.layout.get("iou_2d", 0.0) for s in scores])) if scores else math.nan,
           "corners_ok": float(np.mean([s.layout.get("corners_ok", False) for s in scores])) if scores else math.nan}
    wh = [100.0 * s.layout["wall_height_err"] for s in ok]
    lay["wall_height_cm"] = _mean_std(wh)
    out: dict = {"layout": lay, "with_context": {}, "after_init": {}}
    for key, attr in (("with_context", "objects"), ("after_init", "objects_init")):
        table: dict = {"pos_cm": {}, "orient_deg": {}, "matched": {}, "pos_median_cm": {}, "orient_median_deg": {},
                       "orient_over_deg": {}}
        for cls in TABLE_CLASSES:
            pos, ori, n_gt, matched = [], [], 0, 0
            for s in ok:
                e = getattr(s, attr).get(cls)
                if e:
                    pos += [100.0 * p for p in e["pos"]]
                    ori += e["orient"]
                    n_gt += e["n_gt"]
                    matched += e["matched"]
            table["pos_cm"][cls] = _mean_std(pos)
            table["orient_deg"][cls] = _mean_std(ori)
            table["pos_median_cm"][cls] = _median(pos)
            table["orient_median_deg"][cls] = _median(ori)
            table["orient_over_deg"][cls] = _share_over(ori, FLIP_DEG)
            table["matched"][cls] = (matched, n_gt)
        out[key] = table
    if ap is not None:
        out["detection_ap50"] = dict(ap)
    return out


def _fmt(ms: tuple, digits: int = 1) -> str:
    m, s = ms[0], ms[1]
    return "n/a" if m is None or s is None or not math.isfinite(m) else f"{m:.{digits}f} ± {s:.{digits}f}"


def _num(value: float | None, fmt: str) -> str:
    return "n/a" if value is None or not math.isfinite(value) else fmt.format(value)


def _ours_row(name: str, cells: Sequence[str]) -> str:
    """A Table-2 row with one of our figures per class and the paper's columns empty."""
    return f"| {name} | " + " | ".join(f"{c} | " for c in cells) + "|"


def markdown_table2(summary: Mapping) -> str:
    """The paper's Table 2 layout: ours before/with context next to the paper's figures.

    Under each stage, rows the paper does not have (its columns empty): our medians and the share of objects more
    than :data:`FLIP_DEG` off, and the matched objects. Summaries written before these keys existed get "n/a".
    """
    rows = ["| | " + " | ".join(f"{c} (ours)" + " | " + f"{c} (paper)" for c in TABLE_CLASSES) + " |",
            "|---|" + "---|" * (2 * len(TABLE_CLASSES))]
    for key, title in (("after_init", "after initialisation"), ("with_context", "with context term")):
        t, p = summary[key], PAPER_TABLE2[key]
        ori = [_fmt(t["orient_deg"][c]) + " | " + (_fmt(p["orient_deg"][c]) if c in p["orient_deg"] else "n/a")
               for c in TABLE_CLASSES]
        pos = [_fmt(t["pos_cm"][c]) + " | " + _fmt(p["pos_cm"][c]) for c in TABLE_CLASSES]
        rows.append(f"| orientation error (deg), {title} | " + " | ".join(ori) + " |")
        rows.append(f"| position error (cm), {title} | " + " | ".join(pos) + " |")
        med, over, pos_med = (t.get(k, {}) for k in ("orient_median_deg", "orient_over_deg", "pos_median_cm"))
        rows.append(_ours_row(f"orientation error (deg), median; share over {FLIP_DEG:g} deg, {title}",
                              ["n/a" if c not in p["orient_deg"] else
                               f"{_num(med.get(c), '{:.1f}')}; {_num(over.get(c), '{:.1%}')}" for c in TABLE_CLASSES]))
        rows.append(_ours_row(f"position error (cm), median, {title}",
                              [_num(pos_med.get(c), "{:.1f}") for c in TABLE_CLASSES]))
        rows.append(_ours_row(f"matched / ground truth, {title}",
                              ["{}/{}".format(*t["matched"][c]) for c in TABLE_CLASSES]))
    lay = summary["layout"]
    rows.append(f"| wall height error (cm), with context | {_fmt(lay['wall_height_cm'])} | "
                f"{_fmt(PAPER_TABLE2['with_context']['wall_height_cm'])} |" + " |" * (2 * len(TABLE_CLASSES) - 2))
    text = "\n".join(rows)
    text += (f"\n\nLayout: mean 3D IoU {lay['iou_3d']:.3f}, 2D IoU {lay['iou_2d']:.3f}, exact corner count "
             f"{100 * lay['corners_ok']:.0f}% over {lay['n_rooms']} rooms ({lay['failed']} failed).")
    if summary.get("detection_ap50"):
        text += "\n\nDetection AP@0.5: " + ", ".join(f"{c} {v:.3f}" for c, v in sorted(summary["detection_ap50"].items()))
    return text + "\n"


def jsonable(obj):
    """``obj`` with non-finite floats (means of empty sets) as None: unknown values are null in JSON."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    return obj


def load_json(path: Path) -> dict | None:
    """A JSON file, or None when missing or unreadable (a failed run scores zero, it is not skipped)."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
