"""Exploration without ROS: the closed loop the nodes run (simulator, hall follower, builder).

Simulator-backed (numpy + island_sim cores, no ROS) and deterministic for a seed: per sensor
period a scan at the true pose, the builder decides, the hall follower or the builder drives.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from island_msgs_py.raycast import NearbyRayCaster
from island_msgs_py.types import Edge, FloatArray, Island, Pose2D
from island_sim.core.hall_follower import HallFollower
from island_sim.core.robot import SimRobot
from island_sim.core.sonar import SonarModel

from island_mapping.core.builder import (
    BuilderConfig,
    BuilderEvent,
    CommandMode,
    EventKind,
    IslandBuilder,
)
from island_mapping.core.graph import TopoGraph
from island_mapping.evaluation.navigate import SimSetup


@dataclass(frozen=True)
class ExplorationResult:
    """What an exploration produced.

    islands, edges: the map; origins_odom: each island origin's odometric pose when it was built
    (for the global-odometry baseline); events: every builder event with its time; truth_path,
    odom_path: (K, 3) poses [m, m, rad] at every scan; collisions: wall contacts of the robot.
    """

    islands: tuple[Island, ...]
    edges: tuple[Edge, ...]
    origins_odom: Mapping[int, Pose2D]
    events: tuple[BuilderEvent, ...]
    truth_path: FloatArray
    odom_path: FloatArray
    collisions: int

    def graph(self) -> TopoGraph:
        return TopoGraph.from_parts(self.islands, self.edges)


def explore(
    setup: SimSetup,
    sim_s: float,
    builder_cfg: BuilderConfig | None = None,
    rng: np.random.Generator | None = None,
    start: Pose2D | None = None,
    physics_rate_hz: float = 50.0,
    sensor_rate_hz: float = 10.0,
) -> ExplorationResult:
    """Explore `setup.world` for `sim_s` simulated seconds from `start` (default: the world's).

    Per sensor period: a scan at the true pose; the builder decides; FOLLOW lets the hall
    follower drive (its strategy feeds the builder), DRIVE pauses it and applies the builder's
    twist; when an island is handed back the follower's strategy record restarts.
    """
    gen = rng if rng is not None else np.random.default_rng(0)
    world = setup.world
    robot = SimRobot(world, start or world.start_pose, gen, setup.robot, setup.odometry)
    sonar = SonarModel(setup.sonar)
    near = NearbyRayCaster(world, setup.sonar.range_max_m)  # the world's echoes, cheaper
    follower = HallFollower(setup.follower, np.random.default_rng(int(gen.integers(2**31))))
    builder = IslandBuilder(builder_cfg)
    steps = max(1, round(physics_rate_hz / sensor_rate_hz))
    dt = 1.0 / physics_rate_hz
    events: list[BuilderEvent] = []
    truth, odom = [], []
    builder.on_odometry(0.0, robot.odom_pose, robot.odom_covariance)
    builder.on_ground_truth(robot.true_pose)
    for _ in range(int(sim_s * sensor_rate_hz)):
        t = robot.time_s
        ranges = sonar.scan(near, robot.true_pose, gen)
        builder.set_strategy(follower.strategy())
        builder.on_scan(t, ranges, sonar.angles_rad)
        cmd = builder.command(t)
        events.extend(cmd.events)
        if any(
            e.kind is EventKind.HANDED_BACK and e.accepted_island_id is not None for e in cmd.events
        ):
            follower.reset_strategy()
        follower.set_enabled(cmd.mode is CommandMode.FOLLOW)
        v, w = follower.update(ranges, sonar.angles_rad, robot.odom_pose, t)
        if cmd.mode is CommandMode.DRIVE:
            v, w = cmd.v_mps, cmd.w_radps
        truth.append(robot.true_pose.as_array())
        odom.append(robot.odom_pose.as_array())
        for _ in range(steps):
            robot.step(v, w, dt)
            builder.on_odometry(robot.time_s, robot.odom_pose, robot.odom_covariance)
            builder.on_ground_truth(robot.true_pose)
    return ExplorationResult(
        tuple(builder.islands),
        tuple(builder.edges),
        dict(builder.island_origins_odom),
        tuple(events),
        np.array(truth).reshape(-1, 3),
        np.array(odom).reshape(-1, 3),
        robot.collisions,
    )
