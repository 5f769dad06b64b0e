"""The walls near a moving robot against the whole world: WallClearance (the simulated robot's
per-step wall distance) against geometry.clearance_m, raycast.NearbyRayCaster (its sonar's) against
the world's ray caster; and a SimRobot that keeps no covariance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_msgs_py.geometry import clearance_m
from island_msgs_py.raycast import NearbyRayCaster
from island_msgs_py.types import Pose2D
from island_sim.core.near_walls import WallClearance
from island_sim.core.robot import RobotError, SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world_loader import load_world


def test_wall_clearance_equals_clearance_m_bit_for_bit_along_a_walk_and_after_jumps() -> None:
    world = load_world("paper_fig4")
    walls = WallClearance(world.segments)
    rng = np.random.default_rng(3)
    x0, y0, x1, y1 = world.bounds
    p = np.array([35.0, 21.0])
    for k in range(3000):
        if k % 500 == 0:  # a jump far beyond the gathered walls' reach
            p = rng.uniform([x0, y0], [x1, y1])
        p = p + rng.normal(0.0, 0.03, 2)  # steps of a few cm, like physics steps
        want = float(clearance_m(p[None, :], world.segments)[0])
        assert walls.at(float(p[0]), float(p[1])) == want


def test_wall_clearance_without_walls_is_infinite() -> None:
    assert WallClearance(np.zeros((0, 4))).at(1.0, 2.0) == math.inf


def test_a_robot_without_covariance_moves_exactly_like_one_with_it() -> None:
    world = load_world("paper_fig4")
    start = world.start_pose
    a = SimRobot(world, start, np.random.default_rng(4))
    b = SimRobot(world, start, np.random.default_rng(4), track_covariance=False)
    for k in range(400):
        cmd = (0.4, 0.3 * math.sin(k / 30.0))
        ra, rb = a.step(*cmd, 0.02), b.step(*cmd, 0.02)
        assert ra == rb
    assert a.true_pose == b.true_pose and a.odom_pose == b.odom_pose
    assert a.epsilon_m > 0
    with pytest.raises(RobotError, match="track_covariance"):
        _ = b.odom_covariance


def test_nearby_ray_caster_gives_the_worlds_hits_along_a_walk_and_after_jumps() -> None:
    world = load_world("paper_fig4")
    sonar = SonarModel(SonarConfig())
    near = NearbyRayCaster(world, sonar.config.range_max_m)
    rng = np.random.default_rng(5)
    x0, y0, x1, y1 = world.bounds
    p = np.array([35.0, 21.0, 0.0])
    echoes = 0
    for k in range(600):
        if k % 150 == 0:
            p = np.array([*rng.uniform([x0, y0], [x1, y1]), rng.uniform(-math.pi, math.pi)])
        p = p + rng.normal(0.0, [0.05, 0.05, 0.1])
        pose = Pose2D(*p)
        want = sonar.scan(world, pose, np.random.default_rng(k))
        got = sonar.scan(near, pose, np.random.default_rng(k))
        np.testing.assert_array_equal(got, want)
        echoes += int(np.isfinite(want).sum())
        # Rays from one point, and from points spread wider than the gathering reach; within
        # the sonar's range and beyond it.
        one = rng.uniform([x0, y0], [x1, y1], (1, 2)) + np.zeros((7, 2))
        spread = rng.uniform([x0, y0], [x1, y1], (7, 2))
        angles = rng.uniform(-math.pi, math.pi, 7)
        for origins, max_range in ((one, 3.0), (one, 50.0), (spread, 3.0)):
            a = near.raycast(origins, angles, max_range)
            b = world.raycast(origins, angles, max_range)
            for field in ("distance_m", "segment", "cos_incidence", "normal_angle"):
                np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert echoes > 600 * 4  # the scans heard walls: the comparison was not of empty scans
