"""Backend registry, spec parsing, class mapping, and the annotation-file backend."""

from __future__ import annotations

import json

import numpy as np
import pytest

from detect.backends import (ModelFileError, available_backends, canonical_label, get_detector, load_class_map,
                             parse_spec, register_backend)
from detect.backends.annotations_backend import AnnotationDetector
from detect.detection import Detection, PanoramaDetector
from detect.tiles import detect_panorama


def test_parse_spec_forms():
    s = parse_spec("onnx:/m/y.onnx?classes=/m/coco.names&score=0.3")
    assert (s.kind, s.path, s.options) == ("onnx", "/m/y.onnx", {"classes": "/m/coco.names", "score": "0.3"})
    assert parse_spec("tflite") == parse_spec("tflite:")
    assert parse_spec("tflite").path is None
    assert parse_spec("x/model.tflite").kind == "tflite"
    assert parse_spec("boxes.JSON").kind == "annotations"
    assert parse_spec("what?.onnx").path == "what?.onnx"  # a '?' without key=value is part of the name


@pytest.mark.parametrize("spec,msg", [
    ("frobnicate", "expected one of annotations, builtin, onnx, tflite"),
    ("onnx", "the onnx backend needs a file"),
    ("annotations:", "the annotations backend needs a file"),
    ("", "expected a string like 'tflite'"),
    ("onnx:m.onnx?a=1&&b", "expected options as \\?key=value"),
])
def test_parse_spec_errors(spec, msg):
    with pytest.raises(ValueError, match=msg):
        parse_spec(spec)


def test_unknown_options_are_named(tmp_path):
    f = tmp_path / "b.json"
    f.write_text(json.dumps({"image": {"width": 64, "height": 32}, "objects": []}))
    with pytest.raises(ValueError, match=r"annotations detector: unknown option\(s\) \['score'\]"):
        get_detector(f"annotations:{f}?score=0.5")


def test_register_backend_plugs_in_a_new_one():
    made = []

    def factory(path, options):
        made.append((path, dict(options)))

        class D:
            def detect(self, image):
                return []
        return D()

    register_backend("testonly", factory)
    try:
        assert "testonly" in available_backends()
        get_detector("testonly?x=1", y=2)
        assert made == [(None, {"x": "1", "y": 2})]
    finally:
        from detect import backends

        backends._ENTRIES.pop("testonly")
    with pytest.raises(ValueError, match="expected a lowercase identifier"):
        register_backend("Bad Name", factory)
    with pytest.raises(ValueError, match="'module:function' or a callable"):
        register_backend("bad", "no_colon")


def test_canonical_label_maps_dataset_names():
    assert [canonical_label(n) for n in ("Chair", "Desk", "dining table", "Couch", "potted plant",
                                         "Computer monitor", "TV", "Laptop", "High heels", "-")] == \
        ["chair", "table", "table", "sofa", "plant", "tv", "tv", "laptop", "high_heels", None]
    with pytest.raises(ValueError, match="lowercase word"):
        canonical_label("wine glass!")


def test_load_class_map_formats(tmp_path):
    (tmp_path / "a.json").write_text(json.dumps(["Chair", None, "couch"]))
    assert load_class_map(tmp_path / "a.json") == {0: "chair", 1: None, 2: "sofa"}
    (tmp_path / "b.json").write_text(json.dumps({"1": "tv", "62": "chair"}))
    assert load_class_map(tmp_path / "b.json") == {1: "tv", 62: "chair"}
    (tmp_path / "c.names").write_text("person\nchair\n-\n\n")
    assert load_class_map(tmp_path / "c.names") == {0: "person", 1: "chair", 2: None}


@pytest.mark.parametrize("name,content,msg", [
    ("missing.json", None, "class-mapping file not found"),
    ("bad.json", "{not json", "invalid JSON"),
    ("num.json", "3", "expected a JSON list or object"),
    ("key.json", '{"x": "chair"}', "expected integer class indices"),
    ("val.json", '["chair", 3]', "class 1: expected a class name"),
    ("empty.txt", "-\n???\n", "expected at least one class name"),
])
def test_load_class_map_errors_name_the_file(tmp_path, name, content, msg):
    p = tmp_path / name
    if content is not None:
        p.write_text(content)
    with pytest.raises(ModelFileError, match=msg) as e:
        load_class_map(p)
    assert str(p) in str(e.value) and e.value.path == str(p)


def _pano2cad(tmp_path, objects, size=(1024, 512)):
    p = tmp_path / "scene.json"
    p.write_text(json.dumps({"schema": "pano2cad/scene@1", "image": {"width": size[0], "height": size[1]},
                             "objects": objects}))
    return p


def test_annotations_pano2cad_file_scaled_and_wrapping(tmp_path):
    p = _pano2cad(tmp_path, [
        {"class": "chair", "bbox_pano": [1000, 300, 30, 400], "score": 0.7},
        {"class": "Couch", "bbox_pano": [10, 300, 200, 400]},
        {"class": "bed", "bbox_pano": None},
    ])
    det = get_detector(f"annotations:{p}")
    assert isinstance(det, PanoramaDetector) and isinstance(det, AnnotationDetector)
    assert det.skipped == 1 and det.classes == ("chair", "sofa")
    pano = np.zeros((256, 512, 3), np.uint8)
    got = detect_panorama(pano, det)
    assert [(d.label, d.score) for d in got] == [("sofa", 1.0), ("chair", 0.7)]
    chair = got[1]
    assert chair.wraps and chair.box.tolist() == [500.0, 150.0, 15.0, 200.0]
    assert got[0].to_json()["bbox_pano"] == [5.0, 150.0, 100.0, 200.0]


def test_annotations_coco_file(tmp_path):
    coco = {
        "images": [{"id": 1, "file_name": "rooms/a.png", "width": 2048, "height": 1024},
                   {"id": 2, "file_name": "rooms/b.png", "width": 2048, "height": 1024}],
        "categories": [{"id": 56, "name": "chair"}, {"id": 60, "name": "dining table"}],
        "annotations": [
            {"image_id": 1, "category_id": 56, "bbox": [2000, 500, 100, 80]},
            {"image_id": 1, "category_id": 60, "bbox": [100, 500, 300, 200], "score": 0.6},
            {"image_id": 2, "category_id": 56, "bbox": [10, 10, 20, 20]},
        ],
    }
    p = tmp_path / "coco.json"
    p.write_text(json.dumps(coco))
    with pytest.raises(ModelFileError, match="holds 2 images; choose one with image=NAME"):
        get_detector(f"annotations:{p}")
    det = get_detector(f"annotations:{p}?image=a.png")
    dets = det.detections(2048, 1024)
    assert [(d.label, d.score) for d in dets] == [("chair", 1.0), ("table", 0.6)]
    assert dets[0].wraps and dets[0].box.tolist() == [2000.0, 500.0, 52.0, 580.0]
    assert len(get_detector(f"annotations:{p}", image=2).detections(2048, 1024)) == 1


@pytest.mark.parametrize("data,msg", [
    ({"objects": []}, "expected an image record"),
    ({"image": {"width": 100, "height": 100}, "objects": []}, "W == 2\\*H, got 100x100"),
    ({"image": {"width": 64, "height": 32}, "objects": [{"class": "chair", "bbox_pano": [0, 10, 5, 5]}]},
     "objects\\[0\\]: expected a box"),
    ({"image": {"width": 64, "height": 32}, "objects": [{"class": "???", "bbox_pano": [0, 1, 5, 5]}]},
     "objects\\[0\\]: expected a class name"),
    ({"image": {"width": 64, "height": 32}, "objects": [{"class": "tv", "bbox_pano": [0, 1, 5, 5], "score": 3}]},
     "expected a score in \\[0, 1\\], got 3"),
    ({"images": [{"id": 1, "width": 64, "height": 32}], "categories": [],
      "annotations": [{"image_id": 1, "category_id": 7, "bbox": [0, 0, 4, 4]}]}, "category_id 7 is not in"),
    ([1, 2], "expected a pano2cad file"),
])
def test_annotation_errors_name_the_file(tmp_path, data, msg):
    p = tmp_path / "ann.json"
    p.write_text(json.dumps(data))
    with pytest.raises(ModelFileError, match=msg) as e:
        AnnotationDetector(p)
    assert str(e.value).startswith(str(p))


def test_annotation_file_missing(tmp_path):
    with pytest.raises(ModelFileError, match="annotation file not found"):
        get_detector(str(tmp_path / "nope.json"))


def test_annotation_boxes_survive_rounding_at_the_right_edge(tmp_path):
    p = _pano2cad(tmp_path, [{"class": "tv", "bbox_pano": [1000, 10, 1024, 20]}], size=(1024, 512))
    d = AnnotationDetector(p).detections(700, 350)[0]
    assert isinstance(d, Detection) and d.box[2] <= 700
