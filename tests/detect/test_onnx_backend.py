"""ONNX backend on tiny models exported by the tests (YOLOv8, YOLOv5 and SSD layouts), and its errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from detect.backends import ModelFileError, get_detector
from detect.backends.onnx_backend import OnnxDetector
from detect.detection import BatchDetector
from detect.nms import pano_box_iou
from detect.tiles import detect_panorama

pytest.importorskip("onnxruntime", reason="the onnx backend needs onnxruntime: pip install onnxruntime")

NAMES = ["chair", "table", "tv"]


def _image(colour, box, size=(100, 160)):
    img = np.full(size + (3,), 120, np.uint8)
    x0, y0, x1, y1 = box
    img[y0:y1, x0:x1] = colour
    return img


@pytest.mark.parametrize("kind,layout", [("v8", "yolo"), ("v5", "yolo"), ("ssd", "ssd")])
def test_layouts_decode_to_the_drawn_box(onnx_models, kind, layout):
    det = OnnxDetector(onnx_models[kind], NAMES)
    assert det.layout == layout and det.batchable and isinstance(det, BatchDetector)
    assert det.classes == ("chair", "table", "tv")
    # non-square image: letterbox (YOLO) or stretch (SSD) must be undone
    for colour, label, box in [((255, 0, 0), "chair", (100, 30, 140, 50)), ((0, 0, 255), "tv", (10, 60, 60, 95))]:
        got = det.detect(_image(colour, box))
        assert [d.label for d in got] == [label]
        tol = 1.0 if layout == "yolo" else 1.5  # SSD stretches 160 x 100 into 64 x 64
        assert np.allclose(got[0].box, box, atol=tol), (got[0].box, box)
        assert got[0].score > 0.9


def test_batch_equals_single_images(onnx_models):
    det = get_detector(f"onnx:{onnx_models['v8']}", classes=NAMES)
    imgs = [_image((255, 0, 0), (5, 5, 30, 40)), _image((120, 120, 120), (0, 0, 1, 1)),
            _image((0, 255, 0), (50, 10, 150, 90))]
    batch = det.detect_batch(imgs)
    assert [len(b) for b in batch] == [1, 0, 1]
    for b, im in zip(batch, imgs):
        single = det.detect(im)
        assert [(d.label, d.box.tolist()) for d in b] == [(d.label, d.box.tolist()) for d in single]
    assert batch[2][0].label == "table"


def test_sidecar_mapping_and_spec_options(onnx_models, tmp_path):
    det = get_detector(str(onnx_models["v8"]))  # v8.names lies next to it
    assert det.map_path.name == "v8.names"
    m = tmp_path / "map.json"
    m.write_text(json.dumps({"0": "Couch", "1": None, "2": "Computer monitor"}))
    det2 = get_detector(f"onnx:{onnx_models['v5']}?classes={m}&score=0.5")
    assert det2.classes == ("sofa", "tv")
    assert det2.detect(_image((0, 255, 0), (5, 5, 30, 40))) == []  # class 1 is ignored by the mapping
    assert det2.detect(_image((255, 0, 0), (5, 5, 30, 40)))[0].label == "sofa"


def test_end_to_end_through_the_panorama_driver(onnx_models, synth):
    pano = synth.grey_pano(256, seed=5)
    mask = synth.paint_lonlat(pano, np.deg2rad(-60), np.deg2rad(-40), np.deg2rad(-30), np.deg2rad(-8),
                              synth.COLOURS[1])
    det = OnnxDetector(onnx_models["ssd"], NAMES, score_threshold=0.5)
    found = detect_panorama(pano, det, tile_size=128)
    assert [d.label for d in found] == ["table"]
    cols, rows = np.flatnonzero(mask.any(0)), np.flatnonzero(mask.any(1))
    truth = [cols[0], rows[0], cols[-1] + 1, rows[-1] + 1]
    assert pano_box_iou([found[0].box], [truth], 512, 256)[0, 0] > 0.7
    assert found[0].support >= 2


def test_missing_model_file_is_named(tmp_path):
    p = tmp_path / "none.onnx"
    with pytest.raises(ModelFileError, match="ONNX model file not found") as e:
        get_detector(f"onnx:{p}", classes=NAMES)
    assert e.value.path == str(p)


def test_unreadable_model_file_is_named(tmp_path):
    p = tmp_path / "junk.onnx"
    p.write_bytes(b"not a model")
    with pytest.raises(ModelFileError, match=r"junk.onnx: not a loadable ONNX model"):
        OnnxDetector(p, NAMES)


def test_wrong_output_layout_is_one_clear_error(onnx_models):
    with pytest.raises(ModelFileError, match=r"bad.onnx: output layout not understood: .*output0 \(1, 7\)"):
        OnnxDetector(onnx_models["bad"], NAMES)
    with pytest.raises(ModelFileError, match="YOLO needs exactly one output of rank 3"):
        OnnxDetector(onnx_models["ssd"], NAMES, layout="yolo")


def test_class_mapping_that_does_not_fit_names_the_mapping_file(onnx_models, tmp_path):
    m = tmp_path / "two.names"
    m.write_text("chair\ntable\n")
    with pytest.raises(ModelFileError, match=r"two.names: the class mapping gives C=2 classes but the YOLO output "
                                             r"\(1, 7, 2\) of v8.onnx is neither"):
        OnnxDetector(onnx_models["v8"], m)
    with pytest.raises(ModelFileError, match=r"ssd.onnx is not in the class mapping"):
        # the SSD model reports class 2 (blue), which this mapping lacks
        OnnxDetector(onnx_models["ssd"], ["chair", "table"]).detect(_image((0, 0, 255), (5, 5, 30, 40)))
    bad = tmp_path / "bad.json"
    bad.write_text('["chair", "not a word!"]')
    with pytest.raises(ModelFileError, match="bad.json: class 1: expected a class name"):
        OnnxDetector(onnx_models["v8"], bad)


def test_no_mapping_anywhere_is_named(onnx_models):
    with pytest.raises(ModelFileError, match=r"v5.onnx: no class-mapping file next to the model"):
        OnnxDetector(onnx_models["v5"])


def test_logit_scores_are_refused_unless_declared(onnx_models):
    # the SSD model's scores are probabilities: declaring them logits squashes them through a sigmoid
    det = OnnxDetector(onnx_models["ssd"], NAMES, logits=True, score_threshold=0.0)
    got = det.detect(_image((255, 0, 0), (5, 5, 30, 40)))
    assert max(d.score for d in got) == pytest.approx(1 / (1 + np.exp(-1.0)), abs=0.01)


def test_option_values_are_checked(onnx_models):
    with pytest.raises(ValueError, match=r"option score: expected a number in \[0.0, 1.0\], got '7'"):
        get_detector(f"onnx:{onnx_models['v8']}?score=7")
    with pytest.raises(ValueError, match="option layout: expected one of"):
        get_detector(f"onnx:{onnx_models['v8']}?layout=detr")
