"""Motion primitives stop where the robot is blocked (a wall the sonar missed, e.g. a door
jamb beside the robot), after backing off and trying again a few times, instead of pushing
until the edge's time limit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.route import (
    Drive,
    NavigateConfig,
    Sense,
    go_along_hall,
    look_around,
    stalled,
)
from island_msgs_py.types import Pose2D

ANGLES = np.linspace(-math.pi, math.pi, 16, endpoint=False)


def _run(wall_at_m: float | None, retries: int = 2, inferred: bool = False
         ) -> tuple[int, int, float]:
    """(periods, back-offs, how far it got [m]) of go_along_hall(2 m) on a robot moving
    0.04 m per period forward (0.015 m back), held by a wall ahead at wall_at_m (a contact the
    sonar missed: a door jamb beside). inferred: no contact sensor, the robot infers it from its
    command and odometry's speed (`stalled`, as the explorer node does)."""
    sense = Sense(0.0, Pose2D(0.0, 0.0, 0.0), np.full(16, np.inf), ANGLES)
    motion = go_along_hall(Drive(sense, NavigateConfig(contact_retries=retries)), 2.0)
    periods = backoffs = 0
    backing = False
    for v, _w in motion:
        periods += 1
        x = sense.odom.x
        step_m = 0.04 if v > 0 else -0.015 if v < 0 else 0.0
        held = wall_at_m is not None and v > 0 and x + step_m > wall_at_m
        backoffs += v < 0 and not backing
        backing = v < 0
        sense.t_s += 0.1
        sense.odom = Pose2D(x if held else x + step_m, 0.0, 0.0)
        measured_mps = (sense.odom.x - x) / 0.1
        sense.blocked = stalled(v, measured_mps) if inferred else held
        assert periods < 10_000, "never stopped"
    return periods, backoffs, sense.odom.x


def test_go_along_hall_backs_off_a_contact_then_stops_there() -> None:
    free, backoffs, got = _run(None)
    assert free > 40 and backoffs == 0 and got == pytest.approx(2.0, abs=0.05)
    periods, backoffs, got = _run(0.4)
    assert backoffs == 2  # contact_retries: backed off and went on twice
    assert got <= 0.4 and periods < 100  # then stopped at the wall, not pushing on
    assert _run(0.4, retries=0)[1] == 0  # no retries: stops at the first contact


def test_a_stall_inferred_from_odometry_stops_the_go_as_a_contact_does() -> None:
    """Without a contact sensor (the explorer node hears only odometry) a forward command that
    odometry shows did not move the robot counts as the wall's contact: the same back-offs and
    the same stop; in the open nothing is inferred."""
    assert _run(0.4, inferred=True) == _run(0.4)
    assert _run(None, inferred=True) == _run(None)
    assert not stalled(0.3, 0.25) and not stalled(0.0, 0.0) and not stalled(-0.1, 0.0)
    assert stalled(0.3, 0.0) and stalled(0.3, -1e-4)


# A room (x < 1) whose east wall (0.5 m thick, x = 1.0-1.5) has a 1 m door at -0.5 < y < 0.5,
# a hallway beyond; the same geometry as a generated office's room door.
DOOR_ROOM = np.array([
    [1.0, -3.0, 1.0, -0.5], [1.0, -0.5, 1.5, -0.5], [1.5, -0.5, 1.5, -3.0],
    [1.0, 3.0, 1.0, 0.5], [1.0, 0.5, 1.5, 0.5], [1.5, 0.5, 1.5, 3.0],
    [-3.0, -3.0, 1.0, -3.0], [-3.0, 3.0, 1.0, 3.0], [-3.0, -3.0, -3.0, 3.0],
    [1.5, -3.0, 3.5, -3.0], [1.5, 3.0, 3.5, 3.0], [3.5, -3.0, 3.5, 3.0],
])


@pytest.mark.parametrize("heading_deg", [-5.0, 0.0, -10.0])
def test_a_go_through_a_door_started_off_its_middle_passes_the_jamb(heading_deg: float) -> None:
    """The robot stands 0.6 m before the door, 0.37 m off its middle (where an island in a
    room put its origin), and a strategy says Go 2 m through it. Only the near jamb echoes
    (on one oblique transducer, inside the robot's path); the way straight ahead is free.
    The Go steers past the jamb and through the door instead of stopping at once (it did,
    and the route ended as a deviation)."""
    from island_mapping.evaluation.navigate import SimRunner, SimSetup
    from island_sim.core.robot import SimRobot
    from island_sim.core.world import World

    setup = SimSetup(world=World(DOOR_ROOM, "door"))
    rng = np.random.default_rng(4)
    robot = SimRobot(setup.world, Pose2D(0.4, 0.37, math.radians(heading_deg)), rng,
                     setup.robot, setup.odometry, track_covariance=False)
    sim = SimRunner(setup, robot, rng, NavigateConfig())
    got = sim.run(go_along_hall(sim.drive, 2.0))
    assert got == pytest.approx(2.0, abs=0.05)
    assert robot.true_pose.x > 2.0  # through the door, into the hallway


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_jamb_heard_before_the_go_is_remembered(seed: int) -> None:
    """An island 0.5 m before a 1 m door in a 0.5 m wall, its origin 0.2 m off the door's
    middle (office seed 11, island 27): the look-around on arrival heard the near jamb's
    corner inside the robot's path, the scans of the Go that followed did not, and the robot
    drove onto the corner (4 contacts, stuck in the door). A Go remembers the echoes of the
    last scans, the look-around's too, and steers past the corner through the door."""
    from island_mapping.evaluation.navigate import SimRunner, SimSetup
    from island_sim.core.robot import SimRobot
    from island_sim.core.world import World

    setup = SimSetup(world=World(DOOR_ROOM, "door"))
    rng = np.random.default_rng(seed)
    robot = SimRobot(setup.world, Pose2D(2.03, -0.2, math.pi), rng, setup.robot,
                     setup.odometry, track_covariance=False)
    sim = SimRunner(setup, robot, rng, NavigateConfig())
    sim.run(look_around(sim.drive))
    got = sim.run(go_along_hall(sim.drive, 2.0, remember=True))
    assert got == pytest.approx(2.0, abs=0.05)
    assert robot.true_pose.x < 0.5  # through the door, into the room
    assert robot.collisions == 0


@pytest.mark.parametrize(("y_m", "heading_deg", "seed"),
                         [(0.24, 8.0, 1), (0.245, 0.0, 2), (-0.24, -8.0, 3), (0.2, 10.0, 1)])
def test_a_go_touching_a_jamb_the_ring_cannot_hear_moves_off_it(
        y_m: float, heading_deg: float, seed: int) -> None:
    """The robot stands in a 1 m door's passage touching a jamb (an island's origin there:
    paper_fig4 seed 3, island 5, 0.25 m off the door's middle), nearer than the sonar's
    shortest range, so only the other jamb echoes and centring steers it onto the one it
    touches. Backing off onto the same lane touched again until the Go stopped in the door
    (the route failed there six times, 1900 s of the run); after a contact it moves its lane
    away from the side touched and drives through."""
    from island_mapping.evaluation.navigate import SimRunner, SimSetup
    from island_sim.core.robot import SimRobot
    from island_sim.core.world import World

    setup = SimSetup(world=World(DOOR_ROOM, "door"))
    rng = np.random.default_rng(seed)
    robot = SimRobot(setup.world, Pose2D(0.9, y_m, math.radians(heading_deg)), rng,
                     setup.robot, setup.odometry, track_covariance=False)
    sim = SimRunner(setup, robot, rng, NavigateConfig())
    got = sim.run(go_along_hall(sim.drive, 2.0, remember=True))
    assert got == pytest.approx(2.0, abs=0.05)
    assert robot.true_pose.x > 2.0  # through the door, into the hallway
    assert robot.collisions <= 3
