"""Time the library pose-render cache and the pose CRF (posecrf, issue 8).

Run:  PYOPENGL_PLATFORM=egl .venv/bin/python benchmarks/bench_pose_cache.py [--workers 2] [--write-docs]

1. First build: every built-in model rendered at the 360 poses of the default
   grid with pyrender (EGL, headless) and described by HOG, into an empty
   temporary cache folder (``posecrf.cache.library_renders``).
2. Second call in the same process (everything read from the cache).
3. Second call in a fresh Python process: imports, building the procedural
   library, hashing the models and reading the cache, as a user's next run
   pays it (the time of the ``library_renders`` call alone is given too).
4. Pose CRF per class: ``estimate_poses`` on a scene of 3 crops of one class
   (library renders at random off-grid poses, with masks), median of 5 runs.

With ``--write-docs`` the section "## Pose renders and pose CRF" of
docs/BENCHMARKS.md is replaced (only that section).
"""

from __future__ import annotations

import sys as _sys
_sys.path.insert(0, str(__import__("pathlib").Path(__file__).resolve().parent))
from _docs import replace_section  # noqa: E402

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

DOCS = ROOT / "docs" / "BENCHMARKS.md"
SECTION = "## Pose renders and pose CRF"

_SECOND = """
import json, sys, time
t0 = time.perf_counter()
from posecrf.cache import library_renders
from posecrf.library import builtin_library
t1 = time.perf_counter()
lib = builtin_library()
t2 = time.perf_counter()
r = library_renders(lib, cache_dir=sys.argv[1], workers=1)
t3 = time.perf_counter()
print(json.dumps({"total": t3 - t0, "imports": t1 - t0, "library": t2 - t1, "call": t3 - t2,
                  "built": len(r.built), "loaded": len(r.loaded)}))
"""


def run(workers: int | None) -> dict:
    from posecrf.cache import library_renders
    from posecrf.library import builtin_library
    from posecrf.pose import estimate_poses
    from posecrf.render import PoseRenderer
    from posecrf.retrieval import RenderIndex

    lib = builtin_library()
    out: dict = {"models": len(lib), "workers": workers or os.cpu_count()}
    with tempfile.TemporaryDirectory() as d:
        c0, t0 = time.process_time(), time.perf_counter()
        first = library_renders(lib, cache_dir=d, workers=workers)
        out["first_s"] = time.perf_counter() - t0
        out["first_parent_cpu_s"] = time.process_time() - c0
        out["renders"] = len(first.models) * first.grid.size
        out["failures"] = [f.model_id for f in first.failures]
        out["cache_mb"] = sum(p.stat().st_size for p in Path(d).iterdir()) / 1e6
        out["settings"] = first.settings.key()
        t0 = time.perf_counter()
        second = library_renders(lib, cache_dir=d, workers=workers)
        out["second_same_process_s"] = time.perf_counter() - t0
        assert not second.built and len(second.loaded) == len(first.models)
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        proc = subprocess.run([sys.executable, "-c", _SECOND, d], capture_output=True, text=True, env=env, check=True)
        out["second_fresh_process"] = json.loads(proc.stdout)

        rng = np.random.default_rng(7)
        crf: dict = {}
        with PoseRenderer(first.settings) as r:
            for cls in ("bed", "chair", "tv", "plant"):
                index = RenderIndex.from_renders(first, cls)
                models = lib.by_class(cls)
                crops, masks = [], []
                for _ in range(3):
                    m = models[int(rng.integers(len(models)))]
                    rgb, mask = r.render(m, float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(0.1, 0.7)))
                    crops.append(rgb)
                    masks.append(mask)
                walls, cpus = [], []
                for _ in range(5):
                    c0, t0 = time.process_time(), time.perf_counter()
                    res = estimate_poses(first, cls, crops, masks, index=index)
                    walls.append(time.perf_counter() - t0)
                    cpus.append(time.process_time() - c0)
                crf[cls] = {"renders": index.n_renders, "wall_s": float(np.median(walls)), "cpu_s": float(np.median(cpus)),
                            "iterations": res.iterations}
        out["crf"] = crf
    out["load_average"] = os.getloadavg()[0]
    out["cpus"] = os.cpu_count()
    out["python"] = platform.python_version()
    return out


def section(r: dict) -> str:
    fresh = r["second_fresh_process"]
    lines = [
        SECTION,
        "",
        "`PYOPENGL_PLATFORM=egl .venv/bin/python benchmarks/bench_pose_cache.py --write-docs` (this section is "
        f"written by the script). Built-in library: {r['models']} models x 360 poses = {r['renders']} renders "
        f"(pyrender on Mesa EGL, no GPU) + HOG descriptors, {r['workers']} render processes, into an empty "
        f"temporary cache folder ({r['cache_mb']:.1f} MB of .npz files). Failed models: "
        f"{', '.join(r['failures']) if r['failures'] else 'none'}.",
        "",
        "| step | seconds |",
        "|---|---:|",
        f"| first build (render + describe + write all) | {r['first_s']:.1f} |",
        f"| second call, same process | {r['second_same_process_s']:.2f} |",
        f"| second call, fresh process: total | {fresh['total']:.2f} |",
        f"| ... of which imports | {fresh['imports']:.2f} |",
        f"| ... building the procedural library | {fresh['library']:.2f} |",
        f"| ... `library_renders` (hash, read {fresh['loaded']} files) | {fresh['call']:.2f} |",
        "",
        "Pose CRF (`estimate_poses`, 3 crops of a class with masks, K = 6, TRW-S up to 100 iterations, "
        "E_o of every model and pose; median of 5 runs):",
        "",
        "| class | renders searched | wall s | CPU s | TRW-S iterations |",
        "|---|---:|---:|---:|---:|",
    ]
    for cls, c in r["crf"].items():
        lines.append(f"| {cls} | {c['renders']} | {c['wall_s']:.3f} | {c['cpu_s']:.3f} | {c['iterations']} |")
    lines += [
        "",
        f"Machine: {r['cpus']} CPUs, Python {r['python']}, load average (1 min) at the end {r['load_average']:.1f} "
        "(the machine is shared; wall times above grow with the load).",
        "",
    ]
    return "\n".join(lines)


def update_docs(text: str) -> None:
    """Replace our section of docs/BENCHMARKS.md (benchmarks/_docs.py)."""
    replace_section(DOCS, text, SECTION)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    ap.add_argument("--workers", type=int, default=None, help="render processes (default: CPU count)")
    ap.add_argument("--write-docs", action="store_true", help=f"replace the section {SECTION!r} of docs/BENCHMARKS.md")
    args = ap.parse_args(argv)
    result = run(args.workers)
    text = section(result)
    print(text)
    if args.write_docs:
        update_docs(text)
        print(f"wrote section {SECTION!r} of {DOCS}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
