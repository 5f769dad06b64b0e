"""The geometric check of where islands land (evaluation only)."""

from __future__ import annotations

import numpy as np
from island_mapping.core.placement import (
    PlaceKind,
    classify_place,
    feature_distance_m,
    placement_counts,
)
from island_msgs_py.types import Pose2D
from island_sim.core.world_loader import load_world

CORRIDOR = np.array([[0.0, 0.0, 20.0, 0.0], [0.0, 2.0, 20.0, 2.0]])


def test_middle_of_a_long_corridor_is_a_plain_hallway() -> None:
    assert classify_place(CORRIDOR, 10.0, 1.0) is PlaceKind.PLAIN_HALLWAY


def test_a_wall_across_the_corridor_makes_a_feature_only_when_visible() -> None:
    closed = np.vstack([CORRIDOR, [[20.0, 0.0, 20.0, 2.0]]])
    assert classify_place(closed, 19.0, 1.0) is PlaceKind.FEATURE
    assert classify_place(closed, 10.0, 1.0) is PlaceKind.PLAIN_HALLWAY  # 10 m away
    # A cross wall hidden behind the corridor wall does not count.
    hidden = np.vstack([CORRIDOR, [[9.5, 2.5, 9.5, 4.0]]])
    assert classify_place(hidden, 10.0, 1.0) is PlaceKind.PLAIN_HALLWAY


def test_far_from_every_wall_is_open_space() -> None:
    assert classify_place(CORRIDOR, 10.0, 30.0) is PlaceKind.OPEN_SPACE
    assert classify_place(np.zeros((0, 4)), 0.0, 0.0) is PlaceKind.OPEN_SPACE


def test_paper_fig4_junction_and_hallway() -> None:
    world = load_world("paper_fig4")
    # South corridor (y 8..10): x = 21 lies between doors; x = 9 is the west junction.
    assert classify_place(world.segments, 21.0, 9.0) is PlaceKind.PLAIN_HALLWAY
    assert classify_place(world.segments, 9.0, 9.0) is PlaceKind.FEATURE
    counts = placement_counts(world.segments, [Pose2D(21.0, 9.0, 0.0), Pose2D(9.0, 9.0, 0.0)])
    assert counts == {"plain_hallway": 1, "feature": 1, "open_space": 0}


def test_feature_distance_is_how_far_the_nearest_cross_wall_is() -> None:
    closed = np.vstack([CORRIDOR, [[20.0, 0.0, 20.0, 2.0]]])
    d = feature_distance_m(closed, 16.0, 1.0)
    assert 4.0 <= d <= 4.25  # the end wall is 4 m ahead (first visible just beyond 4 m)
    assert feature_distance_m(CORRIDOR, 10.0, 1.0, max_m=5.0) == float("inf")
