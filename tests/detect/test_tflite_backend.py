"""TFLite Objectron SSD backend: anchors, errors, and a real chair (skipped without the model or ai-edge-litert)."""

from __future__ import annotations

import numpy as np
import pytest

from detect.backends import ModelFileError, get_detector
from detect.backends.tflite_backend import DEFAULT_LABELS, DEFAULT_MODEL, TFLiteSSDDetector, ssd_anchors
from detect.fetch_models import CHECKSUMS, verify
from detect.tiles import detect_panorama

try:
    import ai_edge_litert.interpreter  # noqa: F401

    HAVE_LITERT = True
except ImportError:
    HAVE_LITERT = False
needs_model = pytest.mark.skipif(not (HAVE_LITERT and DEFAULT_MODEL.is_file() and DEFAULT_LABELS.is_file()),
                                 reason="needs ai-edge-litert and `python -m detect.fetch_models`")


def test_anchors_follow_mediapipe_ssd_anchors_calculator():
    a = ssd_anchors()
    assert a.shape == (1917, 4)  # 19*19*3 + (10*10 + 5*5 + 3*3 + 2*2 + 1) * 6
    # first cell of the lowest layer: scales 0.1, 0.2, 0.2 with ratios 1, 2, 1/2
    assert np.allclose(a[0], [0.5 / 19, 0.5 / 19, 0.1, 0.1])
    assert np.allclose(a[1, 2:], [0.2 / np.sqrt(2), 0.2 * np.sqrt(2)], atol=1e-6)
    # last layer: one 1x1 cell, scale 0.95 and the interpolated sqrt(0.95 * 1.0)
    assert np.allclose(a[-1], [0.5, 0.5, np.sqrt(0.95), np.sqrt(0.95)], atol=1e-6)
    assert np.all((a[:, :2] > 0) & (a[:, :2] < 1))


def test_missing_model_names_the_file_and_the_fetch_command(tmp_path):
    with pytest.raises(ModelFileError, match=r"TFLite model file not found") as e:
        TFLiteSSDDetector(tmp_path / "m.tflite", DEFAULT_LABELS)
    assert e.value.path == str(tmp_path / "m.tflite")
    if not DEFAULT_MODEL.is_file():
        with pytest.raises(ModelFileError, match=r"python -m detect.fetch_models"):
            get_detector("tflite")


@needs_model
def test_fetched_files_match_the_recorded_checksums():
    assert verify(DEFAULT_MODEL.parent, CHECKSUMS)


@needs_model
def test_wrong_label_map_names_the_label_file(tmp_path):
    lab = tmp_path / "labels.txt"
    lab.write_text("???\nChair\nTable\n")
    with pytest.raises(ModelFileError, match=r"labels.txt: the label map has 3 names but the model "
                                             r"objectron_ssd.tflite outputs 24 classes"):
        TFLiteSSDDetector(DEFAULT_MODEL, lab)


@needs_model
def test_not_a_tflite_file_is_named(tmp_path):
    bad = tmp_path / "bad.tflite"
    bad.write_bytes(b"\0" * 64)
    with pytest.raises(ModelFileError, match="bad.tflite: not a loadable TFLite model"):
        TFLiteSSDDetector(bad, DEFAULT_LABELS)


@needs_model
def test_classes_and_mapping():
    det = get_detector("tflite")
    assert det.classes == ("chair", "table", "tv")
    assert det.raw_labels[0] == "???" and len(det.raw_labels) == 24
    others = get_detector("tflite?keep_others=true")
    assert {"laptop", "computer_mouse", "chair"} <= set(others.classes)
    assert det.detect(np.full((300, 300, 3), 128, np.uint8)) == []


@needs_model
def test_finds_the_armchair_of_a_real_panorama(synth):
    if synth.real_data is None:
        pytest.skip("the project's real panoramas (shared/data/real) are not here")
    import cv2

    path = synth.real_data / "panocontext_pano_asmasuxybohhcj" / "pano.png"
    if not path.is_file():
        pytest.skip(f"{path} is not here")
    pano = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB)
    dets = detect_panorama(pano, get_detector("tflite"), score_threshold=0.5)
    # the yellow armchair right of the desk spans about u 840..945, v 315..420 in this 1024 x 512 image
    chairs = [d for d in dets if d.label == "chair" and 800 < d.center_px[0] < 980 and 300 < d.center_px[1] < 420]
    assert chairs and chairs[0].support >= 2
