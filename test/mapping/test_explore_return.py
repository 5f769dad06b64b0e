"""The way back to the island left, without the laps of the way out (issue 16).

Office 11 seed 1 handed the robot over into a 4.5 x 4 m room beside its island; the hall
follower ran round it for the whole 300 s cap, the explorer drove the record back lap by lap,
ran out of time, and the lost robot was handed over again: the same 300 s, fourteen times, to
the end of the run (7 islands in 7200 s). Public API: `core.graph.without_loops`.
"""

from __future__ import annotations

import math

import pytest
from island_mapping.core.explore import ExploreError, ExplorerConfig
from island_mapping.core.graph import reverse_strategy, strategy_displacement, without_loops
from island_msgs_py.types import ControlStrategy, PrimitiveKind, StrategyPrimitive

GO, ROT = PrimitiveKind.GO, PrimitiveKind.ROT


def strategy(*steps: tuple[PrimitiveKind, int]) -> ControlStrategy:
    return ControlStrategy(tuple(StrategyPrimitive(k, v) for k, v in steps))


def go_m(s: ControlStrategy) -> float:
    return sum(p.metres for p in s.steps)


def same_end(a: ControlStrategy, b: ControlStrategy) -> bool:
    pa, pb = strategy_displacement(a), strategy_displacement(b)
    return math.hypot(pa.x - pb.x, pa.y - pb.y) < 0.05 and abs(
        math.remainder(pa.theta - pb.theta, 2 * math.pi)) < math.radians(1.5)


def test_laps_round_a_room_are_cut_and_the_end_is_kept() -> None:
    """In 3 m, three laps of a 2 x 2 m room, then 1.5 m on to the far wall."""
    lap = [(GO, 200), (ROT, 90)] * 4
    way = strategy((GO, 300), (ROT, 90), *lap * 3, (GO, 150), (ROT, 45))
    short = without_loops(way, 0.4, 3.0)
    assert same_end(short, way)
    assert go_m(short) < 5.0 < go_m(way)  # 4.5 m of driving for 28.5 m
    assert same_end(reverse_strategy(reverse_strategy(short)), short)


def test_a_way_without_loops_is_unchanged() -> None:
    way = strategy((GO, 300), (ROT, 90), (GO, 500), (ROT, 270), (GO, 800))
    assert without_loops(way, 0.4, 3.0) is way


def test_a_short_wiggle_is_not_a_loop() -> None:
    """Coming back within within_m after less than min_loop_m of path (a turn at a door)."""
    way = strategy((GO, 100), (ROT, 180), (GO, 20), (ROT, 180), (GO, 400))
    assert without_loops(way, 0.4, 3.0) is way


def test_off_keeps_the_whole_way() -> None:
    lap = [(GO, 200), (ROT, 90)] * 4
    way = strategy((GO, 300), *lap)
    assert without_loops(way, 0.0, 3.0) is way


@pytest.mark.parametrize("bad", [{"return_shortcut_m": -0.1}, {"return_loop_m": 0.0}])
def test_bad_return_settings_are_refused_by_name(bad: dict[str, float]) -> None:
    with pytest.raises(ExploreError, match=next(iter(bad))):
        ExplorerConfig(**bad)  # type: ignore[arg-type]
