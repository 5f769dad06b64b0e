"""Which lane the explorer drives to leave an island by an exit (`core.explore.departure`):
a lane must run along the exit or along an island axis; a diagonal lane whose entry merely
lies toward the exit is not driven (the robot would be handed over facing across the
hallway). Public API: `core.explore.departure.choose_lane`, `core.explore.exits.Lane`."""

from __future__ import annotations

import math

from island_mapping.core.explore import ExplorerConfig
from island_mapping.core.explore.departure import choose_lane
from island_mapping.core.explore.exits import Lane
from island_msgs_py.types import Exit

CFG = ExplorerConfig()


def _entry_deg(lane: Lane) -> float:
    x, y = lane.entry(CFG.exit.entry_m)
    return math.degrees(math.atan2(y, x))


def test_a_diagonal_lane_toward_the_exit_is_not_driven() -> None:
    ex = Exit(0, -0.5 * math.pi, 0.64)
    diagonal = Lane(math.radians(-132.0), 1.08, 1.0)  # entry toward the exit, 42 deg off it
    assert abs(_entry_deg(diagonal) + 90.0) < 5.0
    assert choose_lane([diagonal], ex, CFG) is None
    along = Lane(-0.5 * math.pi + 0.1, 0.0, 0.8)
    assert choose_lane([diagonal, along], ex, CFG) is along


def test_a_side_corridor_along_an_axis_is_driven() -> None:
    """An offset lane along an island axis: its entry lies 51 deg off its heading."""
    side = Lane(0.0, -1.5, 1.0)
    ex = Exit(1, math.radians(_entry_deg(side)), 1.0)
    assert abs(math.degrees(ex.heading_rad) + 51.3) < 1.0
    assert choose_lane([side], ex, CFG) is side
    turned = Lane(math.radians(20.0), -1.5, 1.0)  # the same entry side, off every axis
    assert choose_lane([turned], Exit(2, math.radians(_entry_deg(turned)), 1.0), CFG) is None
