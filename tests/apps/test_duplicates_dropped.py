"""apps.pipeline.drop_duplicates: one object detected twice reaches the sampler once, and the scene says so."""

from __future__ import annotations

import numpy as np

from apps.pipeline import drop_duplicates
from layout.sampler import DetectedObject
from panogeom.project import world_box_to_pano

W, H = 1024, 512


def _det(cls, center, size, yaw, score, grow=0.0):
    u0, v0, u1, v1 = world_box_to_pano(center, size, yaw, W, H, camera_height=1.6).extent
    return DetectedObject(cls, [u0 - grow, v0 - grow, u1 + grow, v1 + grow], size, yaw, score=score,
                          symmetric=cls == "plant")


def test_the_second_box_of_a_plant_is_dropped_with_its_orientation_term():
    plant = (np.array([2.0, 1.0, 0.45]), (0.5, 0.5, 0.9))
    objects = [_det("plant", *plant, 0.0, 0.64), _det("chair", np.array([-1.5, 2.0, 0.45]), (0.5, 0.5, 0.9), 0.0, 0.7),
               _det("plant", *plant, 0.0, 0.51, grow=1.5)]  # the same plant, a slightly larger box
    eo = ["plant-0", "chair", "plant-1"]
    notes: list[str] = []
    kept, kept_eo = drop_duplicates(objects, eo, W, H, 1.6, notes)
    assert [o.cls for o in kept] == ["plant", "chair"] and kept[0].score == 0.64
    assert kept_eo == ["plant-0", "chair"]
    assert len(notes) == 1 and notes[0].startswith("dropped plant (score 0.51)") and "detected twice" in notes[0]


def test_two_chairs_side_by_side_both_stay():
    objects = [_det("chair", np.array([2.0, 0.0, 0.45]), (0.5, 0.5, 0.9), 0.0, 0.8),
               _det("chair", np.array([2.0, 0.6, 0.45]), (0.5, 0.5, 0.9), 0.0, 0.6)]
    notes: list[str] = []
    kept, kept_eo = drop_duplicates(objects, [None, None], W, H, 1.6, notes)
    assert len(kept) == 2 and kept_eo == [None, None] and notes == []
