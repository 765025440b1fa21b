"""``report.html``: one self-contained page summarising a ``pano2cad run`` output folder.

The page opens offline (no request leaves the file; a Content-Security-Policy
in the page forbids any): every picture is a ``data:`` URI, the floor plan
SVG is inlined, ``scene.glb`` is embedded as base64 and handed to three.js'
``GLTFLoader.parse``, and the vendored three.js modules
(``apps/report_assets/three``, see its README) are inlined through an import
map of ``data:`` URLs.

Sections: the input panorama with toggleable layers (``overlay.png``, the
colour-coded ``labels.png``, and vector layers of the room layout and object
boxes drawn from scene.json), the floor plan, a table of the objects, the
per-stage timings and warnings, and an interactive 3D view (orbit, zoom, and a
first-person view from the camera position).

A folder without ``scene.json`` (a failed or interrupted run), without
objects, or without some picture still gives a page; it says what is missing.

Convention:
    Panorama pixels and the world frame are those of shared/CONVENTIONS.md;
    scene.glb is y-up (``(x, y, z)`` world -> ``(x, z, -y)`` glTF), so the
    camera sits at glTF ``(0, floor_z + camera_height, 0)`` looking along +x
    (the image centre column).

The page sets ``data-view3d`` on ``<body>`` to ``pending``, ``ready`` (first
frame drawn; ``data-canvas-variance`` and ``data-canvas-variance-fp`` then hold
the pixel variance of the orbit and first-person views, ``data-canvas-rect`` the
canvas' ``[x, y, width, height]`` on the page), ``missing`` (no
scene.glb), ``no-webgl`` or ``error`` (``data-view3d-error`` says why);
``data-csp-violations`` counts blocked requests and ``data-resources`` lists
any resource the page fetched that is not a ``data:``/``blob:`` URL.
"""

from __future__ import annotations

import base64
import html
import json
import os
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .atomic import write_text

__all__ = ["REPORT_FILE", "THREE_VERSION", "CSP", "ReportInputs", "read_inputs", "build_report", "write_report",
           "external_references", "INDEX_FILE", "build_batch_index", "write_batch_index"]

#: File name of the report inside a run's output folder.
REPORT_FILE = "report.html"

_ASSETS = Path(__file__).resolve().parent / "report_assets"
_THREE = _ASSETS / "three"

#: The vendored three.js version (``apps/report_assets/three/VERSION``).
THREE_VERSION = (_THREE / "VERSION").read_text().strip() if (_THREE / "VERSION").is_file() else "unknown"

#: Bare module specifiers of the import map -> vendored file.
_MODULES: dict[str, str] = {
    "three": "three.module.min.js",
    "three/addons/controls/OrbitControls.js": "OrbitControls.js",
    "three/addons/loaders/GLTFLoader.js": "GLTFLoader.js",
    "three/addons/utils/BufferGeometryUtils.js": "BufferGeometryUtils.js",
}

#: A ``data:`` module cannot resolve relative imports; they are rewritten to bare specifiers.
_RELATIVE_IMPORTS: dict[str, tuple[str, str]] = {
    "GLTFLoader.js": ("'../utils/BufferGeometryUtils.js'", "'three/addons/utils/BufferGeometryUtils.js'"),
}

#: Nothing may be fetched from anywhere but the page itself (data: / blob:).
CSP = ("default-src 'none'; script-src 'unsafe-inline' data:; style-src 'unsafe-inline'; "
       "img-src data: blob:; connect-src data: blob:; font-src data:; base-uri 'none'; form-action 'none'")


@dataclass(frozen=True)
class ReportInputs:
    """What a run's output folder holds for the report.

    Attributes
    ----------
    out_dir : Path
    scene : dict or None
        Parsed scene.json, None when missing or unreadable.
    files : mapping str -> Path
        The files found, by name (``overlay.png``, ``labels.png``,
        ``floorplan.svg``, ``scene.glb``, ``scene.json``).
    missing : tuple of str
        One sentence per missing or unreadable input.
    """

    out_dir: Path
    scene: dict[str, Any] | None
    files: Mapping[str, Path]
    missing: tuple[str, ...]


_EXPECTED = {
    "scene.json": "scene.json is missing: the run did not finish (no room, objects or timings to show)",
    "scene.glb": "scene.glb is missing: no 3D view",
    "floorplan.svg": "floorplan.svg is missing: no floor plan",
    "overlay.png": "overlay.png is missing: no panorama overlay",
    "labels.png": "labels.png is missing: no surface-label layer",
}


def read_inputs(out_dir: str | os.PathLike[str]) -> ReportInputs:
    """Collect the files of an output folder and say which are missing.

    Raises
    ------
    ValueError
        ``out_dir`` is not an existing folder.
    """
    d = Path(out_dir)
    if not d.is_dir():
        raise ValueError(f"{d}: expected an existing output folder")
    files = {name: d / name for name in _EXPECTED if (d / name).is_file()}
    missing = [msg for name, msg in _EXPECTED.items() if name not in files]
    scene = None
    if "scene.json" in files:
        try:
            scene = json.loads(files["scene.json"].read_text(encoding="utf-8"))
            if not isinstance(scene, dict) or scene.get("schema") != "pano2cad/scene@1":
                got = scene.get("schema") if isinstance(scene, dict) else type(scene).__name__
                raise ValueError(f"expected schema pano2cad/scene@1, got {got}")
        except (OSError, ValueError) as exc:
            missing.insert(0, f"scene.json could not be read ({exc})")
            scene = None
    return ReportInputs(d, scene, files, tuple(missing))


# ---------------------------------------------------------------- helpers

def _e(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _b64(path: Path) -> str:
    return base64.b64encode(path.read_bytes()).decode("ascii")


def _num(x: Any, fmt: str = "{:.2f}") -> str:
    if x is None:
        return "&ndash;"
    if isinstance(x, (list, tuple)):
        return ", ".join(_num(v, fmt) for v in x)
    try:
        return fmt.format(float(x))
    except (TypeError, ValueError):
        return _e(x)


def _script_json(obj: Any) -> str:
    """JSON safe inside a ``<script>`` element."""
    return json.dumps(obj, allow_nan=False).replace("</", "<\\/")


def _inline_svg(path: Path) -> str:
    text = path.read_text(encoding="utf-8")
    start = text.find("<svg")
    if start < 0:
        raise ValueError(f"{path}: expected an SVG document, found no <svg> element")
    return text[start:]


def _vector_layers(inputs: ReportInputs, width: int, height: int) -> tuple[str, str, str | None]:
    """SVG path data of the layout and of the object boxes in the overlay's pixel frame."""
    from layout.scene import Scene

    from .export.overlay import box_parts, layout_polylines

    def path_d(polys: Sequence[Any]) -> str:
        return " ".join("M" + " L".join(f"{u:.1f},{v:.1f}" for u, v in p) for p in polys if len(p) > 1)

    doc = inputs.scene or {}
    try:
        scene = Scene.from_json_dict(doc)
        pl = layout_polylines(scene, width, height)
    except (KeyError, TypeError, ValueError) as exc:
        return "", "", f"the layout could not be drawn ({exc})"
    layout_d = path_d(pl["floor"] + pl["ceiling"] + pl["corners"])
    img = doc.get("image") or {}
    sx = width / float(img["width"]) if img.get("width") else 1.0
    sy = height / float(img["height"]) if img.get("height") else 1.0
    boxes = []
    for o in doc.get("objects") or []:
        bb = o.get("bbox_pano")
        if not bb or len(bb) != 4 or any(v is None for v in bb):
            continue
        b = [bb[0] * sx, bb[1] * sy, bb[2] * sx, bb[3] * sy]
        parts = box_parts(b, width)
        name = _e(o.get("id", o.get("class", "?")))
        boxes.append(f'<path class="box" d="{path_d(parts)}"/>'
                     f'<text x="{b[0] + 3:.1f}" y="{max(b[1] - 4, 12):.1f}">{name}</text>')
    return layout_d, "".join(boxes), None


def _image_size(path: Path) -> tuple[int, int]:
    from PIL import Image

    with Image.open(path) as im:
        return im.size


# ---------------------------------------------------------------- sections

def _pano_section(inputs: ReportInputs) -> str:
    f = inputs.files
    base = f.get("overlay.png") or f.get("labels.png")
    if base is None:
        return ('<section id="panorama"><h2>Panorama</h2>'
                '<p class="missing">No panorama picture in this folder.</p></section>')
    w, h = _image_size(base)
    layers, toggles = [], []
    if "overlay.png" in f:
        layers.append(f'<img class="layer layer-overlay" alt="panorama with layout and objects" '
                      f'src="data:image/png;base64,{_b64(f["overlay.png"])}">')
        toggles.append(("overlay", "panorama with drawn layout and boxes", True))
    if "labels.png" in f:
        layers.append(f'<img class="layer layer-labels{" over" if "overlay.png" in f else ""}" alt="surface labels" '
                      f'src="data:image/png;base64,{_b64(f["labels.png"])}">')
        toggles.append(("labels", "surface labels", "overlay.png" not in f))
    note = ""
    if inputs.scene is not None:
        layout_d, boxes, err = _vector_layers(inputs, w, h)
        if err:
            note = f'<p class="missing">{_e(err)}</p>'
        layers.append(f'<svg class="layer vec" viewBox="0 0 {w} {h}" preserveAspectRatio="none" '
                      f'style="font-size:{w / 90:.1f}px;stroke-width:{w / 500:.2f}px">'
                      f'<g class="layer-layout"><path class="layout" d="{layout_d}"/></g>'
                      f'<g class="layer-boxes">{boxes}</g></svg>')
        toggles.append(("layout", "layout (vector)", True))
        toggles.append(("boxes", "object boxes (vector)", True))
    checks = "".join(f'<label><input type="checkbox" data-layer="{k}"{" checked" if on else ""}> {_e(t)}</label>'
                     for k, t, on in toggles)
    return (f'<section id="panorama"><h2>Panorama</h2><div class="toggles">{checks}</div>{note}'
            f'<div class="pano" style="aspect-ratio:{w}/{h}">{"".join(layers)}</div></section>')


def _plan_section(inputs: ReportInputs) -> str:
    if "floorplan.svg" not in inputs.files:
        return '<section id="plan"><h2>Floor plan</h2><p class="missing">floorplan.svg is missing.</p></section>'
    svg = _inline_svg(inputs.files["floorplan.svg"])
    return f'<section id="plan"><h2>Floor plan</h2><div class="plan">{svg}</div></section>'


def _objects_section(inputs: ReportInputs) -> str:
    if inputs.scene is None:
        return '<section id="objects"><h2>Objects</h2><p class="missing">Unknown: scene.json is missing.</p></section>'
    objs = inputs.scene.get("objects") or []
    if not objs:
        return '<section id="objects"><h2>Objects</h2><p class="missing">No objects in this scene.</p></section>'
    rows = "".join(
        f"<tr><td>{_e(o.get('id', ''))}</td><td>{_e(o.get('class', ''))}</td><td>{_num(o.get('center'))}</td>"
        f"<td>{_num(o.get('yaw_deg'), '{:.1f}')}</td><td>{_num(o.get('size'))}</td>"
        f"<td>{_e(o['model']) if o.get('model') is not None else '&ndash;'}</td><td>{_num(o.get('score'))}</td></tr>"
        for o in objs)
    return ('<section id="objects"><h2>Objects</h2><table class="objects"><thead><tr><th>id</th><th>class</th>'
            '<th>position x, y, z (m)</th><th>yaw (deg)</th><th>size l, w, h (m)</th><th>model</th><th>score</th>'
            f'</tr></thead><tbody>{rows}</tbody></table></section>')


def _timing_section(inputs: ReportInputs) -> str:
    doc = inputs.scene
    if doc is None:
        return '<section id="timing"><h2>Timings</h2><p class="missing">Unknown: scene.json is missing.</p></section>'
    t = {k: v for k, v in (doc.get("timing_s") or {}).items() if isinstance(v, (int, float))}
    warn = "".join(f"<li>{_e(w)}</li>" for w in doc.get("warnings") or [])
    warn = f'<h3>Warnings</h3><ul class="warnings">{warn}</ul>' if warn else ""
    if not t:
        return f'<section id="timing"><h2>Timings</h2><p class="missing">No timings recorded.</p>{warn}</section>'
    top = max(t.values()) or 1.0
    rows = "".join(f'<tr><td>{_e(k)}</td><td class="num">{v:.2f}</td>'
                   f'<td><span class="bar" style="width:{100.0 * v / top:.1f}%"></span></td></tr>'
                   for k, v in sorted(t.items(), key=lambda kv: kv[0] == "total"))
    return (f'<section id="timing"><h2>Timings</h2><table class="timing"><thead><tr><th>stage</th><th>s</th><th></th>'
            f'</tr></thead><tbody>{rows}</tbody></table>{warn}</section>')


def _view3d_section(inputs: ReportInputs) -> str:
    if "scene.glb" not in inputs.files:
        return ('<section id="view3d"><h2>3D view</h2><p class="missing">scene.glb is missing: no 3D view.</p>'
                '</section>')
    return ('<section id="view3d"><h2>3D view</h2><div class="toggles">'
            '<button type="button" id="btn-orbit">orbit</button> '
            '<button type="button" id="btn-fp">first person (camera position)</button> '
            '<span class="hint">drag: rotate, wheel: zoom, right-drag: pan</span></div>'
            '<div id="viewport"><p class="missing" id="view3d-msg">Loading the 3D view&hellip;</p></div>'
            f'<script type="application/octet-stream" id="glb-data">{_b64(inputs.files["scene.glb"])}</script>'
            '</section>')


def _importmap() -> str:
    imports = {}
    for spec, name in _MODULES.items():
        src = (_THREE / name).read_text(encoding="utf-8")
        if name in _RELATIVE_IMPORTS:
            old, new = _RELATIVE_IMPORTS[name]
            if old not in src:
                raise RuntimeError(f"{_THREE / name}: expected the import {old} to rewrite; re-vendor three.js")
            src = src.replace(old, new)
        imports[spec] = "data:text/javascript;base64," + base64.b64encode(src.encode("utf-8")).decode("ascii")
    return _script_json({"imports": imports})


def build_report(out_dir: str | os.PathLike[str]) -> str:
    """The HTML text of the report of an output folder (see the module docstring).

    Examples
    --------
    >>> import tempfile
    >>> page = build_report(tempfile.mkdtemp())
    >>> "scene.json is missing" in page and 'data-view3d="missing"' in page
    True
    """
    inputs = read_inputs(out_dir)
    doc = inputs.scene or {}
    cam_h = (doc.get("camera") or {}).get("height_m")
    room = doc.get("room") or {}
    data = {"camera_height_m": cam_h, "floor_z": room.get("floor_z", 0.0)}
    title = (doc.get("image") or {}).get("file") or inputs.out_dir.name
    missing = "".join(f"<li>{_e(m)}</li>" for m in inputs.missing)
    missing = f'<ul class="missing" id="missing">{missing}</ul>' if missing else ""
    summary = ""
    if inputs.scene is not None:
        floor = room.get("floor") or []
        xs, ys = [p[0] for p in floor], [p[1] for p in floor]
        ext = f"{max(xs) - min(xs):.2f} x {max(ys) - min(ys):.2f} m, " if floor else ""
        ceil = room.get("ceiling_z")
        summary = (f'<p class="summary">Room {ext}{len(floor)} corners, ceiling '
                   f'{_num(ceil) + " m" if ceil is not None else "unknown"}, camera {_num(cam_h)} m, '
                   f'{len(doc.get("objects") or [])} objects.</p>')
    css = (_ASSETS / "report.css").read_text(encoding="utf-8")
    js = (_ASSETS / "report.js").read_text(encoding="utf-8")
    if "</script" in js.lower() or "</style" in css.lower():
        raise RuntimeError(f"{_ASSETS}: report.js / report.css must not contain a closing </script> or </style> tag")
    state = "pending" if "scene.glb" in inputs.files else "missing"
    return "\n".join([
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>pano2cad report: {_e(title)}</title>",
        f"<style>{css}</style>",
        "<script>window.addEventListener('error',function(e){document.body&&document.body.setAttribute("
        "'data-view3d-error',String(e.message));});</script>",
        "</head>",
        f'<body data-view3d="{state}" data-csp-violations="0" data-resources="[]">',
        f"<header><h1>pano2cad report: {_e(title)}</h1>{summary}{missing}</header>",
        _pano_section(inputs), _plan_section(inputs), _objects_section(inputs), _timing_section(inputs),
        _view3d_section(inputs),
        f'<footer>Made by pano2cad; 3D view by three.js r{_e(THREE_VERSION)} (MIT licence, below).'
        f'<details><summary>three.js licence</summary><pre>{_e((_THREE / "LICENSE").read_text())}</pre></details>'
        "</footer>",
        f'<script type="application/json" id="report-data">{_script_json(data)}</script>',
        f'<script type="importmap">{_importmap()}</script>',
        f'<script type="module">{js}</script>',
        "</body></html>",
        "",
    ])


def write_report(out_dir: str | os.PathLike[str]) -> Path:
    """Write ``out_dir/report.html`` atomically and return its path.

    Raises
    ------
    ValueError
        ``out_dir`` is not an existing folder.
    """
    page = build_report(out_dir)
    return write_text(Path(out_dir) / REPORT_FILE, page)


_HTTP_ATTR = re.compile(r"""(?:src|href|action|poster|data)\s*=\s*["']?\s*(?:https?:)?//""", re.I)


def external_references(page: str) -> list[str]:
    """Attributes of ``page`` that point outside the file (``src="https://..."``, ``href="//..."``)."""
    return [m.group(0) for m in _HTTP_ATTR.finditer(page)]


#: File name of the batch index inside a ``pano2cad batch`` output folder.
INDEX_FILE = "index.html"


def _thumbnail(path: Path, width: int = 320) -> str:
    import io

    from PIL import Image

    with Image.open(path) as im:
        im = im.convert("RGB")
        im.thumbnail((width, width))
        buf = io.BytesIO()
        im.save(buf, format="JPEG", quality=80)
    return "data:image/jpeg;base64," + base64.b64encode(buf.getvalue()).decode("ascii")


def build_batch_index(batch_dir: str | os.PathLike[str]) -> str:
    """HTML of an index page linking the report of every run folder under ``batch_dir``, with thumbnails.

    A run folder is a direct sub-folder holding ``report.html``, ``scene.json``
    or ``overlay.png``; folders whose names start with ``.`` (partial runs) are
    skipped. A folder without ``report.html`` is listed without a link.

    Examples
    --------
    >>> import tempfile
    >>> "No runs in this folder" in build_batch_index(tempfile.mkdtemp())
    True
    """
    d = Path(batch_dir)
    if not d.is_dir():
        raise ValueError(f"{d}: expected an existing batch output folder")
    runs = sorted(p for p in d.iterdir() if p.is_dir() and not p.name.startswith(".")
                  and any((p / n).is_file() for n in (REPORT_FILE, "scene.json", "overlay.png")))
    cards = []
    for run in runs:
        inputs = read_inputs(run)
        doc = inputs.scene
        thumb = inputs.files.get("overlay.png") or inputs.files.get("labels.png")
        img = (f'<img alt="{_e(run.name)}" src="{_thumbnail(thumb)}">' if thumb is not None
               else '<div class="noimg">no picture</div>')
        if doc is None:
            info = '<span class="missing">failed: no scene.json</span>'
        else:
            floor = (doc.get("room") or {}).get("floor") or []
            xs, ys = [p[0] for p in floor], [p[1] for p in floor]
            ext = f"{max(xs) - min(xs):.1f} x {max(ys) - min(ys):.1f} m, " if floor else ""
            info = f"{ext}{len(doc.get('objects') or [])} objects"
        name = _e(run.name)
        if (run / REPORT_FILE).is_file():
            href = _e(f"{run.name}/{REPORT_FILE}")
            cards.append(f'<a class="card" href="{href}">{img}<b>{name}</b><br>{info}</a>')
        else:
            cards.append(f'<div class="card">{img}<b>{name}</b><br>{info}<br>'
                         f'<span class="missing">no report.html</span></div>')
    body = "".join(cards) if cards else '<p class="missing">No runs in this folder.</p>'
    css = ("body{font:14px/1.4 system-ui,sans-serif;margin:12px 20px;color:#222}.missing{color:#a33}"
           ".card{display:inline-block;vertical-align:top;width:330px;margin:6px;padding:6px;border:1px solid #ddd;"
           "color:inherit;text-decoration:none}.card img{width:320px;display:block}"
           ".noimg{width:320px;height:160px;background:#eee}")
    return "\n".join([
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{CSP}">',
        f"<title>pano2cad batch: {_e(d.name)}</title><style>{css}</style></head><body>",
        f"<h1>pano2cad batch: {_e(d.name)} ({len(runs)} runs)</h1>", body, "</body></html>", ""])


def write_batch_index(batch_dir: str | os.PathLike[str]) -> Path:
    """Write ``batch_dir/index.html`` (see :func:`build_batch_index`) atomically and return its path."""
    page = build_batch_index(batch_dir)
    return write_text(Path(batch_dir) / INDEX_FILE, page)
