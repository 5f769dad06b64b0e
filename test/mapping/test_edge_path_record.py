"""An edge's strategy from the way the robot drove (`BuilderConfig.edge_path_tolerance_m`):
the odometric path simplified to a polyline, whatever the follower recorded of its own
primitives (turning while driving is not in its record)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from island_mapping.core.builder import (
    BuilderConfig,
    CommandMode,
    EventKind,
    IslandBuilder,
    PathRecord,
    strategy_from_path,
)
from island_mapping.core.graph import strategy_displacement
from island_msgs_py.types import ControlStrategy, Pose2D, PrimitiveKind
from island_sim.core.robot import OdometryConfig, SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World


def _kinds(s: ControlStrategy) -> str:
    return "".join("G" if p.kind is PrimitiveKind.GO else "R" for p in s.steps)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_corner_driven_round_while_moving_becomes_go_rot_go(seed: int) -> None:
    """5 m east then 3 m north, centring wobble of 10 cm and a rounded corner: a long leg
    east, a quarter turn (in one or two Rots, with a short leg across the rounded corner), a
    long leg north, ending at the heading the robot ended with."""
    rng = np.random.default_rng(seed)
    east = [(x, 0.1 * math.sin(2.0 * x) + rng.normal(0, 0.01)) for x in np.arange(0, 4.6, 0.05)]
    arc = [(4.6 + 0.4 * math.sin(a), 0.4 - 0.4 * math.cos(a))
           for a in np.linspace(0, 0.5 * math.pi, 10)]
    north = [(5.0 + 0.1 * math.sin(2.0 * y), y) for y in np.arange(0.4, 3.0, 0.05)]
    s = strategy_from_path(np.array(east + arc + north), 0.0, 0.5 * math.pi, 0.25)
    gos = [p.value for p in s.steps if p.kind is PrimitiveKind.GO]
    assert gos[0] >= 440 and gos[-1] >= 220 and all(g < 100 for g in gos[1:-1]), str(s)
    first, last = (k for k, p in enumerate(s.steps) if p.kind is PrimitiveKind.GO and (
        p.value in (gos[0], gos[-1])))
    turn = sum(p.value for p in s.steps[first:last] if p.kind is PrimitiveKind.ROT) % 360
    assert abs(turn - 90) <= 8, str(s)
    end = strategy_displacement(s)
    assert math.hypot(end.x - north[-1][0], end.y - north[-1][1]) < 0.15
    assert abs(math.degrees(end.theta) % 360 - 90) <= 1


def test_a_dead_end_keeps_its_far_end_and_a_back_off_vanishes() -> None:
    """Out 3 m, back 2 m, then north 2 m (a dead end probed): Go, Rot 180, Go, Rot, Go. A
    back-off of 0.3 m on the way out leaves no trace."""
    rec = PathRecord(0.25)
    rec.restart(Pose2D(0.0, 0.0, 0.0))
    for x in [*np.arange(0, 1.5, 0.01), *np.arange(1.5, 1.2, -0.01), *np.arange(1.2, 3, 0.01)]:
        rec.add(Pose2D(float(x), 0.0, 0.0))
    for x in np.arange(3.0, 1.0, -0.01):
        rec.add(Pose2D(float(x), 0.0, math.pi))
    for y in np.arange(0.0, 2.0, 0.01):
        rec.add(Pose2D(1.0, float(y), 0.5 * math.pi))
    s = rec.strategy()
    assert _kinds(s) in ("GRGRG", "GRGRGR"), str(s)
    assert [p.value for p in s.steps[:4]] == [pytest.approx(300, abs=4), 180,
                                              pytest.approx(200, abs=4),
                                              pytest.approx(270, abs=2)]


def test_a_long_record_stays_bounded_and_right() -> None:
    """50 000 positions along a zigzag corridor walk (past the record's cap): the strategy
    still ends where the robot did."""
    rec = PathRecord(0.25)
    rec.restart(Pose2D(0.0, 0.0, 0.0))
    x = y = 0.0
    for k in range(50_000):
        heading = 0.0 if (k // 5000) % 2 == 0 else 0.5 * math.pi
        x, y = x + 0.06 * math.cos(heading), y + 0.06 * math.sin(heading)
        rec.add(Pose2D(x, y, heading))
    end = strategy_displacement(rec.strategy())
    assert math.hypot(end.x - x, end.y - y) < 0.5  # 3 km of legs, rounded to 1 deg and 1 cm
    assert _kinds(rec.strategy()).count("G") == 10


def test_a_lap_round_a_room_and_a_shuttle_are_cut_from_the_way() -> None:
    """In through a doorway (2 m north), once round a 4 x 3 m room, back and forth along its
    wall, then 2 m east: with loops cut the way is in and east (both laps gone), ending
    where the robot did; without, the laps stay."""
    def walk(rec: PathRecord) -> None:
        rec.restart(Pose2D(0.0, 0.0, 0.5 * math.pi))
        pts = [(0.0, y) for y in np.arange(0.0, 2.0, 0.02)]
        lap = [(0.0, 2.0), (2.0, 2.0), (2.0, 5.0), (-2.0, 5.0), (-2.0, 2.0), (0.0, 2.0)]
        for a, b in itertools.pairwise(lap):
            pts += [(a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
                    for t in np.linspace(0.0, 1.0, 60, endpoint=False)]
        pts += [(x, 2.0) for x in np.arange(0.0, -1.8, -0.02)]  # shuttle west and back
        pts += [(x, 2.0) for x in np.arange(-1.8, 2.0, 0.02)]  # then on east to x = 2
        for x, y in pts:
            rec.add(Pose2D(float(x), float(y), 0.0))
    cut, kept = PathRecord(0.25, shortcut_m=0.4, loop_m=3.0), PathRecord(0.25)
    walk(cut)
    walk(kept)
    go = [sum(p.metres for p in r.strategy().steps if p.kind is PrimitiveKind.GO)
          for r in (cut, kept)]
    assert go[0] < 5.0 < 17.0 < go[1], (str(cut.strategy()), str(kept.strategy()))
    for r in (cut, kept):  # the displacement is in the frame of the start, facing north
        end = Pose2D(0.0, 0.0, 0.5 * math.pi).compose(strategy_displacement(r.strategy()))
        assert math.hypot(end.x - 2.0, end.y - 2.0) < 0.2


def test_a_record_that_is_off_keeps_nothing() -> None:
    """tolerance_m 0 (the builder's default: edges keep the follower's record)."""
    rec = PathRecord(0.0)
    rec.restart(Pose2D(0.0, 0.0, 0.0))
    for x in np.arange(0.0, 5.0, 0.01):
        rec.add(Pose2D(float(x), 0.1 * math.sin(float(x)), 0.0))
    assert str(rec.strategy()) == ""


def _l_world() -> World:
    """A 2 m corridor east 12 m, then north 10 m to a dead end."""
    segs = [[-4.0, -1.0, 11.0, -1.0], [11.0, -1.0, 11.0, 11.0], [-4.0, 1.0, 9.0, 1.0],
            [9.0, 1.0, 9.0, 11.0], [9.0, 11.0, 11.0, 11.0], [-4.0, -1.0, -4.0, 1.0]]
    return World(np.array(segs), "L")


@pytest.mark.parametrize("tolerance_m", [0.0, 0.25])
def test_the_edge_follows_the_way_driven_not_the_followers_record(tolerance_m: float) -> None:
    """A stand-in follower drives the L, steering round the corner while driving, and records
    `Go 2000` (its turns while driving are not in its record). With edge_path_tolerance_m the
    edge from island 0 (the start) to the next island (at the corner) drives the way the robot
    went; without it the edge keeps the record."""
    world, start = _l_world(), Pose2D(-3.0, 0.0, 0.0)
    builder = IslandBuilder(BuilderConfig(edge_path_tolerance_m=tolerance_m))
    rng = np.random.default_rng(1)
    robot = SimRobot(world, start, rng, odometry=OdometryConfig.exact())
    sonar = SonarModel(SonarConfig(), seed=1)
    t, accepted = 0.0, []
    builder.on_odometry(t, robot.odom_pose, np.zeros((3, 3)))
    for _ in range(3000):
        builder.on_scan(t, sonar.scan(world, robot.true_pose, rng), sonar.angles_rad)
        builder.set_strategy(ControlStrategy.parse("Go 2000"))
        cmd = builder.command(t)
        accepted += [e for e in cmd.events if e.kind is EventKind.ISLAND_ACCEPTED]
        if len(accepted) == 2:
            break
        v, w = cmd.v_mps, cmd.w_radps
        if cmd.mode is CommandMode.FOLLOW:
            p = robot.true_pose
            goal = 0.0 if p.x < 9.6 else 0.5 * math.pi  # east, then north round the corner
            off = -p.y if goal == 0.0 else p.x - 10.0
            v = 0.4 if p.y < 8.5 else 0.0
            w = float(np.clip(2.0 * math.remainder(goal - p.theta, 2 * math.pi) + 1.0 * off,
                              -1.0, 1.0))
        for _ in range(5):
            robot.step(v, w, 0.02)
            t += 0.02
            s = 0.06 * (abs(robot.odom_pose.x - start.x) + abs(robot.odom_pose.y))
            builder.on_odometry(t, robot.odom_pose, np.diag([s * s, s * s, 1e-6]))
    assert len(accepted) == 2
    edge, origin, first = accepted[1].edge, accepted[1].anchor_odom, accepted[0].anchor_odom
    assert edge is not None and origin is not None and (edge.source, edge.target) == (0, 1)
    assert first is not None
    moved, want = strategy_displacement(edge.strategy), origin.relative_to(first)
    off_m = math.hypot(moved.x - want.x, moved.y - want.y)
    if tolerance_m > 0.0:
        assert want.x > 10.0  # the island is 10 m or more along the way
        assert off_m < 0.15, str(edge.strategy)
        assert abs(math.degrees(math.remainder(moved.theta - want.theta, 2 * math.pi))) <= 2
    else:
        assert str(edge.strategy).startswith("Go 2000"), str(edge.strategy)
        assert off_m > 5.0
