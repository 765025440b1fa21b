"""panogeom example: cubemap, the paper's 6 layout views and a rotated panorama.

Usage::

    python examples/panogeom_views.py [PANO] [--out out/examples/panogeom]

Without PANO it renders a procedural test panorama
(:func:`panogeom.transform.procedural_pano`). It writes into the output folder

- ``pano.png``: the input panorama,
- ``cubemap_dice.png``: the cubemap as a 3 x 4 cross (U above F; L F R B; D below F),
- ``view_0.png`` .. ``view_5.png``: the layout views (90 degree FOV every 60 degrees, Sec. 3.1 of the paper),
- ``rotated.png``: the panorama seen from a frame turned by yaw/pitch/roll (``--rotate-deg``),
- ``cubemap_back.png``: the cubemap resampled back into a panorama,

and prints one line per file.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from panogeom.cubemap import cubemap_to_equirect, equirect_to_cubemap  # noqa: E402
from panogeom.perspective import equirect_to_perspective, layout_views  # noqa: E402
from panogeom.rotation import ypr_to_matrix  # noqa: E402
from panogeom.transform import procedural_pano, rotate_pano  # noqa: E402


def _read(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        img = np.asarray(im.convert("RGB"))
    h, w = img.shape[:2]
    if w != 2 * h:
        raise ValueError(f"{path}: expected an equirectangular panorama with width == 2 * height, got {w}x{h}")
    return img


def _write(path: Path, img: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(img).save(path)
    print(f"wrote {path} ({img.shape[1]}x{img.shape[0]})")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("pano", nargs="?", type=Path, help="equirectangular image (W == 2H); procedural if omitted")
    ap.add_argument("--out", type=Path, default=Path("out/examples/panogeom"), help="output folder")
    ap.add_argument("--height", type=int, default=1024, help="height of the procedural panorama")
    ap.add_argument("--face-size", type=int, default=512, help="cubemap face size in pixels")
    ap.add_argument("--view-size", type=int, default=512, help="layout view size in pixels")
    ap.add_argument("--rotate-deg", type=float, nargs=3, default=(40.0, 15.0, 5.0), metavar=("YAW", "PITCH", "ROLL"),
                    help="rotation of the output frame, degrees")
    args = ap.parse_args(argv)
    for name in ("height", "face_size", "view_size"):
        if getattr(args, name) <= 0:
            ap.error(f"--{name.replace('_', '-')}: expected a positive integer, got {getattr(args, name)}")
    try:
        pano = _read(args.pano) if args.pano else procedural_pano(args.height)
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    _write(out / "pano.png", pano)
    dice = equirect_to_cubemap(pano, args.face_size, "dice")
    _write(out / "cubemap_dice.png", dice)
    for k, view in enumerate(layout_views(args.view_size)):
        _write(out / f"view_{k}.png", equirect_to_perspective(pano, view))
    R = ypr_to_matrix(*np.radians(args.rotate_deg))
    _write(out / "rotated.png", rotate_pano(pano, R))
    _write(out / "cubemap_back.png", cubemap_to_equirect(dice, pano.shape[0]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
