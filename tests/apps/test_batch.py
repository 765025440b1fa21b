"""``pano2cad batch``: inputs and names, failure isolation, resume, --force, atomic items, the Dask engine.

The end-to-end runs use 10 generated 256-pixel panoramas plus 2 bad files,
layout only (--no-objects), so the whole module stays around a minute.
"""

import csv
import json
import os
import shutil
import signal
from pathlib import Path

import pytest

from apps.batch import (BatchItem, discover_inputs, process_item, run_batch, unique_names)
from apps.cli import main
from apps.errors import UserError

RUN_FILES = {"scene.json", "scene.glb", "scene.obj", "scene.mtl", "floorplan.png", "floorplan.svg",
             "overlay.png", "labels.png", "label_ids.png", "report.html"}
FAST = ["--no-objects", "--size", "256", "--quiet"]


def _index(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _partials(out: Path) -> list[str]:
    return [p.name for p in out.iterdir() if ".partial-" in p.name]


@pytest.fixture(scope="module")
def panos(tmp_path_factory) -> Path:
    """10 generated panoramas and 2 bad files (not an image, a truncated PNG) in one folder."""
    root = tmp_path_factory.mktemp("batch")
    assert main(["synth", "--rooms", "10", "--seed", "5", "--size", "256", "--jobs", "1", "--quiet",
                 "--out", str(root / "rooms")]) == 0
    flat = root / "panos"
    flat.mkdir()
    for room in sorted((root / "rooms").glob("room-*")):
        shutil.copy(room / "pano.png", flat / f"{room.name}.png")
    (flat / "corrupt.jpg").write_bytes(b"this is not a JPEG")
    (flat / "truncated.png").write_bytes((root / "rooms" / "room-0000" / "pano.png").read_bytes()[:2000])
    return flat


@pytest.fixture(scope="module")
def local_run(panos, tmp_path_factory):
    """The local engine on the 12 files: (out folder, exit code, index rows right after the run)."""
    out = tmp_path_factory.mktemp("out-local")
    code = main(["batch", str(panos), "--out", str(out), *FAST])
    return out, code, _index(out / "index.csv")


# ----------------------------------------------------------------------------- inputs and names


def test_unique_names_disambiguates_duplicates_by_parent_folder():
    names = unique_names(["data/a/pano.png", "data/b/pano.png", "x/kitchen.jpg"])
    assert names == ["a-pano", "b-pano", "kitchen"]
    # deterministic: the same paths in another order give the same names
    assert unique_names(["x/kitchen.jpg", "data/b/pano.png", "data/a/pano.png"]) == ["kitchen", "b-pano", "a-pano"]


def test_unique_names_falls_back_to_a_hash_and_avoids_taken_names():
    names = unique_names(["r/pano.png", "r/pano.jpg", "r-pano.png"])
    assert len(set(names)) == 3 and names[2] == "r-pano"
    assert names[0].startswith("pano-") and names[1].startswith("pano-") and names[0] != names[1]


def test_unique_names_rejects_a_file_listed_twice():
    with pytest.raises(ValueError, match="more than once"):
        unique_names(["a/pano.png", "a/../a/pano.png"])


def test_discover_folder_glob_and_duplicate_stems(panos):
    items = discover_inputs(panos)
    assert [i.name for i in items] == ["corrupt", *(f"room-{k:04d}" for k in range(10)), "truncated"]
    rooms = panos.parent / "rooms"
    globbed = discover_inputs(str(rooms / "*" / "pano.png"))
    assert [i.name for i in globbed] == [f"room-{k:04d}-pano" for k in range(10)]
    assert all(i.path.is_file() for i in globbed)


def test_discover_csv_and_json_manifests(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "m.csv").write_text("path,camera_height,annotations\nsub/a.jpg,1.45,boxes.json\nb.png,,\n")
    items = discover_inputs(tmp_path / "m.csv")
    assert [(i.name, i.path, i.camera_height, i.annotations) for i in items] == [
        ("a", tmp_path / "sub" / "a.jpg", 1.45, tmp_path / "boxes.json"), ("b", tmp_path / "b.png", None, None)]
    (tmp_path / "m.json").write_text(json.dumps({"items": [{"path": "sub/a.jpg", "camera_height": 2.0}, "b.png"]}))
    items = discover_inputs(tmp_path / "m.json")
    assert [(i.name, i.camera_height) for i in items] == [("a", 2.0), ("b", None)]


@pytest.mark.parametrize("text, match", [
    ("file,camera_height\na.jpg,1.6\n", "'path' column"),
    ("path,camera_height\na.jpg,12\n", r"row 1: camera_height: expected metres in \[0.3, 5\]"),
    ("path,camera_height\na.jpg,tall\n", "row 1: camera_height: expected metres"),
    ("path\na.jpg\na.jpg\n", "more than once"),
    ("path\n", "lists no panoramas"),
])
def test_bad_manifest_is_a_user_error(tmp_path, text, match):
    (tmp_path / "m.csv").write_text(text)
    with pytest.raises(UserError, match=match):
        discover_inputs(tmp_path / "m.csv")


def test_nothing_to_process_is_a_user_error(tmp_path):
    with pytest.raises(UserError, match="holds no image files"):
        discover_inputs(tmp_path)
    with pytest.raises(UserError, match="matches no files"):
        discover_inputs(str(tmp_path / "*.jpg"))


@pytest.mark.parametrize("extra, message", [
    (["--scheduler", "tcp://127.0.0.1:1"], "--scheduler needs --engine dask"),
    (["--jobs", "-1"], "--jobs"),
    (["--engine", "spark"], "invalid choice"),
])
def test_cli_usage_errors_exit_2(tmp_path, capsys, extra, message):
    assert main(["batch", str(tmp_path / "nothing"), "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_cli_missing_inputs_exit_2(tmp_path, capsys):
    assert main(["batch", str(tmp_path / "nothing"), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "nothing is there" in capsys.readouterr().err


# ----------------------------------------------------------------------------- atomic items


def test_an_item_interrupted_while_writing_leaves_nothing(tmp_path, panos, monkeypatch):
    import apps.cmd_run
    import apps.pipeline

    class Boom(Exception):
        pass

    def half_write(result, out, image_name):
        (out / "scene.glb").write_bytes(b"half")
        raise Boom("disk full")

    monkeypatch.setattr(apps.pipeline, "run_pipeline", lambda image, options, progress: object())
    monkeypatch.setattr(apps.cmd_run, "write_outputs", half_write)
    item = BatchItem("room-0001", panos / "room-0001.png")
    res = process_item(item, tmp_path, apps.pipeline.RunOptions(objects=False), size=256)
    assert (res.status, res.exit_code, res.error) == ("failed", 1, "Boom: disk full")
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- local engine end to end


def test_local_batch_isolates_failures(local_run, panos):
    out, code, rows = local_run
    assert code == 3
    assert [r["name"] for r in rows] == ["corrupt", *(f"room-{k:04d}" for k in range(10)), "truncated"]
    ok = [r for r in rows if r["status"] == "ok"]
    bad = {r["name"]: r for r in rows if r["status"] == "failed"}
    assert len(ok) == 10 and set(bad) == {"corrupt", "truncated"}
    for name, r in bad.items():
        assert r["exit_code"] == "2" and str(panos / Path(r["file"]).name) in r["error"]
        assert not (out / name).exists()
    for r in ok:
        assert {p.name for p in (out / r["name"]).iterdir()} == RUN_FILES
        scene = json.loads((out / r["name"] / "scene.json").read_text())
        assert scene["image"]["file"] == f"{r['name']}.png"
        assert int(r["corners"]) == len(scene["room"]["floor"]) >= 4
        assert float(r["wall_height_m"]) == pytest.approx(scene["room"]["ceiling_z"] - scene["room"]["floor_z"],
                                                          abs=1e-4)
        assert float(r["area_m2"]) > 0 and r["n_chair"] == "0" and r["error"] == ""
    assert _partials(out) == []


def test_rerun_skips_complete_items(local_run, panos):
    """A rerun leaves complete items' files alone and lists them as skipped (only the corrupt input runs again)."""
    out, _, first = local_run
    stamps = {p: p.stat().st_mtime_ns for p in out.glob("*/scene.json")}
    code = main(["batch", str(panos), "--out", str(out), *FAST])
    rows = _index(out / "index.csv")
    assert code == 3
    assert sum(r["status"] == "skipped" for r in rows) == 10
    assert {p: p.stat().st_mtime_ns for p in out.glob("*/scene.json")} == stamps
    strip = ("status", "seconds")
    assert [{k: v for k, v in r.items() if k not in strip} for r in rows] == \
        [{k: v for k, v in r.items() if k not in strip} for r in first]


def test_force_recomputes_with_manifest_options(local_run, panos, tmp_path):
    out, _, _ = local_run
    shutil.copytree(out / "room-0003", tmp_path / "room-0003")
    before = json.loads((tmp_path / "room-0003" / "scene.json").read_text())
    (tmp_path / "m.csv").write_text(f"path,camera_height\n{panos / 'room-0003.png'},2.2\n")
    assert main(["batch", str(tmp_path / "m.csv"), "--out", str(tmp_path), *FAST]) == 0
    assert _index(tmp_path / "index.csv")[0]["status"] == "skipped"
    assert json.loads((tmp_path / "room-0003" / "scene.json").read_text()) == before
    assert main(["batch", str(tmp_path / "m.csv"), "--out", str(tmp_path), "--force", *FAST]) == 0
    row = _index(tmp_path / "index.csv")[0]
    after = json.loads((tmp_path / "room-0003" / "scene.json").read_text())
    assert row["status"] == "ok" and after["camera"]["height_m"] == pytest.approx(2.2)
    assert before["camera"]["height_m"] == pytest.approx(1.6)
    assert {p.name for p in (tmp_path / "room-0003").iterdir()} == RUN_FILES and _partials(tmp_path) == []


def test_parquet_index_matches_csv(local_run):
    pq = pytest.importorskip("pyarrow.parquet")
    out, _, rows = local_run
    table = pq.read_table(out / "index.parquet").to_pylist()
    assert [r["name"] for r in table] == [r["name"] for r in rows]


# ----------------------------------------------------------------------------- Dask engine


def test_dask_survives_a_killed_worker_and_matches_local(local_run, panos, tmp_path):
    pytest.importorskip("distributed")
    from distributed import Client, LocalCluster

    from apps.pipeline import RunOptions

    _, _, local_rows = local_run
    killed: dict = {}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address="127.0.0.1:0") as cluster, Client(cluster) as client:

        def kill_a_busy_worker(result):
            if killed:
                return
            busy = [w for w, keys in client.processing().items() if keys]
            if not busy:
                return
            pids = client.run(os.getpid)
            killed["worker"], killed["tasks"] = busy[0], len(client.processing()[busy[0]])
            os.kill(pids[busy[0]], signal.SIGKILL)

        res = run_batch(discover_inputs(panos), tmp_path, RunOptions(objects=False), size=256, engine="dask",
                        scheduler=cluster.scheduler_address, on_result=kill_a_busy_worker)
    assert killed and killed["tasks"] >= 1, "no worker was killed while it had work"
    rows = _index(tmp_path / "index.csv")
    assert [r["name"] for r in rows] == [r["name"] for r in local_rows]  # every item exactly once
    assert len(res.failed) == 2 and _partials(tmp_path) == []
    strip = ("seconds",)
    assert [{k: v for k, v in r.items() if k not in strip} for r in rows] == \
        [{k: v for k, v in r.items() if k not in strip} for r in local_rows]
