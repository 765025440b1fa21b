"""report.html: a self-contained page (no request leaves the file) with a working three.js 3D view.

The browser tests drive headless Chromium (Debian packages ``chromium`` and
``chromium-driver``) through its command line: ``--dump-dom`` reads the
status the page writes into ``<body data-...>``, ``--screenshot`` takes the
picture. Every http(s) request the browser makes is sent to a loopback proxy
that counts connections, and host names resolve to nothing, so nothing can
leave the machine; they are skipped when Chromium is not installed.
"""

import base64
import hashlib
import html
import io
import json
import re
import shutil
import socket
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from apps.atomic import write_json
from apps.cli import main
from apps.export import export_all
from apps.report import (CSP, INDEX_FILE, REPORT_FILE, THREE_VERSION, build_report, external_references,
                         read_inputs, write_batch_index, write_report)
from layout.scene import Scene, SceneObject
from panogeom.project import world_box_to_pano

W, H = 512, 256
ASSETS = Path(__file__).resolve().parents[2] / "apps" / "report_assets"
# Debian's /usr/bin/chromium is a shell wrapper that adds flags (--enable-remote-extensions, --load-extension);
# the binary behind it is started directly.
CHROMIUM = next((p for p in ["/usr/lib/chromium/chromium"] + [shutil.which(n) for n in ("chromium", "chromium-browser")]
                 if p and Path(p).is_file()), None)
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None, reason="Chromium is not installed (apt-get install -y chromium chromium-driver)")


def _scene(objects: bool = True) -> Scene:
    objs = ()
    if objects:
        specs = [("bed-0", "bed", [-0.8, -0.6], [2.0, 1.6, 0.5], 0.0),
                 ("tv-0", "tv", [2.3, 0.8], [0.2, 1.0, 0.6], np.pi)]
        objs = tuple(SceneObject(i, c, [x, y, 0.5 * s[2]], s, yaw, None, 0.8,
                                 world_box_to_pano([x, y, 0.5 * s[2]], s, yaw, W, H, 1.5, None).extent)
                     for i, c, (x, y), s, yaw in specs)
    return Scene([[-2.0, -1.5], [2.6, -1.5], [2.6, 2.0], [-2.0, 2.0]], 2.5, 1.5, objs,
                 image_file="pano.png", image_width=W, image_height=H,
                 timing={"rectify": 1.25, "surfaces": 3.5, "total": 5.0})


def make_run_dir(path: Path, objects: bool = True) -> Path:
    """An output folder like ``pano2cad run`` writes (without report.html)."""
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    image = np.clip(np.linspace(40, 220, H)[:, None, None] + rng.normal(0, 12, (H, W, 3)), 0, 255).astype(np.uint8)
    labels = np.zeros((H, W), np.uint8)
    labels[: H // 3], labels[H // 3: 2 * H // 3], labels[2 * H // 3:] = 2, 3, 1
    scene = _scene(objects)
    export_all(scene, path, image=image, labels=labels)
    doc = scene.to_json_dict()
    doc["warnings"] = ["a test warning <with markup>"]
    write_json(path / "scene.json", doc)
    return path


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    return make_run_dir(tmp_path_factory.mktemp("report") / "run")


# ---------------------------------------------------------------- the page

def test_report_has_every_section_and_nothing_external(run_dir):
    path = write_report(run_dir)
    assert path == run_dir / REPORT_FILE
    page = path.read_text(encoding="utf-8")
    assert external_references(page) == []
    assert f'content="{CSP}"' in page and "default-src 'none'" in CSP
    for section in ("panorama", "plan", "objects", "timing", "view3d"):
        assert f'<section id="{section}">' in page
    assert page.count("data:image/png;base64,") == 2  # overlay and labels
    assert '<svg class="layer vec"' in page and "<?xml" not in page  # floor plan inlined without its prolog
    assert 'id="glb-data"' in page and 'data-view3d="pending"' in page
    # the objects table, with unknown models as a dash
    assert "<td>bed-0</td><td>bed</td><td>-0.80, -0.60, 0.25</td><td>0.0</td><td>2.00, 1.60, 0.50</td>" in page
    assert "<td>tv-0</td><td>tv</td>" in page and "<td>180.0</td>" in page
    # timings (total last) and escaped warnings
    assert page.index("<td>rectify</td>") < page.index("<td>surfaces</td>") < page.index("<td>total</td>")
    assert "a test warning &lt;with markup&gt;" in page
    # the vendored three.js licence and version are in the page
    assert "The MIT License" in page and f"r{THREE_VERSION}" in page
    # the GLB is embedded byte for byte
    glb = re.search(r'id="glb-data">([A-Za-z0-9+/=]+)<', page).group(1)
    assert base64.b64decode(glb) == (run_dir / "scene.glb").read_bytes()


def test_vector_layers_follow_the_objects_boxes(run_dir):
    page = build_report(run_dir)
    doc = json.loads((run_dir / "scene.json").read_text())
    u0, v0, u1, v1 = doc["objects"][0]["bbox_pano"]
    assert u0 <= u1
    assert f'<path class="box" d="M{u0:.1f},{v0:.1f} L{u1:.1f},{v0:.1f}' in page
    assert re.search(r'<path class="layout" d="M[0-9.]+,[0-9.]+ L', page)
    for layer in ("overlay", "labels", "layout", "boxes"):
        assert f'data-layer="{layer}"' in page


def test_external_references_are_found():
    assert external_references('<img src="https://cdn.example/x.png"><a href="//cdn.example">x</a>') == [
        'src="https://', 'href="//']
    svg = '<svg xmlns="http://www.w3.org/2000/svg"><img src="data:image/png;base64,AA"></svg>'
    assert external_references(svg) == []


def test_report_without_objects_says_so(tmp_path):
    d = make_run_dir(tmp_path / "run", objects=False)
    page = build_report(d)
    assert "No objects in this scene." in page and '<table class="objects">' not in page
    assert 'data-view3d="pending"' in page


def test_failed_run_report_says_what_is_missing(tmp_path):
    d = make_run_dir(tmp_path / "run")
    (d / "scene.json").unlink()
    (d / "scene.glb").unlink()
    inputs = read_inputs(d)
    assert inputs.scene is None and "scene.json" not in inputs.files
    page = write_report(d).read_text()
    assert "scene.json is missing: the run did not finish" in page
    assert "scene.glb is missing: no 3D view" in page
    assert 'data-view3d="missing"' in page and 'id="glb-data"' not in page
    assert "Unknown: scene.json is missing." in page
    assert "data:image/png;base64," in page  # the pictures that exist are still shown


def test_unreadable_scene_json_is_reported(tmp_path):
    d = make_run_dir(tmp_path / "run")
    (d / "scene.json").write_text('{"schema": "other"}')
    inputs = read_inputs(d)
    assert inputs.scene is None
    assert any("scene.json could not be read" in m and "other" in m for m in inputs.missing)


def test_empty_and_absent_folders(tmp_path):
    page = build_report(tmp_path)
    for name in ("scene.json", "scene.glb", "floorplan.svg", "overlay.png"):
        assert f"{name} is missing" in page
    with pytest.raises(ValueError, match="expected an existing output folder"):
        build_report(tmp_path / "nope")


def test_vendored_three_matches_its_checksums_and_version():
    three = ASSETS / "three"
    sums = dict(reversed(line.split()) for line in (three / "SHA256SUMS").read_text().splitlines())
    assert set(sums) == {"three.module.min.js", "OrbitControls.js", "GLTFLoader.js", "BufferGeometryUtils.js",
                         "LICENSE"}
    for name, digest in sums.items():
        assert hashlib.sha256((three / name).read_bytes()).hexdigest() == digest, name
    assert f'const t="{THREE_VERSION.split(".")[1]}"' in (three / "three.module.min.js").read_text()[:400]


def test_cli_report_rebuilds_the_page(run_dir, tmp_path, capsys):
    (run_dir / REPORT_FILE).unlink(missing_ok=True)
    assert main(["report", str(run_dir)]) == 0
    assert capsys.readouterr().out.strip() == str(run_dir / REPORT_FILE)
    assert (run_dir / REPORT_FILE).read_text().startswith("<!DOCTYPE html>")
    assert main(["report", str(tmp_path / "nope")]) == 2
    assert "nope: expected an output folder" in capsys.readouterr().err
    (tmp_path / "file").write_text("x")
    assert main(["report", str(tmp_path / "file")]) == 2


def test_run_writes_the_report(tmp_path, monkeypatch, capsys):
    import apps.pipeline
    from apps.pipeline import PipelineResult

    pano = tmp_path / "pano.png"
    Image.fromarray(np.full((H, W, 3), 128, np.uint8)).save(pano)
    labels = np.ones((H, W), np.uint8)

    def fake_pipeline(image, options, prog):
        return PipelineResult(_scene(), image, labels, [], ("a warning",))

    monkeypatch.setattr(apps.pipeline, "run_pipeline", fake_pipeline)
    out = tmp_path / "out"
    assert main(["run", str(pano), "--out", str(out), "--size", str(W), "--quiet"]) == 0
    assert str(out / REPORT_FILE) in capsys.readouterr().out.split()
    page = (out / REPORT_FILE).read_text()
    assert "<td>bed-0</td>" in page and "a warning" in page and 'id="glb-data"' in page


def test_batch_index_links_every_report_with_a_thumbnail(run_dir, tmp_path):
    batch = tmp_path / "batch"
    shutil.copytree(run_dir, batch / "room-a")
    write_report(batch / "room-a")
    failed = batch / "room-b"
    failed.mkdir()
    (failed / "overlay.png").write_bytes((run_dir / "overlay.png").read_bytes())
    write_report(failed)
    (batch / ".room-c.partial").mkdir()
    (batch / ".room-c.partial" / "scene.json").write_text("{}")
    (batch / "notes").mkdir()  # not a run folder
    page = write_batch_index(batch).read_text()
    assert (batch / INDEX_FILE).is_file() and external_references(page) == []
    hrefs = re.findall(r'href="([^"]+)"', page)
    assert hrefs == ["room-a/report.html", "room-b/report.html"]
    assert all((batch / h).is_file() for h in hrefs)
    assert page.count("data:image/jpeg;base64,") == 2 and "(2 runs)" in page
    assert "4.6 x 3.5 m, 2 objects" in page and "failed: no scene.json" in page
    thumb = re.search(r'src="data:image/jpeg;base64,([^"]+)"', page).group(1)
    assert Image.open(io.BytesIO(base64.b64decode(thumb))).size == (320, 160)


# ---------------------------------------------------------------- in a real browser

class _CountingProxy:
    """A loopback TCP listener used as Chromium's proxy: every request the browser sends out lands here."""

    def __init__(self):
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.sock.settimeout(0.2)
        self.port = self.sock.getsockname()[1]
        self.requests: list[bytes] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        while not self._stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except OSError:
                continue
            with conn:
                conn.settimeout(1.0)
                data = b""
                try:  # up to the end of the request line, which may come in several segments
                    while b"\r\n" not in data and len(data) < 8192:
                        chunk = conn.recv(4096)
                        if not chunk:
                            break
                        data += chunk
                except OSError:
                    pass
                # a connection that sends nothing (Chromium opens spare sockets to its proxy) carries no request
                if data:
                    self.requests.append(data)

    def close(self):
        self._stop.set()
        self._thread.join(2)
        self.sock.close()


#: Chromium's own background services, which it contacts whatever the flags (extension/component update
#: checks, account and network-time services); never anything a page asks for.
BROWSER_SERVICE_HOSTS = {"update.googleapis.com", "accounts.google.com", "clients2.google.com"}


def request_host(request: bytes) -> str:
    """Host of a proxy request line: ``GET http://host/...`` or ``CONNECT host:443``."""
    words = request.split(b"\r\n", 1)[0].decode("latin-1").split()
    target = words[1] if len(words) > 1 else ""
    return re.sub(r"^\w+://", "", target).split("/", 1)[0].rsplit(":", 1)[0]


def page_requests(requests: list[bytes]) -> list[str]:
    """The requests that did not come from the browser's own services."""
    return [r.split(b"\r\n", 1)[0].decode("latin-1") for r in requests if request_host(r) not in BROWSER_SERVICE_HOSTS]


def test_request_host():
    assert request_host(b"GET http://cdn.example.org/x.js HTTP/1.1\r\nHost: cdn") == "cdn.example.org"
    assert request_host(b"CONNECT update.googleapis.com:443 HTTP/1.1\r\n") == "update.googleapis.com"
    assert page_requests([b"CONNECT accounts.google.com:443 HTTP/1.1\r\n", b"CONNECT fonts.googleapis.com:443 HTTP/1.1"]
                         ) == ["CONNECT fonts.googleapis.com:443 HTTP/1.1"]


def chromium(page: Path, tmp: Path, *, screenshot: Path | None = None, size=(1100, 3200)) -> tuple[str, list[bytes]]:
    """Open ``page`` in headless Chromium; return (the DOM after the page settled, the requests sent out)."""
    proxy = _CountingProxy()
    try:
        cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
               "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-extensions",
               "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
               f"--proxy-server=http://127.0.0.1:{proxy.port}", "--proxy-bypass-list=<-loopback>",
               "--use-angle=swiftshader", "--enable-unsafe-swiftshader",  # software WebGL
               f"--user-data-dir={tmp / 'chromium-profile'}", f"--window-size={size[0]},{size[1]}",
               "--hide-scrollbars", "--virtual-time-budget=20000"]
        out = subprocess.run(cmd + ["--dump-dom", page.as_uri()], capture_output=True, text=True, timeout=120)
        assert out.returncode == 0, out.stderr[-2000:]
        if screenshot is not None:
            shot = subprocess.run(cmd + [f"--screenshot={screenshot}", page.as_uri()], capture_output=True,
                                  text=True, timeout=120)
            assert shot.returncode == 0 and screenshot.is_file(), shot.stderr[-2000:]
        return out.stdout, list(proxy.requests)
    finally:
        proxy.close()


def body_attrs(dom: str) -> dict[str, str]:
    tag = re.search(r"<body\b([^>]*)>", dom).group(1)
    return {k: html.unescape(v) for k, v in re.findall(r'([\w-]+)="([^"]*)"', tag)}


@needs_chromium
def test_the_harness_sees_a_request_that_leaves_the_page(tmp_path):
    page = tmp_path / "leaky.html"
    page.write_text('<!DOCTYPE html><html><body><img src="http://pano2cad-test.invalid/x.png"></body></html>')
    _, requests = chromium(page, tmp_path, size=(400, 300))
    assert page_requests(requests) == ["GET http://pano2cad-test.invalid/x.png HTTP/1.1"], requests


@needs_chromium
def test_report_renders_the_3d_view_offline(run_dir, tmp_path):
    page = write_report(run_dir)
    shot = tmp_path / "report.png"
    dom, requests = chromium(page, tmp_path, screenshot=shot)
    attrs = body_attrs(dom)
    assert attrs.get("data-view3d") == "ready", attrs
    assert page_requests(requests) == [], requests
    assert attrs["data-csp-violations"] == "0" and json.loads(attrs["data-resources"]) == []
    # the page's own readPixels: the orbit and the first-person views are not blank
    assert float(attrs["data-canvas-variance"]) > 50.0, attrs
    assert float(attrs["data-canvas-variance-fp"]) > 50.0, attrs
    # and the screenshot shows it: the canvas area is not a flat colour
    x, y, w, h = json.loads(attrs["data-canvas-rect"])
    img = np.asarray(Image.open(shot).convert("L"), dtype=np.float64)
    assert y + h <= img.shape[0], f"the 3D view ({y}+{h}) lies below the screenshot ({img.shape[0]} px)"
    canvas = img[y:y + h, x:x + w]
    assert canvas.var() > 50.0 and len(np.unique(canvas)) > 20
    # the panorama layers are shown too
    assert "<td>bed-0</td>" in dom


@needs_chromium
def test_failed_run_report_opens_and_says_what_is_missing(tmp_path):
    d = tmp_path / "failed"
    d.mkdir()
    page = write_report(d)
    dom, requests = chromium(page, tmp_path, size=(800, 600))
    attrs = body_attrs(dom)
    assert attrs.get("data-view3d") == "missing" and page_requests(requests) == []
    assert "data-view3d-error" not in attrs, attrs  # the module ran without an error
    assert "scene.json is missing" in dom and "scene.glb is missing" in dom
