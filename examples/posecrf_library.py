"""Contact sheet and statistics of posecrf's built-in 3D model library.

Run:  .venv/bin/python examples/posecrf_library.py [--out out/examples]

Writes ``library_contact_sheet.png`` (every built-in model drawn in an
orthographic view from front-right-above by a small z-buffer rasteriser,
faces Lambert-shaded, a red arrow on the floor pointing to +x = the model's front)
and ``library_stats.md`` (the table in docs/EVALUATION.md), and exports one
model to GLB and OBJ to time the exporters.

Convention: models are in the canonical model frame (metres, z up, bbox
centre x = y = 0, min z = 0, front facing +x); view angles in radians.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def view_basis(azimuth: float, elevation: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unit vectors (right, up, towards_camera) of an orthographic view.

    The camera sits in direction (cos(el)cos(az), cos(el)sin(az), sin(el))
    from the model and looks at it.
    """
    c = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    forward = -c
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    return right, up, c


def rasterize(model, azimuth: float = -0.6, elevation: float = 0.45, size: int = 220, supersample: int = 2):
    """Z-buffered orthographic rendering of a model's coloured faces.

    Returns
    -------
    image : (size, size, 3) float in [0, 1]
    to_px : callable mapping (N, 3) model points to (N, 2) pixel (col, row)
    """
    right, up, toward = view_basis(azimuth, elevation)
    s_px = size * supersample
    v = model.vertices
    l, w, _ = model.size
    arrow = np.array([[l / 2 + 0.02, 0, 0], [l / 2 + 0.3, 0, 0]])
    floor = np.array([[-l / 2, -w / 2, 0], [l / 2, -w / 2, 0], [l / 2, w / 2, 0], [-l / 2, w / 2, 0]])
    pts = np.concatenate([v, arrow, floor])
    uv = np.stack([pts @ right, pts @ up], axis=1)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    scale = 0.9 * s_px / max(hi - lo)
    mid = (lo + hi) / 2

    def to_px(p: np.ndarray, ss: int = 1) -> np.ndarray:
        q = np.stack([p @ right, p @ up], axis=-1)
        col = (q[..., 0] - mid[0]) * scale + s_px / 2
        row = s_px / 2 - (q[..., 1] - mid[1]) * scale
        return np.stack([col, row], axis=-1) / ss

    img = np.ones((s_px, s_px, 3))
    zbuf = np.full((s_px, s_px), -np.inf)

    def fill(tri3: np.ndarray, color: np.ndarray, use_z: bool) -> None:
        p = to_px(tri3)
        z = tri3 @ toward
        c0, r0 = np.floor(p.min(axis=0)).astype(int)
        c1, r1 = np.ceil(p.max(axis=0)).astype(int)
        c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, s_px - 1), min(r1, s_px - 1)
        if c1 < c0 or r1 < r0:
            return
        cc, rr = np.meshgrid(np.arange(c0, c1 + 1) + 0.5, np.arange(r0, r1 + 1) + 0.5)
        (x0, y0), (x1, y1), (x2, y2) = p
        det = (y1 - y2) * (x0 - x2) + (x2 - x1) * (y0 - y2)
        if abs(det) < 1e-12:
            return
        a = ((y1 - y2) * (cc - x2) + (x2 - x1) * (rr - y2)) / det
        b = ((y2 - y0) * (cc - x2) + (x0 - x2) * (rr - y2)) / det
        g = 1 - a - b
        inside = (a >= 0) & (b >= 0) & (g >= 0)
        zz = a * z[0] + b * z[1] + g * z[2]
        sub_z = zbuf[r0 : r1 + 1, c0 : c1 + 1]
        win = inside & (zz > sub_z) if use_z else inside
        sub_z[win] = zz[win] if use_z else sub_z[win]
        img[r0 : r1 + 1, c0 : c1 + 1][win] = color

    for tri in (floor[[0, 1, 2]], floor[[0, 2, 3]]):
        fill(tri, np.array([0.92, 0.92, 0.92]), use_z=False)
    tri_all = v[model.faces]
    n = np.cross(tri_all[:, 1] - tri_all[:, 0], tri_all[:, 2] - tri_all[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    light = np.array([0.5, -0.3, 0.8])
    light /= np.linalg.norm(light)
    shade = 0.45 + 0.55 * np.clip(n @ light, 0.0, 1.0)
    cols = model.face_colors[:, :3] / 255.0 * shade[:, None]
    # cull faces turned away (closed solids; single-sided screen quads face +x)
    for k in np.flatnonzero(n @ toward > 0):
        fill(tri_all[k], cols[k], use_z=True)
    image = img.reshape(size, supersample, size, supersample, 3).mean(axis=(1, 3))
    return image, lambda p: to_px(p, supersample), arrow


def draw_model(ax, model, azimuth: float = -0.6, elevation: float = 0.45) -> None:
    """Show a z-buffered rendering of the model with a red arrow to its front (+x)."""
    image, to_px, arrow = rasterize(model, azimuth, elevation)
    ax.imshow(image, interpolation="bilinear")
    a2 = to_px(arrow)
    ax.annotate("", xy=a2[1], xytext=a2[0], arrowprops=dict(arrowstyle="->", color="red", lw=1.5))
    ax.axis("off")


def contact_sheet(library, path: Path, cols: int = 8) -> None:
    """Draw every model of `library` into one PNG at `path`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = list(library)
    rows = int(np.ceil(len(models) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(cols * 2.3, rows * 2.5), dpi=110)
    for ax in axes.ravel():
        ax.axis("off")
    for ax, m in zip(axes.ravel(), models):
        draw_model(ax, m)
        ax.set_title(f"{m.id}\n{m.size[0]:.2f} x {m.size[1]:.2f} x {m.size[2]:.2f} m", fontsize=7)
    fig.suptitle("posecrf built-in library (red arrow: front = +x)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)


def stats_markdown() -> str:
    """Measure the library and return the markdown table for docs/EVALUATION.md."""
    from posecrf.library import builtin_library, export_model
    from posecrf.library.procedural import build_all

    t0 = time.perf_counter()
    models = build_all()
    t_build = time.perf_counter() - t0
    lib = builtin_library()
    lines = [
        "| class | models | faces min / median / max | size l x w x h (m), smallest .. largest volume |",
        "|---|---|---|---|",
    ]
    for cls in lib.classes:
        ms = lib.by_class(cls)
        faces = np.array([m.n_faces for m in ms])
        vols = [float(np.prod(m.size)) for m in ms]
        a, b = ms[int(np.argmin(vols))].size, ms[int(np.argmax(vols))].size
        lines.append(
            f"| {cls} | {len(ms)} | {faces.min()} / {int(np.median(faces))} / {faces.max()} | "
            f"{a[0]:.2f} x {a[1]:.2f} x {a[2]:.2f} .. {b[0]:.2f} x {b[1]:.2f} x {b[2]:.2f} |"
        )
    n_hash = len({m.content_hash() for m in lib})
    with tempfile.TemporaryDirectory() as tmp:
        big = max(lib, key=lambda m: m.n_faces)
        t0 = time.perf_counter()
        export_model(big, Path(tmp) / "m.glb")
        t_glb = time.perf_counter() - t0
        t0 = time.perf_counter()
        export_model(big, Path(tmp) / "m.obj")
        t_obj = time.perf_counter() - t0
    user = user_folder_check()
    lines += [
        "",
        f"- {len(models)} models, {sum(m.n_faces for m in models)} faces in all; "
        f"{n_hash} distinct content hashes.",
        f"- building all models: {t_build:.2f} s (one process, 2-core machine).",
        f"- export of the largest model ({big.id}, {big.n_faces} faces): GLB {t_glb * 1000:.0f} ms, OBJ {t_obj * 1000:.0f} ms.",
        user,
    ]
    return "\n".join(lines)


def user_folder_check() -> str:
    """Write every built-in model as a user file (front -y, up +z, centimetres,
    offset origin; GLB with one node per part), plus one broken file, load the
    folder and measure how well the canonical frame and size come back."""
    import json

    import trimesh
    from scipy.spatial import cKDTree

    from posecrf.library import axes_rotation, builtin_library, load_model_folder

    lib = builtin_library()
    r = axes_rotation("-y", "+z")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for m in lib:
            scene = trimesh.Scene()
            for pid, name in enumerate(m.part_names):
                sel = m.face_parts == pid
                part = trimesh.Trimesh((m.vertices @ r) * 100.0 + [30.0, -12.0, 5.0], m.faces[sel], face_colors=m.face_colors[sel], process=False)
                part.remove_unreferenced_vertices()
                scene.add_geometry(part, geom_name=name, node_name=name)
            scene.export(str(folder / f"user-{m.id}.glb"))
            meta = {"class": m.cls, "front": "-y", "up": "+z", "units": "cm"}
            (folder / f"user-{m.id}.json").write_text(json.dumps(meta))
        (folder / "broken.glb").write_bytes(b"glTF-not-really")
        (folder / "broken.json").write_text(json.dumps({"class": "tv", "front": "+x", "up": "+z", "units": "m"}))
        t0 = time.perf_counter()
        res = load_model_folder(folder)
        t_load = time.perf_counter() - t0
    size_err = max(float(np.abs(u.size - lib[u.id[5:]].size).max()) for u in res.library)
    vert_err = max(float(cKDTree(lib[u.id[5:]].vertices).query(u.vertices)[0].max()) for u in res.library)
    return (
        f"- user folder: {len(res.library)} of {len(lib)} re-exported models (front -y, up +z, cm) loaded in "
        f"{t_load:.2f} s, {len(res.errors)} error(s) reported ({', '.join(e.file.name for e in res.errors)}); "
        f"max size error {size_err:.1e} m, max vertex distance to the original {vert_err:.1e} m."
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/examples"), help="output folder (default: out/examples)")
    args = parser.parse_args(argv)
    from posecrf.library import builtin_library

    args.out.mkdir(parents=True, exist_ok=True)
    sheet = args.out / "library_contact_sheet.png"
    contact_sheet(builtin_library(), sheet)
    table = stats_markdown()
    (args.out / "library_stats.md").write_text(table + "\n")
    print(table)
    print(f"wrote {sheet}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
