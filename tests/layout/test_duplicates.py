"""layout.duplicates: one object detected twice."""

from __future__ import annotations

import numpy as np
import pytest

from layout.duplicates import Duplicate, same_class_duplicates


def test_the_lower_scored_copy_is_dropped():
    d = same_class_duplicates(["plant", "plant"], [0.64, 0.51], [[1.0, 2.0], [1.02, 2.01]], [0.0, 0.3],
                              [[0.5, 0.5], [0.5, 0.5]])
    assert len(d) == 1 and (d[0].dropped, d[0].kept) == (1, 0)
    assert 0.8 < d[0].share <= 1.0


def test_objects_of_different_classes_are_never_merged():
    d = same_class_duplicates(["table", "chair"], [0.9, 0.5], [[0.0, 2.0], [0.0, 2.0]], [0.0, 0.0],
                              [[1.6, 0.9], [0.5, 0.5]])
    assert d == ()


def test_neighbours_that_share_less_than_the_threshold_stay():
    # two chairs side by side, 0.4 m of 0.5 m apart: they share a fifth of a footprint
    d = same_class_duplicates(["chair", "chair"], [0.9, 0.5], [[0.0, 2.0], [0.4, 2.0]], [0.0, 0.0],
                              [[0.5, 0.5], [0.5, 0.5]])
    assert d == ()
    assert len(same_class_duplicates(["chair", "chair"], [0.9, 0.5], [[0.0, 2.0], [0.4, 2.0]], [0.0, 0.0],
                                     [[0.5, 0.5], [0.5, 0.5]], min_share=0.15)) == 1


def test_three_copies_leave_the_best_scored_one():
    d = same_class_duplicates(["tv"] * 3, [0.5, 0.8, 0.6], [[2.0, 0.0], [2.01, 0.0], [2.0, 0.02]], [0.0] * 3,
                              [[0.2, 1.0]] * 3)
    assert sorted(x.dropped for x in d) == [0, 2]
    assert all(isinstance(x, Duplicate) for x in d)


def test_a_missing_score_counts_as_zero():
    d = same_class_duplicates(["plant", "plant"], [None, 0.3], [[1.0, 1.0], [1.0, 1.0]], [0.0, 0.0],
                              [[0.5, 0.5]] * 2)
    assert (d[0].dropped, d[0].kept) == (0, 1)


def test_small_footprint_inside_a_large_one_counts_by_the_smaller():
    # a 0.4 m plant wholly inside a 1 m plant's footprint: all of the smaller one is shared
    d = same_class_duplicates(["plant", "plant"], [0.4, 0.7], [[0.0, 2.0], [0.1, 2.0]], [0.0, 0.0],
                              [[1.0, 1.0], [0.4, 0.4]])
    assert len(d) == 1 and d[0].dropped == 0 and d[0].share == pytest.approx(1.0)


def test_fewer_than_two_objects():
    assert same_class_duplicates([], [], np.zeros((0, 2)), [], np.zeros((0, 2))) == ()
    assert same_class_duplicates(["bed"], [0.9], [[0.0, 1.0]], [0.0], [[2.0, 1.6]]) == ()


@pytest.mark.parametrize("share", [0.0, -0.1, 1.5])
def test_bad_threshold(share):
    with pytest.raises(ValueError, match="min_share"):
        same_class_duplicates(["bed"], [0.9], [[0.0, 1.0]], [0.0], [[2.0, 1.6]], min_share=share)


def test_mismatched_lengths():
    with pytest.raises(ValueError, match="expected 2 scores"):
        same_class_duplicates(["bed", "bed"], [0.9], [[0.0, 1.0], [0.0, 1.0]], [0.0, 0.0], [[2.0, 1.6]] * 2)
