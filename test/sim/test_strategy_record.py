"""Strategy record: Table 1 units, merging of like primitives, rotations in progress, reset."""

from __future__ import annotations

import math

from island_msgs_py.types import PrimitiveKind
from island_sim.core.strategy_record import StrategyRecorder


def test_travel_and_rotation_become_go_cm_and_rot_deg_ccw() -> None:
    rec = StrategyRecorder()
    rec.add_travel(0.8)
    rec.add_travel(0.454)  # one Go: travel adds up until closed
    rec.close_go()
    rec.start_rotation(0.1)
    rec.close_rotation(0.1 - math.pi / 2.0)  # a right turn is Rot 270 (CCW, 0-360)
    rec.add_travel(2.0)
    assert str(rec.strategy(None)) == "Go 125, Rot 270, Go 200"


def test_like_primitives_merge_and_a_full_circle_vanishes() -> None:
    rec = StrategyRecorder()
    rec.add_travel(1.0)
    rec.close_go()
    rec.close_rotation(None)  # no rotation: nothing recorded, the Go stays open to merging
    rec.add_travel(0.5)
    rec.close_go()
    for start, end in ((0.0, math.pi), (math.pi, 0.0)):  # two half turns: back where it was
        rec.start_rotation(start)
        rec.close_rotation(end)
    assert [(s.kind, s.value) for s in rec.strategy(None).steps] == [(PrimitiveKind.GO, 150)]


def test_rotation_in_progress_is_reported_and_reset_measures_on_from_now() -> None:
    rec = StrategyRecorder()
    rec.add_travel(1.0)
    rec.close_go()
    rec.start_rotation(0.0)
    assert str(rec.strategy(math.pi / 2.0)) == "Go 100, Rot 90"  # up to the current heading
    assert str(rec.strategy(None)) == "Go 100"  # no heading: nothing measured yet
    rec.reset(math.pi / 2.0)
    assert str(rec.strategy(math.pi / 2.0)) == ""
    rec.close_rotation(math.pi)  # only the part after the reset counts
    assert str(rec.strategy(None)) == "Rot 90"
