"""The simulated robot driven by route following by the map (paper section 8.2).

Simulator-backed (numpy + island_sim cores, no ROS). Route following itself lives in
`island_mapping.core.route` as generators of velocity commands (the explorer node runs the same
code live); `SimRunner` steps a `SimRobot` and its sonar ring one sensor period per command and
feeds the generator the new scan and odometry. `SimSetup` is what the simulated trips run on.
Whole routes and their evaluation: `evaluation.routes`.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass, field
from typing import TypeVar, cast

import numpy as np
from island_msgs_py.raycast import NearbyRayCaster
from island_sim.core.hall_follower import HallFollowerConfig
from island_sim.core.robot import OdometryConfig, RobotConfig, SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World

from island_mapping.core.route import Command, Drive, NavigateConfig, Sense

T = TypeVar("T")


@dataclass
class SimSetup:
    """What the simulated trip runs on: the world, sensor, body, odometry and hall perception."""

    world: World
    sonar: SonarConfig = field(default_factory=SonarConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    follower: HallFollowerConfig = field(default_factory=HallFollowerConfig)


class SimRunner:
    """A SimRobot and its sonar ring, stepped one sensor period per command of a route generator
    (`island_mapping.core.route`): the generator yields (v, w), the robot drives that for one
    sensor period, the new scan and odometry go into the generator's `Sense`."""

    def __init__(self, setup: SimSetup, robot: SimRobot, rng: np.random.Generator,
                 cfg: NavigateConfig) -> None:
        self.world, self.robot, self.rng, self.cfg = setup.world, robot, rng, cfg
        self.sonar = SonarModel(setup.sonar)
        # The walls in the sonar's reach of the robot: the world's echoes, cast at a fraction
        # of the cost (island_msgs_py.raycast).
        self.caster = NearbyRayCaster(setup.world, setup.sonar.range_max_m)
        self.dt = 1.0 / cfg.physics_rate_hz
        scan = self.sonar.scan(self.caster, robot.true_pose, rng)
        sense = Sense(robot.time_s, robot.odom_pose, scan, self.sonar.angles_rad,
                      robot.velocity[1], False)
        self.drive = Drive(sense, cfg, setup.follower.perception,
                           setup.follower.default_hall_width_m)

    def step(self, v_mps: float, w_radps: float) -> None:
        """One sensor period under (v, w), then the new sensing."""
        blocked = False
        for _ in range(self.cfg.steps_per_scan):
            blocked |= self.robot.step(v_mps, w_radps, self.dt).blocked
        s = self.drive.sense
        s.ranges_m = self.sonar.scan(self.caster, self.robot.true_pose, self.rng)
        s.t_s, s.odom = self.robot.time_s, self.robot.odom_pose
        s.w_radps, s.blocked = self.robot.velocity[1], blocked

    def run(self, gen: Generator[Command, None, T]) -> T:
        """Drive the robot by `gen` until it returns; its return value."""
        try:
            cmd = next(gen)
            while True:
                self.step(*cmd)
                cmd = gen.send(None)
        except StopIteration as stop:
            return cast(T, stop.value)
