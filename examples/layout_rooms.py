"""Top view of six synthetic rooms with furniture and camera.

Generates rooms with :func:`layout.rooms.generate_room`, typical bedroom
contents with :func:`layout.placement.sample_class_counts`, places them with
:func:`layout.placement.place_objects` (context prior sampling) and saves
``out/examples/rooms_topview.png``: floor polygon, footprints with an arrow
along each object's front, the camera (cross) and its 0.5 m wall clearance.

Run: ``.venv/bin/python examples/layout_rooms.py [--seed 0] [--out out/examples]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from layout.placement import ObjectSpec, place_objects, sample_class_counts
from layout.rooms import TEMPLATE_NAMES, generate_room

# typical footprints (length along the front, width, height) in metres; a
# real caller takes them from the model library
SIZES: dict[str, tuple[float, float, float]] = {
    "bed": (2.05, 1.6, 0.55),
    "chair": (0.5, 0.5, 0.9),
    "tv": (0.25, 1.1, 0.7),
    "plant": (0.4, 0.4, 0.9),
    "sofa": (0.9, 2.0, 0.85),
    "table": (0.8, 1.2, 0.75),
    "nightstand": (0.4, 0.45, 0.55),
    "wardrobe": (0.6, 1.5, 2.0),
}
COLORS = {
    "bed": "tab:blue",
    "chair": "tab:orange",
    "tv": "black",
    "plant": "tab:green",
    "sofa": "tab:purple",
    "table": "tab:brown",
    "nightstand": "tab:pink",
    "wardrobe": "tab:gray",
}


def bedroom_specs(rng: np.random.Generator) -> list[ObjectSpec]:
    counts = sample_class_counts(rng)
    return [
        ObjectSpec(name, SIZES[name], f"{name}-{i}", symmetric=(name == "plant"))
        for name, n in counts.items()
        for i in range(n)
    ]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path("out/examples"))
    args = ap.parse_args(argv)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    rng = np.random.default_rng(args.seed)
    templates = ("L", "T", "U", "plus", "notched", "corridor")
    assert set(templates) <= set(TEMPLATE_NAMES)
    fig, axes = plt.subplots(2, 3, figsize=(15, 10))
    for ax, name in zip(axes.ravel(), templates):
        room = generate_room(rng, template=name)
        pl = place_objects(room, bedroom_specs(rng), rng)
        ax.add_patch(Polygon(room.floor, closed=True, fill=True, fc="#f4f0e8", ec="k", lw=2))
        ax.add_patch(Polygon(room.template_floor, closed=True, fill=False, ec="0.6", ls=":", lw=1))
        for o in pl.objects:
            fp = o.footprint
            ax.add_patch(Polygon(fp, closed=True, fc=COLORS.get(o.class_name, "c"), alpha=0.5, ec="k", lw=0.8))
            cx, cy = o.center[:2]
            if not o.symmetric:
                L = 0.5 * o.size[0] + 0.25
                ax.annotate(
                    "",
                    xy=(cx + L * np.cos(o.yaw), cy + L * np.sin(o.yaw)),
                    xytext=(cx, cy),
                    arrowprops=dict(arrowstyle="->", lw=1.2, color="k"),
                )
            ax.text(cx, cy, o.class_name, fontsize=7, ha="center", va="center")
        cam = pl.camera_xy
        ax.plot(cam[0], cam[1], "rx", ms=10, mew=2)
        ax.add_patch(Circle(cam, 0.3, fill=False, ec="r", ls="--", lw=0.8))
        ax.set_title(
            f"{room.template}: {room.n_corners} corners, h={room.ceiling_z:.2f} m, cam {pl.camera_height:.2f} m\n"
            f"E={pl.energy:.2f}, dropped {len(pl.dropped)}",
            fontsize=9,
        )
        ax.set_aspect("equal")
        pad = 0.5
        ax.set_xlim(room.floor[:, 0].min() - pad, room.floor[:, 0].max() + pad)
        ax.set_ylim(room.floor[:, 1].min() - pad, room.floor[:, 1].max() + pad)
        ax.grid(True, lw=0.3)
    fig.suptitle("layout.rooms + layout.placement: floor (solid), template before offsets (dotted), camera (x)")
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "rooms_topview.png"
    fig.savefig(path, dpi=80)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
