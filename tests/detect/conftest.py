"""Fixtures of the detect tests: synthetic panoramas and tiny ONNX detectors the tests export themselves."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest

from panogeom.coords import pixel_grid, pixel_to_lonlat

#: Colours the tiny models classify: index = class index.
COLOURS = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255]], np.uint8)
NAMES = ["chair", "table", "tv"]


def grey_pano(height: int = 512, seed: int = 0) -> np.ndarray:
    """A grey panorama with mild noise (no saturated colour)."""
    rng = np.random.default_rng(seed)
    g = rng.integers(90, 150, (height, 2 * height, 1))
    return np.repeat(g, 3, axis=2).astype(np.uint8)


def paint_lonlat(pano: np.ndarray, lon0: float, lon1: float, lat0: float, lat1: float,
                 colour: np.ndarray) -> np.ndarray:
    """Paint the lon/lat rectangle [lon0, lon1] x [lat0, lat1] (lon may wrap, radians); returns the mask."""
    H, W = pano.shape[:2]
    ll = pixel_to_lonlat(pixel_grid(W, H), W, H)
    dl = np.mod(ll[..., 0] - lon0, 2 * np.pi)
    m = (dl <= np.mod(lon1 - lon0, 2 * np.pi)) & (ll[..., 1] >= lat0) & (ll[..., 1] <= lat1)
    pano[m] = colour
    return m


def _blob_stats(torch, x, S: int):
    """Mask-weighted centre, size, mean colour and presence of the saturated pixels of (B, 3, S, S) in [0, 1]."""
    sat = x.max(1).values - x.min(1).values
    m = torch.sigmoid((sat - 0.5) * 40.0)
    mass = m.sum((1, 2)) + 1e-6
    c = torch.arange(S, dtype=torch.float32) + 0.5
    cx = (m * c[None, None, :]).sum((1, 2)) / mass
    cy = (m * c[None, :, None]).sum((1, 2)) / mass
    vx = (m * (c[None, None, :] - cx[:, None, None]) ** 2).sum((1, 2)) / mass
    vy = (m * (c[None, :, None] - cy[:, None, None]) ** 2).sum((1, 2)) / mass
    w, h = torch.sqrt(12.0 * vx + 1e-6), torch.sqrt(12.0 * vy + 1e-6)
    colour = (x * m[:, None]).sum((2, 3)) / mass[:, None]
    present = torch.clamp(mass / 20.0, 0.0, 1.0)
    return cx, cy, w, h, colour, present


def _export(torch, module, path: Path, S: int, outputs: list[str]) -> Path:
    dyn = {"images": {0: "batch"}}
    dyn.update({o: {0: "batch"} for o in outputs})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(module, torch.zeros(1, 3, S, S), str(path), dynamo=False, input_names=["images"],
                          output_names=outputs, dynamic_axes=dyn, opset_version=17)
    return path


@pytest.fixture(scope="session")
def onnx_models(tmp_path_factory):
    """Tiny colour-blob detectors exported to ONNX: {"v8", "v5", "ssd", "bad"} -> path (input 64x64).

    Each finds the saturated blob of a tile and classifies it by colour (red 0,
    green 1, blue 2), with a second, low-score candidate box.
    """
    pytest.importorskip("onnx", reason="torch.onnx.export needs the onnx package: pip install onnx")
    pytest.importorskip("onnxruntime", reason="the onnx backend needs onnxruntime: pip install onnxruntime")
    torch = pytest.importorskip("torch")
    S = 64
    d = tmp_path_factory.mktemp("onnx")

    class V8(torch.nn.Module):
        def forward(self, x):
            cx, cy, w, h, colour, present = _blob_stats(torch, x, S)
            cand = torch.cat([torch.stack([cx, cy, w, h], 1), colour * present[:, None]], 1)
            low = torch.cat([torch.full_like(cand[:, :4], S / 4.0), torch.full_like(cand[:, 4:], 0.01)], 1)
            return torch.stack([cand, low], 2)                           # (B, 4 + 3, 2)

    class V5(torch.nn.Module):
        def forward(self, x):
            cx, cy, w, h, colour, present = _blob_stats(torch, x, S)
            cand = torch.cat([torch.stack([cx, cy, w, h, present], 1), colour], 1)
            low = torch.cat([torch.full_like(cand[:, :4], S / 4.0), torch.full_like(cand[:, 4:], 0.05)], 1)
            return torch.stack([cand, low], 1)                           # (B, 2, 5 + 3)

    class SSD(torch.nn.Module):
        def forward(self, x):
            cx, cy, w, h, colour, present = _blob_stats(torch, x, S)
            box = torch.stack([(cy - h / 2) / S, (cx - w / 2) / S, (cy + h / 2) / S, (cx + w / 2) / S], 1)
            boxes = torch.stack([box, torch.full_like(box, 0.25) + torch.tensor([0.0, 0.0, 0.5, 0.5])], 1)
            sc, cl = (colour * present[:, None]).max(1)
            scores = torch.stack([sc, torch.full_like(sc, 0.02)], 1)
            classes = torch.stack([cl, torch.zeros_like(cl)], 1)
            return boxes, scores, classes                                 # (B, 2, 4), (B, 2), (B, 2) int64

    class Bad(torch.nn.Module):
        def forward(self, x):
            return x.mean((2, 3)).repeat(1, 3)[:, :7]                     # (B, 7): no detection layout

    paths = {
        "v8": _export(torch, V8(), d / "v8.onnx", S, ["output0"]),
        "v5": _export(torch, V5(), d / "v5.onnx", S, ["output0"]),
        "ssd": _export(torch, SSD(), d / "ssd.onnx", S, ["detection_boxes", "detection_scores", "detection_classes"]),
        "bad": _export(torch, Bad(), d / "bad.onnx", S, ["output0"]),
    }
    (d / "v8.names").write_text("\n".join(NAMES) + "\n")
    return paths


def find_real_data() -> Path | None:
    """The project's real panoramas (shared/data/real), next to or inside the repository, if present."""
    repo = Path(__file__).resolve().parents[2]
    for cand in (repo.parent / "shared" / "data" / "real", repo / "shared" / "data" / "real"):
        if cand.is_dir():
            return cand
    return None


def fake_rooms(root: Path, seed: int, n: int = 1) -> Path:
    """Room folders with painted objects, as `pano2cad synth` writes them (a tv and a bed)."""
    import cv2

    from panogeom.boxes import mask_to_pano_box
    from panogeom.coords import pixel_grid, pixel_to_lonlat

    root.mkdir(parents=True)
    W, H = 256, 128
    ll = np.rad2deg(pixel_to_lonlat(pixel_grid(W, H), W, H))
    for i in range(n):
        d = root / f"room-{i:04d}"
        d.mkdir()
        rgb = np.full((H, W, 3), 120, np.uint8)
        inst = np.zeros((H, W), np.uint16)
        objs = []
        for k, (label, lon, lat, colour) in enumerate((("tv", 30 + 50 * i, 0, (20, 20, 20)),
                                                        ("bed", -90, -30, (200, 40, 40)))):
            m = (np.abs(ll[..., 0] - lon) < 15) & (np.abs(ll[..., 1] - lat) < 10)
            rgb[m] = colour
            inst[m] = k + 1
            objs.append({"class": label, "bbox_pano": mask_to_pano_box(m).tolist(), "visible_px": int(m.sum())})
        cv2.imwrite(str(d / "pano.png"), rgb[..., ::-1])
        cv2.imwrite(str(d / "instances.png"), inst)
        (d / "gt.json").write_text(json.dumps({"image": {"width": W, "height": H}, "objects": objs}))
    (root / "index.json").write_text(json.dumps({"seed": seed}))
    return root


@pytest.fixture(scope="session")
def synth():
    """Helpers for synthetic scenes (fixtures, as conftest modules are not importable under importlib mode)."""
    from types import SimpleNamespace

    return SimpleNamespace(grey_pano=grey_pano, paint_lonlat=paint_lonlat, COLOURS=COLOURS, NAMES=NAMES,
                           fake_rooms=fake_rooms,
                           real_data=find_real_data())
