"""Which lane the explorer drives to leave an island by an exit (`core.explore.departure`):
a lane must run along the exit or along an island axis; a diagonal lane whose entry merely
lies toward the exit is not driven (the robot would be handed over facing across the
hallway); with no lane seen, the robot drives on along the exit through the doorway it points
at. Public APIs: `core.explore` (`choose_lane`, `drive_departure`, `DeparturePlan`),
`core.explore.exits.Lane`, and the simulator harness `evaluation.navigate.SimRunner`."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.explore import DeparturePlan, ExplorerConfig, choose_lane, drive_departure
from island_mapping.core.explore.exits import Lane
from island_mapping.core.route import NavigateConfig
from island_mapping.evaluation.navigate import SimRunner, SimSetup
from island_msgs_py.hall_perception import HallPerceptionConfig
from island_msgs_py.types import Exit, Pose2D
from island_sim.core.robot import SimRobot
from island_sim.core.world import World

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


# A 4 x 4 m room (x 0..4) with a 0.8 m doorway in its west wall at y = 0, and a hallway
# outside it along y (x -2..0) [m].
ROOM_AND_HALL = np.array([[0, -2, 0, -0.4], [0, 0.4, 0, 2], [0, 2, 4, 2], [4, 2, 4, -2],
                          [4, -2, 0, -2], [-2, -4, -2, 4], [-2, 4, 0, 4], [0, 4, 0, 2],
                          [-2, -4, 0, -4], [0, -4, 0, -2]], dtype=float)
ORIGIN = Pose2D(1.1, 0.25, 0.0)  # the island's origin, true and odometric


def _sim(seed: int, start: Pose2D = ORIGIN) -> tuple[SimRunner, SimRobot]:
    setup = SimSetup(world=World(ROOM_AND_HALL, "room"))
    rng = np.random.default_rng(seed)
    robot = SimRobot(setup.world, start, rng, setup.robot, setup.odometry,
                     track_covariance=False)
    return SimRunner(setup, robot, rng, NavigateConfig()), robot


@pytest.mark.parametrize("seed, origin", [(1, ORIGIN), (2, ORIGIN), (3, Pose2D(1.8, -0.3, 0.0))])
def test_with_no_lane_seen_the_robot_passes_the_doorway_the_exit_points_at(
        seed: int, origin: Pose2D) -> None:
    """No lane (the sonar's cones close a 0.8 m doorway): the robot turns to the exit and
    drives on through the doorway's middle, without touching a jamb."""
    sim, robot = _sim(seed, origin)
    plan = DeparturePlan((), math.atan2(-origin.y, -origin.x))
    left = sim.run(drive_departure(sim.drive, plan, origin, CFG, HallPerceptionConfig()))
    assert left
    assert robot.true_pose.x < -0.2  # out of the room, in the hallway
    assert robot.collisions == 0


def test_a_wall_close_ahead_closes_the_exit_and_the_robot_stays_at_the_origin() -> None:
    near = Pose2D(3.3, 0.0, 0.0)  # 0.7 m from the east wall, facing it
    sim, robot = _sim(1, near)
    assert not sim.run(drive_departure(sim.drive, DeparturePlan((), 0.0), near, CFG,
                                       HallPerceptionConfig()))
    assert math.hypot(robot.true_pose.x - near.x, robot.true_pose.y - near.y) < 0.1
