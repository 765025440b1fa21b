"""Object pose and model from a panorama with posecrf: crops -> HOG k-NN -> pose CRF -> world yaw.

Run:  PYOPENGL_PLATFORM=egl .venv/bin/python examples/posecrf_pose.py [--out out/examples] [--seed 3]

1. A panorama of a box room with a bed, a TV and two chairs from the built-in
   library at random yaws is ray cast with panogeom (camera 1.6 m high,
   faces shaded by their colour and the angle to the ray).
2. Each object's box in the panorama (from the instance image, as a
   detector would give it) is cut out as a perspective crop centred on its
   viewing ray (``posecrf.crops.extract_crop``); the instance image gives the
   mask (grab-cut's job in the full pipeline).
3. ``posecrf.cache.library_renders`` loads the library's pose-render
   descriptors (rendered once, ~1 min on 2 cores, then cached in
   ``$PANO2CAD_CACHE`` or ``~/.cache/pano2cad/renders``).
4. ``posecrf.pose.estimate_poses`` runs the pose CRF per class; the
   crop-relative yaw becomes a world yaw with ``PoseEstimate.world_yaw``.

Prints a table (true and estimated world yaw, model, confidence) and writes
``posecrf_pose.png``: per object the crop, and the retrieved model rendered
at the estimated pose.

Convention: world frame of shared/CONVENTIONS.md (metres, z up, yaw
counter-clockwise from +x to the object's front); angles are radians inside
and printed in degrees.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

from panogeom.perspective import equirect_to_perspective  # noqa: E402
from panogeom.rotation import angle_difference  # noqa: E402
from panogeom.raycast import RenderMesh, pose_matrix, raycast_equirect, room_meshes, transform_mesh  # noqa: E402
from posecrf.cache import library_renders  # noqa: E402
from posecrf.crops import extract_crop  # noqa: E402
from posecrf.library import builtin_library  # noqa: E402
from posecrf.pose import estimate_poses  # noqa: E402
from posecrf.render import PoseRenderer  # noqa: E402

CAMERA = np.array([0.0, 0.0, 1.6])


def scene(seed: int):
    """Room mesh, placed objects [(model, yaw, instance id)] and the object meshes."""
    lib = builtin_library()
    rng = np.random.default_rng(seed)
    picks = [lib["bed-02"], lib["tv-03"], lib["chair-01"], lib["chair-07"]]
    room = room_meshes([[-3.5, -3.0], [3.5, -3.0], [3.5, 3.0], [-3.5, 3.0]], ceiling_z=2.7)
    meshes, placed = [room], []
    for k, m in enumerate(picks, start=1):
        az = 2 * math.pi * (k - 1) / len(picks) + rng.uniform(-0.3, 0.3)
        dist = rng.uniform(1.9, 2.5) if m.cls != "bed" else 2.3
        yaw = float(rng.uniform(0, 2 * math.pi))
        pos = [dist * math.cos(az), dist * math.sin(az), 0.0]
        rm = RenderMesh(m.vertices, m.faces, labels=5, instance_ids=k, colors=m.face_colors[:, :3])
        meshes.append(transform_mesh(rm, pose_matrix(yaw, pos)))
        placed.append((m, yaw, k))
    return meshes, placed


def shade(result, meshes) -> np.ndarray:
    """Albedo of the hit face times a simple angle term: (H, W, 3) uint8."""
    colors = np.concatenate([m.colors for m in meshes])
    hit = result.face_ids >= 0
    albedo = np.where(hit[..., None], colors[np.maximum(result.face_ids, 0)], 0.0)
    cosang = np.abs(np.nansum(result.normals * result.rays, axis=-1))
    img = albedo * (0.4 + 0.6 * cosang)[..., None]
    return (np.clip(img, 0, 1) * 255).astype(np.uint8)


def instance_box(inst: np.ndarray, k: int) -> list[float]:
    """Panorama box (u0, v0, u1, v1) of instance k, seam-aware (u0 > u1 when it wraps)."""
    ys, xs = np.nonzero(inst == k)
    W = inst.shape[1]
    cols = np.unique(xs)
    gaps = np.diff(np.concatenate([cols, [cols[0] + W]]))
    j = int(np.argmax(gaps))  # the widest empty run of columns lies outside the object
    u0, u1 = float(cols[(j + 1) % len(cols)]), float(cols[j] + 1)
    return [u0, float(ys.min()), u1, float(ys.max() + 1)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/examples"))
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--width", type=int, default=2048, help="panorama width")
    args = ap.parse_args(argv)
    import cv2

    meshes, placed = scene(args.seed)
    res = raycast_equirect(meshes, args.width, CAMERA)
    pano = shade(res, meshes)
    renders = library_renders(builtin_library(), progress=True)

    by_class: dict[str, list] = {}
    for m, yaw, k in placed:
        box = instance_box(res.instance_ids, k)
        crop, view = extract_crop(pano, box, size=160, margin=0.1)
        mask = equirect_to_perspective((res.instance_ids == k).astype(np.uint8), view, "nearest") > 0
        by_class.setdefault(m.cls, []).append((m, yaw, crop, mask, view))

    print(f"{'object':10} {'true yaw':>9} {'est. yaw':>9} {'error':>6} {'model':>9} {'conf':>5}")
    tiles = []
    with PoseRenderer(renders.settings) as r:
        for cls, items in by_class.items():
            out = estimate_poses(renders, cls, [i[2] for i in items], [i[3] for i in items])
            for (m, yaw, crop, mask, view), e in zip(items, out.estimates):
                wy = e.world_yaw(view.direction)
                err = float(angle_difference(wy, yaw))
                print(f"{m.id:10} {math.degrees(yaw):9.1f} {math.degrees(wy):9.1f} {math.degrees(err):6.1f} "
                      f"{e.model_id:>9} {e.confidence:5.2f}")
                rgb, _ = r.render(builtin_library()[e.model_id], e.yaw_rel, e.pitch)
                tiles.append(np.concatenate([cv2.resize(crop, (128, 128)), cv2.resize(rgb, (128, 128))], axis=1))
    args.out.mkdir(parents=True, exist_ok=True)
    sheet = np.concatenate(tiles, axis=0)
    cv2.imwrite(str(args.out / "posecrf_pose.png"), sheet[..., ::-1])
    cv2.imwrite(str(args.out / "posecrf_pose_pano.jpg"), pano[..., ::-1])
    print(f"wrote {args.out / 'posecrf_pose.png'} and {args.out / 'posecrf_pose_pano.jpg'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
