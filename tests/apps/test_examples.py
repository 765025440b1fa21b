"""Every example script runs (in a temporary output folder where it takes one)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def _args(name: str, tmp: Path) -> list[str]:
    if name == "detect_tiles.py":
        from PIL import Image
        import numpy as np

        pano = tmp / "pano.png"
        Image.fromarray(np.random.default_rng(0).integers(0, 255, (128, 256, 3), dtype=np.uint8)).save(pano)
        return [str(pano), "--detector", "annotations:" + str(_annotations(tmp)), "--out", str(tmp)]
    if name == "synth_rooms.py":
        return ["--out", str(tmp / "synth.png")]
    if name == "full_pipeline.py":
        return ["--out", str(tmp), "--size", "512"]
    return []


def _annotations(tmp: Path) -> Path:
    import json

    p = tmp / "boxes.json"
    p.write_text(json.dumps({"image": {"width": 256, "height": 128},
                             "objects": [{"class": "chair", "bbox_pano": [100, 60, 120, 90]}]}))
    return p


def test_examples_exist():
    names = {p.name for p in EXAMPLES}
    assert {"full_pipeline.py", "posecrf_trws_toy.py", "panogeom_views.py", "layout_from_labels.py",
            "detect_tiles.py", "panogeom_vanishing.py"} <= names


@pytest.mark.parametrize("script", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_example_runs(script, tmp_path):
    env = dict(os.environ, PYOPENGL_PLATFORM="egl", MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, str(script), *_args(script.name, tmp_path)], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-3000:]
