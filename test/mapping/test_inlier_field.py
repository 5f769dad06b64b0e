"""The recognizer's inlier test on a distance grid answers exactly as the direct test."""

from __future__ import annotations

import numpy as np
import pytest
from island_mapping.core.builder.inlier_field import InlierField
from island_msgs_py.geometry import point_segment_distance


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_grid_answers_exactly_as_the_direct_test(seed: int) -> None:
    rng = np.random.default_rng(seed)
    starts = rng.uniform(-8.0, 8.0, (60, 2))
    segs = np.concatenate([starts, starts + rng.normal(0.0, 2.0, (60, 2))], axis=1)
    # points near the walls (many in the band around the threshold) and far from them
    on = segs[rng.integers(0, 60, 20000)]
    t = rng.uniform(0.0, 1.0, (20000, 1))
    pts = on[:, :2] + t * (on[:, 2:] - on[:, :2]) + rng.normal(0.0, 0.15, (20000, 2))
    pts = np.concatenate([pts, rng.uniform(-30.0, 30.0, (5000, 2))])
    field = InlierField(segs, 0.15)
    direct = point_segment_distance(pts, segs).min(axis=1) <= 0.15
    assert 0.2 < direct.mean() < 0.8
    assert np.array_equal(field.within(pts), direct)


def test_no_walls_no_inliers_and_a_huge_model_is_answered_directly() -> None:
    assert not InlierField(np.zeros((0, 4)), 0.15).within(np.zeros((3, 2))).any()
    segs = np.array([[0.0, 0.0, 1.0e5, 0.0], [0.0, 0.0, 0.0, 1.0e5]])
    pts = np.array([[5.0, 0.1], [5.0, 0.3], [0.1, 7.0]])
    assert InlierField(segs, 0.15).within(pts).tolist() == [True, False, True]
