"""Arrivals that are right when they say so (issue 16): a room that fits itself turned (a
square, a + junction) leaves an arrival unsure once the robot has turned enough since its last
trusted fix for odometry's heading to be a quarter turn off (`NavigateConfig.alias_after_deg`,
`core.route.arrival.turned_alias`). Public APIs: `core.route`, the simulator's robot and sonar.
"""

from __future__ import annotations

import math

import numpy as np
from island_mapping.core.route import Drive, NavigateConfig, Sense
from island_mapping.core.route.arrival import Fix, localize_and_dock
from island_msgs_py.raycast import NearbyRayCaster
from island_msgs_py.types import FloatArray, Island, LineModel, ModelType, Pose2D
from island_sim.core.robot import SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import world_from_dict

# A square room 3 x 3 m (its middle at 0, 0) and an L-shaped one; island models in the frame
# of their middle, as a star would have mapped their walls.
SQUARE = np.array([[-1.5, -1.5, 1.5, -1.5], [1.5, -1.5, 1.5, 1.5], [1.5, 1.5, -1.5, 1.5],
                   [-1.5, 1.5, -1.5, -1.5]])
ELL = np.array([[-1.5, -1.5, 3.5, -1.5], [3.5, -1.5, 3.5, 0.0], [3.5, 0.0, 1.5, 0.0],
                [1.5, 0.0, 1.5, 1.5], [1.5, 1.5, -1.5, 1.5], [-1.5, 1.5, -1.5, -1.5]])


def _arrive(segments: FloatArray, spun_deg: float) -> tuple[Fix, float]:
    """Arrive at the room's island with odometry 0.1 m, 5 deg off and `spun_deg` turned since
    the last fix: the fix, and the turn left to count after it [deg]."""
    world = world_from_dict({"segments": segments.tolist(), "start_pose": [0.2, -0.1, 0.3]})
    rng = np.random.default_rng(3)
    robot = SimRobot(world, world.start_pose, rng)
    sonar, near = SonarModel(SonarConfig()), NearbyRayCaster(world, 6.5)
    sense = Sense(0.0, robot.odom_pose, sonar.scan(near, robot.true_pose, rng), sonar.angles_rad)
    drive = Drive(sense, NavigateConfig(dock_attempts=1))
    drive.deadline_s, drive.spun_rad = 120.0, math.radians(spun_deg)
    island = Island(0, LineModel(segments), ModelType.LINE, 1.0, 0.0)
    estimate = Pose2D(0.3, -0.1, 0.3 + math.radians(5.0))
    gen = localize_and_dock(drive, island, estimate)
    try:
        while True:
            v, w = next(gen)
            for _ in range(5):
                robot.step(v, w, 0.02)
            sense.t_s, sense.odom = robot.time_s, robot.odom_pose
            sense.ranges_m = sonar.scan(near, robot.true_pose, rng)
    except StopIteration as stop:
        return stop.value, math.degrees(drive.spun_rad)


def test_a_square_room_fits_itself_turned_so_a_long_spin_leaves_the_arrival_unsure() -> None:
    fix, _ = _arrive(SQUARE, spun_deg=0.0)
    assert fix.trusted  # turned little since the last fix: the heading tells the turn
    fix, _ = _arrive(SQUARE, spun_deg=20000.0)
    assert not fix.trusted  # a quarter turn off fits as well: which one is unknown
    fix, left = _arrive(ELL, spun_deg=20000.0)
    assert fix.trusted and abs(fix.pose.x - 0.2) < 0.3  # an L fits one way only
    assert left < 360.0 * 3  # counted afresh from the trusted fix
