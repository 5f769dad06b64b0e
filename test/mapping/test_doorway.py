"""A departure with no lane passes the narrow doorway its exit leads to (`core.explore.doorway`):
a look finds the doorway's wall and jambs, the robot stands before its middle and drives
through. A 0.74 m doorway in a 0.12 m wall leaves the 0.5 m robot 0.12 m a side; the house
is turned off the odometry axes. Public APIs: `core.explore` (`drive_departure`,
`DeparturePlan`, `ExplorerConfig`, `DoorwayConfig`, `pass_doorway`) and the simulator harness
`evaluation.navigate.SimRunner`."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from island_mapping.core.explore import (
    DeparturePlan,
    DoorwayConfig,
    ExploreError,
    ExplorerConfig,
    drive_departure,
    pass_doorway,
)
from island_mapping.core.route import NavigateConfig
from island_mapping.evaluation.navigate import SimRunner, SimSetup
from island_msgs_py.hall_perception import HallPerceptionConfig
from island_msgs_py.types import Pose2D
from island_sim.core.robot import SimRobot
from island_sim.core.world import World

TURN_RAD = math.radians(33.0)  # the house's turn off the odometry axes
DOOR_Y, DOOR_W, WALL_T = 2.0, 0.74, 0.12  # the west wall's doorway (room frame) [m]


def _turn(x: float, y: float) -> tuple[float, float]:
    c, s = math.cos(TURN_RAD), math.sin(TURN_RAD)
    return c * x - s * y, s * x + c * y


def _house(door: bool) -> World:
    """A 4 x 4 m room (x 0..4) whose west wall (x -0.12..0) has a doorway at y 2, and a 1 m
    hallway behind it, turned by TURN_RAD."""
    lo, hi = (DOOR_Y - 0.5 * DOOR_W, DOOR_Y + 0.5 * DOOR_W) if door else (DOOR_Y, DOOR_Y)
    segs = [[0, 0, 4, 0], [4, 0, 4, 4], [4, 4, 0, 4],
            [0, 0, 0, lo], [0, lo, -WALL_T, lo], [-WALL_T, lo, -WALL_T, 0],
            [0, hi, 0, 4], [0, hi, -WALL_T, hi], [-WALL_T, hi, -WALL_T, 4],
            [-WALL_T - 1.0, -1, -WALL_T - 1.0, 5], [-WALL_T - 1.0, -1, -WALL_T, -1],
            [-WALL_T - 1.0, 5, -WALL_T, 5], [-WALL_T, -1, -WALL_T, 0], [-WALL_T, 4, -WALL_T, 5]]
    turned = [[*_turn(a, b), *_turn(c, d)] for a, b, c, d in segs]
    return World(np.array(turned, dtype=float), "house")


def _run(world: World, room_xy: tuple[float, float], off_deg: float, seed: int,
         cfg: ExplorerConfig) -> tuple[bool, SimRobot]:
    """Depart from room_xy (room frame) along the bearing to the doorway's middle, off_deg
    off it, as with no lane seen; (left, robot)."""
    x, y = _turn(*room_xy)
    mx, my = _turn(0.0, DOOR_Y)
    start = Pose2D(x, y, 0.4)
    heading = math.atan2(my - y, mx - x) + math.radians(off_deg)
    setup = SimSetup(world=world)
    rng = np.random.default_rng(seed)
    robot = SimRobot(world, start, rng, setup.robot, setup.odometry, track_covariance=False)
    sim = SimRunner(setup, robot, rng, NavigateConfig())
    plan = DeparturePlan((), heading - start.theta)
    left = sim.run(drive_departure(sim.drive, plan, start, cfg, HallPerceptionConfig()))
    return bool(left), robot


def _room_x(robot: SimRobot) -> float:
    """The robot's x in the room frame (< -WALL_T: through the west wall)."""
    p = robot.true_pose
    return math.cos(TURN_RAD) * p.x + math.sin(TURN_RAD) * p.y


@pytest.mark.parametrize("room_xy, off_deg, seed", [
    ((1.6, 2.1), 8.0, 1), ((1.5, 1.2), -8.0, 2), ((2.0, 3.0), 6.0, 3)])
def test_with_no_lane_the_robot_passes_a_narrow_doorway_at_its_middle(
        room_xy: tuple[float, float], off_deg: float, seed: int) -> None:
    left, robot = _run(_house(door=True), room_xy, off_deg, seed, ExplorerConfig())
    assert left
    assert _room_x(robot) < -WALL_T - 0.3  # in the hallway behind the doorway
    assert robot.collisions == 0


def test_a_wall_without_a_doorway_is_not_driven_into() -> None:
    """The look finds the wall and no doorway in it: the robot stays in the room."""
    left, robot = _run(_house(door=False), (1.6, 2.1), 8.0, 1, ExplorerConfig())
    assert left  # handed over where the look left it, as a departure with no lane is
    assert _room_x(robot) > 0.25
    assert robot.collisions == 0


def test_pass_doorway_says_when_no_wall_is_met() -> None:
    """No wall within a look's reach, nor after the approach: pass_doorway drives the
    approach and reports no doorway."""
    world = _house(door=True)
    setup = SimSetup(world=world)
    rng = np.random.default_rng(4)
    x, y = _turn(2.0, 0.8)
    north = TURN_RAD + 0.5 * math.pi
    start = Pose2D(x, y, north)  # facing the north wall, 3.2 m away
    robot = SimRobot(world, start, rng, setup.robot, setup.odometry, track_covariance=False)
    sim = SimRunner(setup, robot, rng, NavigateConfig())
    found = sim.run(pass_doorway(sim.drive, north, DoorwayConfig(), 1.0, 1.5))
    assert found is False
    assert robot.collisions == 0
    assert math.hypot(robot.true_pose.x - x, robot.true_pose.y - y) == pytest.approx(1.0, abs=0.1)


@pytest.mark.parametrize("field, value", [("approach_m", 0.0), ("refines", -1),
                                          ("cone_rays", 0), ("enabled", "yes"),
                                          ("see_through_m", math.nan)])
def test_a_bad_doorway_config_names_the_field(field: str, value: object) -> None:
    with pytest.raises(ExploreError, match=field):
        dataclasses.replace(DoorwayConfig(), **{field: value})
