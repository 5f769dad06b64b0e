"""A drive back to a new island's origin that stalls (a wall behind the robot) still ends facing
the island's heading 0 before the builder hands the robot back. Traced on paper_fig4 seed 1:
island 11 in a 1 m doorway, the reverse drive to the origin pushed at the jamb, the builder
handed back facing 174 deg away, and the next edge's strategy was recorded turned round (every
route over it failed). Public API: `IslandBuilder`."""

from __future__ import annotations

import math

import numpy as np
from island_mapping.core.builder import (
    BuilderConfig,
    CommandMode,
    EventKind,
    IslandBuilder,
    RevisitConfig,
)
from island_msgs_py.types import Pose2D, wrap_angle
from island_sim.core.robot import OdometryConfig, SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World

H = 1.25  # corridors 2.5 m wide
# A corridor along x (closed at x = -30) crossing one along y at x = 0.
CROSS = np.array([[-30.0, -H, -H, -H], [-30.0, H, -H, H], [-H, H, -H, 10.0], [H, H, H, 10.0],
                  [-H, -H, -H, -10.0], [H, -H, H, -10.0], [H, -H, 10.0, -H], [H, H, 10.0, H],
                  [-30.0, -H, -30.0, H]])


def _handed_back_heading_deg(held: bool, pinned: bool = False) -> tuple[float, int]:
    """Follow the corridor east to x = -3 (a stand-in follower), let the builder build an
    island; `held`: from the acceptance on the robot cannot translate (it still turns),
    `pinned`: nor turn. The robot's heading relative to the island's origin when handed back
    [deg], and the stalls."""
    cfg = BuilderConfig(peak_ahead_m=0.0, bound_floor=0.05, build_first_island=False,
                        revisit=RevisitConfig(enabled=False))
    builder = IslandBuilder(cfg)
    rng = np.random.default_rng(0)
    world = World(CROSS, "cross")
    robot = SimRobot(world, Pose2D(-16.0, 0.0, 0.0), rng,
                     odometry=OdometryConfig.exact())
    sonar = SonarModel(SonarConfig(), seed=0)
    t, path, last = 0.0, 0.0, robot.odom_pose
    builder.on_odometry(t, last, np.zeros((3, 3)))
    origin: Pose2D | None = None
    for _ in range(1500):
        builder.on_scan(t, sonar.scan(world, robot.true_pose, rng), sonar.angles_rad)
        cmd = builder.command(t)
        for e in cmd.events:
            if e.kind is EventKind.ISLAND_ACCEPTED:
                origin = e.anchor_odom
            if e.kind is EventKind.HANDED_BACK and origin is not None:
                back = wrap_angle(robot.odom_pose.theta - origin.theta)
                return math.degrees(back), builder.diagnostics.drive_stalls
        if cmd.mode is CommandMode.FOLLOW:
            p = robot.true_pose
            v = 0.4 if p.x < -3.0 else 0.0
            w = float(np.clip(-2.0 * p.theta - 1.0 * p.y, -1.0, 1.0))
        else:
            v, w = cmd.v_mps, cmd.w_radps
            if held and origin is not None:
                v = 0.0
            if pinned and origin is not None:
                w = 0.0
        for _ in range(5):
            robot.step(v, w, 0.02)
            t += 0.02
            o = robot.odom_pose
            path += math.hypot(o.x - last.x, o.y - last.y) if cmd.mode is (
                CommandMode.FOLLOW) else 0.0
            last = o
            builder.on_ground_truth(robot.true_pose)
            builder.on_odometry(t, o, np.diag([(0.2 * path) ** 2] * 2 + [1e-6]))
    raise AssertionError("never handed back")


def test_a_stalled_drive_back_still_ends_facing_the_island_heading() -> None:
    free, free_stalls = _handed_back_heading_deg(held=False)
    assert abs(free) < 5.0 and free_stalls == 0
    held, stalls = _handed_back_heading_deg(held=True)
    assert stalls >= 1  # the drive back stalled...
    assert abs(held) < 5.0  # ...and the robot turned to the island's heading all the same


def test_a_robot_that_cannot_turn_either_is_handed_back_where_it_is() -> None:
    """A robot pinned (no translation, no turn) from the acceptance on: the turn stalls too,
    and the builder hands it back there instead of turning for ever."""
    _, stalls = _handed_back_heading_deg(held=True, pinned=True)
    assert stalls >= 2

