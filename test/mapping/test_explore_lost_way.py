"""A lost robot's way: back to the island it left, and as the next edge's prefix (issue 16).

Office 11 seed 3 was lost eight times in a row beside island 13: after each failed way back
the explorer handed the robot over "by no exit" with the record of its own moves since the
dock as the prefix, which leaves out every stretch the hall follower drove and repeats the
returns tried. The next way back replayed that record reversed and led elsewhere, and the
edges built from such prefixes (32-37 primitives) were a wander no route could replay.

Here the explorer runs against a scripted robot in open space (no echoes: no look localizes):
it departs from island 0, the "follower" drives an L, the builder stops it, the way back ends
in a look that fails (the second look, which would drive to the origin, is off), and the
explorer hands the robot over as lost. Public API: `Explorer.step`.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.builder import BuilderEvent, EventKind
from island_mapping.core.explore import ExploreError, Explorer, ExplorerConfig, Handover
from island_mapping.core.graph import TopoGraph, strategy_displacement
from island_mapping.core.route import Sense
from island_msgs_py.types import (
    ControlStrategy,
    Exit,
    ExitUpdate,
    Island,
    LineModel,
    ModelType,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
)

DT_S = 0.1
GO = PrimitiveKind.GO
N_BEAMS = 16


class Robot:
    """Unicycle kinematics with exact odometry, a ring that never echoes."""

    def __init__(self, start: Pose2D) -> None:
        self.pose = start
        self.t_s = 0.0

    def sense(self) -> Sense:
        angles = np.linspace(-math.pi, math.pi, N_BEAMS, endpoint=False)
        return Sense(self.t_s, self.pose, np.full(N_BEAMS, np.inf), angles)

    def move(self, v_mps: float, w_radps: float) -> None:
        p = self.pose
        th = p.theta + w_radps * DT_S
        self.pose = Pose2D(p.x + v_mps * DT_S * math.cos(p.theta),
                           p.y + v_mps * DT_S * math.sin(p.theta),
                           math.remainder(th, 2.0 * math.pi))
        self.t_s += DT_S


def _follower_l() -> list[tuple[float, float]]:
    """The hall follower's stretch (v, w): 3 m on, a quarter turn left while driving, 2 m on."""
    return ([(0.5, 0.0)] * 60 + [(0.3, 0.5 * math.pi / 2.0)] * 20 + [(0.5, 0.0)] * 40)


ORIGIN = Pose2D(1.0, 2.0, 0.3)
"""Island 0's origin in odometry, where the robot stands when the builder hands it back."""


def _handed_back_at_island_0(cfg: ExplorerConfig) -> tuple[Explorer, Robot]:
    """An explorer whose map holds island 0 (one unexplored exit along theta 0, no model),
    told that the builder has just handed the robot back there."""
    ex = Explorer(cfg)
    island = Island(0, LineModel(np.zeros((0, 4))), ModelType.LINE, 1.0, 0.0,
                    exits=(Exit(0, 0.0, 1.0),))
    ex.on_graph(TopoGraph.from_parts([island], []))
    ex.on_events([BuilderEvent(EventKind.HANDED_BACK, 0.0, ORIGIN, 0.1, anchor_odom=ORIGIN,
                               accepted_island_id=0)])
    return ex, Robot(ORIGIN)


def _run_until_lost(cfg: ExplorerConfig) -> tuple[Handover, Pose2D, Pose2D]:
    """(the lost handover, the robot's odometry then, island 0's origin in odometry)."""
    ex, robot = _handed_back_at_island_0(cfg)
    script: list[tuple[float, float]] = []
    driven_m = 0.0
    for _ in range(40_000):
        out = ex.step(robot.sense())
        for r in out.requests:
            if isinstance(r, Handover) and r.exit_index is None:
                return r, robot.pose, ORIGIN
            if isinstance(r, Handover):
                script = _follower_l()
        if out.drive:
            robot.move(out.v_mps, out.w_radps)
        elif script:
            v, w = script.pop(0)
            robot.move(v, w)
            # The follower's own record: Rot only for turns in place, so its L is one Go.
            driven_m += v * DT_S
            ex.on_strategy(ControlStrategy((StrategyPrimitive(GO, round(100 * driven_m)),)))
            if not script:  # the builder stops the follower
                ex.on_events([BuilderEvent(EventKind.STOPPED, robot.t_s, robot.pose, 0.5)])
        else:
            robot.move(0.0, 0.0)
    raise AssertionError("the explorer never handed the robot over as lost")


def test_a_lost_robots_way_back_and_prefix_are_the_way_it_drove() -> None:
    """The way back retraces the follower's L to island 0's origin (exact odometry here), and
    the prefix ends where odometry puts the robot in island 0's frame, the out-and-back cut."""
    handover, odom, origin = _run_until_lost(ExplorerConfig(relocalize_max_shift_m=0.0))
    truth = odom.relative_to(origin)
    assert math.hypot(truth.x, truth.y) < 0.3  # back at the origin
    end = strategy_displacement(handover.prefix)
    assert math.hypot(end.x - truth.x, end.y - truth.y) < 0.3
    assert abs(math.remainder(end.theta - truth.theta, 2.0 * math.pi)) < math.radians(5.0)
    assert sum(s.metres for s in handover.prefix.steps) < 1.0


def test_off_the_way_back_and_prefix_are_the_records() -> None:
    """way_tolerance_m 0: the way back is the follower's record reversed, one straight
    Go for its L, and ends metres from the origin; the prefix, the explorer's own moves (that
    way back, not the L), ends metres from the robot."""
    handover, odom, origin = _run_until_lost(
        ExplorerConfig(way_tolerance_m=0.0, relocalize_max_shift_m=0.0))
    truth = odom.relative_to(origin)
    assert math.hypot(truth.x, truth.y) > 1.0
    end = strategy_displacement(handover.prefix)
    assert math.hypot(end.x - truth.x, end.y - truth.y) > 1.0


@pytest.mark.parametrize("bad", [-0.5, math.nan])
def test_a_bad_tolerance_is_refused_by_name(bad: float) -> None:
    with pytest.raises(ExploreError, match="way_tolerance_m"):
        ExplorerConfig(way_tolerance_m=bad)


def test_a_handover_in_the_step_of_a_hand_back_waits_for_the_builder() -> None:
    """The map holds the island when the builder hands back, and the departure needs no
    motion (the robot faces the exit, a lane from the origin): the whole choice runs in that
    one step. The hand-back event of that step came before the handover and must not end the
    new trip at once (office 11 seed 2 at 7200 s: the exit was marked blocked, the explorer
    drove on by the map while the builder followed, and the next dock raised BuilderError)."""
    ex, robot = _handed_back_at_island_0(ExplorerConfig())
    out = ex.step(robot.sense())
    assert any(isinstance(r, Handover) and r.exit_index == 0 for r in out.requests)
    assert not any(isinstance(r, ExitUpdate) for r in out.requests)  # not blocked at once
    assert not out.drive and not ex.done  # the builder side drives now
