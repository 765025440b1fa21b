"""Four generated rooms like the paper's Fig. 7: panorama, surface labels and a top view with objects.

Usage: python examples/synth_rooms.py [--seed 0] [--out docs/images/synth_examples.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from apps.export.colors import class_color
    from apps.export.labels import colorize_labels
    from apps.synth import make_room
    from layout.polygon import oriented_rectangles

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default="docs/images/synth_examples.png")
    args = ap.parse_args()
    rooms = [make_room(i, args.seed, 1024) for i in range(4)]
    fig, axes = plt.subplots(4, 3, figsize=(15, 13), gridspec_kw={"width_ratios": [2, 2, 1]})
    for row, r in zip(axes, rooms):
        gt = r.gt
        row[0].imshow(r.rgb)
        row[0].set_title(f"{r.name}: {gt['template']}, {gt['n_corners']} corners", fontsize=9)
        row[1].imshow(colorize_labels(r.labels))
        row[1].set_title("surface labels (floor, ceiling, wall x, wall y, object)", fontsize=9)
        floor = np.array(gt["room"]["floor"])
        row[2].fill(*floor.T, color="#f2ece0", edgecolor="k", lw=2)
        for o in gt["objects"]:
            rect = oriented_rectangles(np.array(o["center"][:2]), np.deg2rad(o["yaw_deg"]), np.array(o["size"][:2]))
            c = np.asarray(class_color(o["class"]), float) / 255.0
            row[2].fill(*rect.T, color=c, alpha=0.7)
            cx, cy = o["center"][:2]
            yaw = np.deg2rad(o["yaw_deg"])
            if o["class"] != "plant":
                row[2].arrow(cx, cy, 0.4 * np.cos(yaw), 0.4 * np.sin(yaw), width=0.03, color="k")
            row[2].text(cx, cy, o["class"], fontsize=6, ha="center")
        row[2].plot(0, 0, "rx")
        row[2].set_aspect("equal")
        row[2].set_title(f"top view, wall {gt['room']['ceiling_z']:.2f} m, camera {gt['camera_height_m']:.2f} m",
                         fontsize=9)
        for a in row[:2]:
            a.axis("off")
    fig.tight_layout()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=80)
    print(out)


if __name__ == "__main__":
    main()
