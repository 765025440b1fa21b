"""benchmarks/sampler_replay.py: a capture replayed without changes gives the pipeline's scene; an override changes
what the sampler does."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from apps.cli import main as cli

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "sampler_replay.py"
_spec = importlib.util.spec_from_file_location("benchmarks_sampler_replay", _PATH)
sr = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = sr
_spec.loader.exec_module(sr)


@pytest.fixture(scope="module")
def captured(tmp_path_factory):
    root = tmp_path_factory.mktemp("replay")
    data, run = root / "data", root / "run"
    assert cli(["synth", "--rooms", "1", "--seed", "3", "--size", "512", "--out", str(data), "--quiet"]) == 0
    assert sr.main(["capture", "--data", str(data), "--out", str(run), "--samples", "60", "--size", "512",
                    "--jobs", "1", "--quiet"]) == 0
    return data, run


def test_a_replay_without_changes_gives_the_captured_scene(captured, capsys):
    from apps.evaluation import score_room

    data, run = captured
    room = next(p for p in run.iterdir() if (p / "capture.pkl").is_file())
    scores, rows = sr.replay([data], [run], {}, [None], {})
    assert len(scores) == 1 and rows
    gt = json.loads((data / room.name / "gt.json").read_text())
    direct = score_room(room.name, json.loads((room / "scene.json").read_text()), gt)
    want = sorted((c, round(p, 9)) for c, e in direct.objects.items() for p in e["pos"])
    assert sorted((r[2], round(r[3], 9)) for r in rows) == want
    assert scores[0].layout["iou_3d"] == pytest.approx(direct.layout["iou_3d"])
    assert sr.main(["replay", str(data), str(run), "--json", str(run / "rows.json")]) == 0
    printed = capsys.readouterr().out
    assert "1 room runs" in printed and "3D IoU" in printed
    assert len(json.loads((run / "rows.json").read_text())) == len(rows)


def test_an_override_reaches_the_sampler(captured):
    data, run = captured
    _, base = sr.replay([data], [run], {}, [None], {})
    # the scale held at a 3.4 m wall height: a larger room, every object elsewhere
    scores, other = sr.replay([data], [run], {"wall_height_range": (3.4, 3.4), "initial_wall_height": 3.4},
                              [None], {})
    assert scores[0].layout["wall_height_err"] > 0.3
    assert [r[3] for r in base] != [r[3] for r in other]


def test_a_hook_sees_every_call(captured):
    data, run = captured
    seen = []

    def before(args, kwargs, room):
        seen.append((room, kwargs["config"].n_samples))
        return args, kwargs

    sr.replay([data], [run], {}, [1, 2], {"before": before})
    assert len(seen) == 2 and seen[0][1] == 60


def test_mismatched_folders_are_a_usage_error(tmp_path):
    with pytest.raises(SystemExit) as e:
        sr.main(["replay", "a,b", str(tmp_path)])
    assert e.value.code == 2
