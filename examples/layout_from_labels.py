"""Room geometry from surface labels: an L-shaped room, its label panorama, the recovered floor plan.

Run::

    .venv/bin/python examples/layout_from_labels.py

Draws an L-shaped room with :func:`layout.rooms.generate_room`, puts the
camera where it sees most of the floor, renders the analytic surface-label
panorama (:func:`layout.labelmap.render_room_labels`), corrupts a copy the
way estimated labels go wrong (:func:`layout.labelmap.perturb_labels`),
recovers the Manhattan floor polygon and wall height from both
(:func:`layout.roomgeom.estimate_room_geometry`), moves the corrupted room's
walls and ceiling height onto the creases of a panorama
(:func:`layout.wallsnap.snap_room`; here a grey image painted from the
analytic labels, :func:`layout.labelmap.shade_labels`, stands in for the photo)
and saves a figure with the
label maps and the recovered polygons over the true one to
``out/examples/layout_from_labels.png``. It also prints the corners in the
HorizonNet-style ``corners_px`` form.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from layout.corners import polygon_to_corners_px  # noqa: E402
from layout.labelmap import perturb_labels, render_room_labels, sample_camera_xy, shade_labels  # noqa: E402
from layout.metrics import score_layout  # noqa: E402
from layout.roomgeom import estimate_room_geometry  # noqa: E402
from layout.rooms import generate_room  # noqa: E402
from layout.wallsnap import snap_room  # noqa: E402

CAMERA_HEIGHT = 1.6
WIDTH = 1024
# surface label colours: unknown, floor, ceiling, wall x, wall y, object
COLOURS = np.array([[40, 40, 40], [196, 160, 110], [235, 235, 235], [70, 130, 200], [220, 110, 80], [250, 220, 40]],
                   np.uint8)


def main() -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(6)
    room = generate_room(rng, template="L")
    cam = sample_camera_xy(room.floor, rng, margin=0.5, candidates=8)
    truth = room.floor - cam  # the world frame has its origin below the camera
    labels = render_room_labels(room.floor, room.ceiling_z, cam, CAMERA_HEIGHT, WIDTH)
    noisy, mask = perturb_labels(labels, rng)

    clean = estimate_room_geometry(labels, CAMERA_HEIGHT)
    rough = estimate_room_geometry(noisy, CAMERA_HEIGHT, object_mask=mask)
    for name, geo in (("ground-truth labels", clean), ("corrupted labels", rough)):
        s = score_layout(geo.floor, geo.ceiling_z, truth, room.ceiling_z, CAMERA_HEIGHT, WIDTH)
        print(f"{name}: {geo.n_corners} corners (true {len(truth)}), wall height {geo.ceiling_z:.3f} m "
              f"(true {room.ceiling_z:.3f}), 3D IoU {s.iou_3d:.3f}, 2D IoU {s.iou_2d:.3f}, "
              f"corner error {100 * s.corner_error.mean:.1f} cm, {1000 * geo.timing_s:.0f} ms"
              + (f", uncertain: {'; '.join(geo.reasons)}" if geo.uncertain else ""))
    # the walls onto the image's creases: a grey panorama painted from the analytic labels (one grey level per
    # label, some noise) stands in for the photo
    snapped = snap_room(shade_labels(labels, rng), rough.floor, rough.ceiling_z, CAMERA_HEIGHT, object_mask=mask)
    s = score_layout(snapped.floor, snapped.ceiling_z, truth, room.ceiling_z, CAMERA_HEIGHT, WIDTH)
    moved = snapped.walls.moved
    print(f"corrupted labels, walls snapped to the image: {int(moved.sum())} of {len(moved)} walls moved, "
          f"wall height {snapped.ceiling_z:.3f} m, 3D IoU {s.iou_3d:.3f}, 2D IoU {s.iou_2d:.3f}")
    print("corners_px [u_ceiling, v_ceiling, u_floor, v_floor]:")
    print(np.round(polygon_to_corners_px(clean.floor, clean.ceiling_z, CAMERA_HEIGHT, WIDTH), 1))

    fig = plt.figure(figsize=(13, 7.5))
    grid = fig.add_gridspec(2, 2, width_ratios=[1.6, 1.0])
    for row, (lab, title) in enumerate(((labels, "analytic surface labels"),
                                        (noisy, "corrupted labels (objects masked)"))):
        ax = fig.add_subplot(grid[row, 0])
        ax.imshow(COLOURS[lab])
        ax.set_title(title)
        geo = clean if row == 0 else rough
        c = polygon_to_corners_px(geo.floor, geo.ceiling_z, CAMERA_HEIGHT, WIDTH)
        ax.plot(c[:, 0], c[:, 1], "k+", ms=10, mew=2)
        ax.plot(c[:, 2], c[:, 3], "k+", ms=10, mew=2)
        ax.set_xticks([])
        ax.set_yticks([])
    ax = fig.add_subplot(grid[:, 1])
    t = np.vstack([truth, truth[:1]])
    ax.fill(t[:, 0], t[:, 1], color="0.85", label=f"true floor ({len(truth)} corners)")
    for floor, style, name in ((clean.floor, "b-o", "from ground-truth labels"),
                               (rough.floor, "r--s", "from corrupted labels"),
                               (snapped.floor, "g-.^", "corrupted, walls snapped to the image")):
        p = np.vstack([floor, floor[:1]])
        ax.plot(p[:, 0], p[:, 1], style, ms=4, label=f"{name} ({len(floor)} corners)")
    ax.plot(0, 0, "k*", ms=12, label="camera")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize=8)
    ax.set_title("floor plan seen from above")
    fig.tight_layout()
    out = ROOT / "out" / "examples" / "layout_from_labels.png"
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    print(f"wrote {out.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
