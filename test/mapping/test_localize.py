"""Line-model localization (Dudek & MacKenzie): recovers offsets, reports degeneracy honestly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.localize import (
    LocalizeConfig,
    LocalizeError,
    Solver,
    Weighting,
    convergence_region,
    localize,
)
from island_msgs_py.geometry import ranges_to_points
from island_msgs_py.raycast import raycast
from island_msgs_py.types import LineModel, Pose2D
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World

ROOM = np.array([[-3, -2, 3, -2], [3, -2, 3, 2], [3, 2, -3, 2], [-3, 2, -3, -2]], float)
CORRIDOR = np.array([[-80, -1.5, 80, -1.5], [-80, 1.5, 80, 1.5]], float)


def robot_points(walls: np.ndarray, pose: Pose2D, step_deg: float = 5.0,
                 max_range_m: float = 8.0) -> np.ndarray:
    """Ideal range points in the robot frame [m] seen from `pose`."""
    a = np.radians(np.arange(0.0, 360.0, step_deg) + 0.5)
    h = raycast(walls, np.array([[pose.x, pose.y]]), a + pose.theta, max_range_m)
    ok = np.isfinite(h.distance_m)
    return np.c_[h.distance_m[ok] * np.cos(a[ok]), h.distance_m[ok] * np.sin(a[ok])]


@pytest.mark.parametrize("solver", list(Solver))
@pytest.mark.parametrize("direction_deg", [0.0, 45.0, 200.0])
def test_recovers_a_10_cm_offset_in_a_room(solver: Solver, direction_deg: float) -> None:
    truth = Pose2D(0.4, -0.3, 0.2)
    pts = robot_points(ROOM, truth)
    a = math.radians(direction_deg)
    start = Pose2D(truth.x + 0.1 * math.cos(a), truth.y + 0.1 * math.sin(a), truth.theta)
    res = localize(LineModel(ROOM), pts, start, LocalizeConfig(solver=solver))
    assert res.converged
    assert math.hypot(res.pose.x - truth.x, res.pose.y - truth.y) < 0.005
    assert abs(res.pose.theta - truth.theta) < 0.005
    assert res.residual_m < 0.01 and res.matched_fraction == 1.0
    assert 1 <= res.iterations < LocalizeConfig().max_iterations


@pytest.mark.parametrize("solver", list(Solver))
def test_heading_extension_corrects_a_heading_error(solver: Solver) -> None:
    truth = Pose2D(-0.5, 0.2, -0.4)
    pts = robot_points(ROOM, truth)
    start = Pose2D(truth.x + 0.08, truth.y - 0.05, truth.theta + math.radians(4.0))
    res = localize(ROOM, pts, start, LocalizeConfig(solver=solver))
    assert res.converged and abs(res.pose.theta - truth.theta) < math.radians(0.3)
    assert math.hypot(res.pose.x - truth.x, res.pose.y - truth.y) < 0.01
    fixed = localize(ROOM, pts, start, LocalizeConfig(solver=solver, estimate_heading=False))
    assert fixed.pose.theta == pytest.approx(start.theta)  # translation only keeps the heading
    assert fixed.residual_m > res.residual_m


def test_noisy_sonar_scan_localizes_within_a_few_centimetres() -> None:
    rng = np.random.default_rng(11)
    sonar = SonarModel(SonarConfig(noise_std_m=0.01))
    world = World(ROOM)
    truth = Pose2D(0.3, 0.4, 0.0)
    clouds = []
    for dth in np.radians([0.0, 5.6, 11.25, 16.9]):  # the ring turned in place
        pose = Pose2D(truth.x, truth.y, dth)
        r = sonar.scan(world, pose, rng)
        clouds.append(ranges_to_points(r, sonar.angles_rad + dth))
    pts = np.concatenate(clouds)
    res = localize(ROOM, pts, Pose2D(truth.x + 0.09, truth.y - 0.07, 0.0),
                   LocalizeConfig(estimate_heading=False))
    assert res.converged
    assert math.hypot(res.pose.x - truth.x, res.pose.y - truth.y) < 0.05


@pytest.mark.parametrize("solver", list(Solver))
def test_featureless_corridor_along_its_axis_is_reported_not_converged(solver: Solver) -> None:
    truth = Pose2D(0.0, 0.3, 0.0)
    pts = robot_points(CORRIDOR, truth, max_range_m=6.5)
    start = Pose2D(0.1, 0.38, 0.0)
    res = localize(CORRIDOR, pts, start, LocalizeConfig(solver=solver, estimate_heading=False))
    assert not res.converged
    assert res.constraint < 1e-6
    assert res.pose.y == pytest.approx(truth.y, abs=0.005)  # across the axis it is constrained
    assert res.pose.x == pytest.approx(start.x, abs=0.005)  # along it nothing moved it


def test_degenerate_inputs_give_a_not_converged_result() -> None:
    start = Pose2D(0.0, 0.0, 0.0)
    empty = localize(np.zeros((0, 4)), [[1.0, 0.0]] * 5, start)
    assert not empty.converged and empty.pose == start
    few = localize(ROOM, [[1.0, 0.0], [np.nan, 1.0]], start)
    assert not few.converged and few.iterations == 0
    lost = localize(ROOM, np.c_[np.full(10, 40.0), np.arange(10.0)], start)
    assert not lost.converged and lost.matched_fraction == 0.0


def test_nan_rows_are_ignored() -> None:
    truth = Pose2D(0.2, 0.1, 0.0)
    pts = robot_points(ROOM, truth)
    pts_nan = np.concatenate([pts, [[np.nan, 0.0], [np.inf, np.inf]]])
    a = localize(ROOM, pts, Pose2D(0.25, 0.05, 0.0))
    b = localize(ROOM, pts_nan, Pose2D(0.25, 0.05, 0.0))
    assert a == b


def test_cauchy_weighting_resists_an_outlier_better_than_uniform() -> None:
    truth = Pose2D(0.0, 0.0, 0.0)
    pts = robot_points(ROOM, truth, step_deg=10.0)
    pts = np.concatenate([pts, [[1.0, 1.55]] * 3])  # clutter 0.45 m off the top wall
    start = Pose2D(0.05, -0.05, 0.0)
    errs = {}
    for w in Weighting:
        res = localize(ROOM, pts, start, LocalizeConfig(weighting=w, estimate_heading=False))
        errs[w] = math.hypot(res.pose.x, res.pose.y)
    assert errs[Weighting.CAUCHY] < errs[Weighting.UNIFORM]


def test_convergence_region_shrinks_with_the_initial_offset() -> None:
    truth = Pose2D(0.0, 0.0, 0.0)
    pts = robot_points(ROOM, truth)
    rates = convergence_region(ROOM, pts, truth, [0.1, 0.3, 2.0], 12, np.random.default_rng(0),
                               LocalizeConfig(estimate_heading=False))
    assert rates[0] == 1.0 and rates[1] == 1.0
    assert rates[2] < 0.5
    again = convergence_region(ROOM, pts, truth, [0.1, 0.3, 2.0], 12, np.random.default_rng(0),
                               LocalizeConfig(estimate_heading=False))
    assert np.array_equal(rates, again)


def test_bad_config_and_points_are_named() -> None:
    with pytest.raises(LocalizeError, match="max_iterations"):
        LocalizeConfig(max_iterations=0)
    with pytest.raises(LocalizeError, match=r"[Ss]olver"):
        LocalizeConfig(solver="newton")  # type: ignore[arg-type]
    with pytest.raises(LocalizeError, match="points_robot"):
        localize(ROOM, np.zeros((3, 3)), Pose2D(0, 0, 0))


def test_cone_aware_sonar_localization_recovers_an_offset_that_axis_points_miss() -> None:
    from island_mapping.core.localize import SonarBeams, localize_sonar

    rng = np.random.default_rng(21)
    sonar = SonarModel()  # 25 deg cones, specular loss, 1 cm noise
    world = World(ROOM)
    truth = Pose2D(-0.6, 0.5, 0.3)
    turns = np.radians([0.0, 5.625, 11.25, 16.875])
    ranges = np.concatenate([sonar.scan(world, Pose2D(truth.x, truth.y, truth.theta + t), rng)
                             for t in turns])
    beams = SonarBeams(
        axis_rad=np.concatenate([sonar.angles_rad + t for t in turns]),
        cone_offsets_rad=sonar.ray_offsets_rad,
        ring_radius_m=sonar.config.ring_radius_m,
        reflect_deg=sonar.config.reflect_deg,
        range_min_m=sonar.config.range_min_m,
        range_max_m=sonar.config.range_max_m,
    )
    start = Pose2D(truth.x + 0.1, truth.y - 0.05, truth.theta)
    cfg = LocalizeConfig(estimate_heading=False)
    aware = localize_sonar(ROOM, ranges, beams, start, cfg)
    assert aware.converged
    err_aware = math.hypot(aware.pose.x - truth.x, aware.pose.y - truth.y)
    assert err_aware < 0.01
    pts = ranges_to_points(ranges, beams.axis_rad)
    axis = localize(ROOM, pts, start, cfg)
    assert math.hypot(axis.pose.x - truth.x, axis.pose.y - truth.y) > 2 * err_aware
    with pytest.raises(LocalizeError, match="beams"):
        localize_sonar(ROOM, ranges[:5], beams, start, cfg)


def test_sonar_localization_pairs_readings_with_the_visible_face_of_a_thin_wall() -> None:
    from island_mapping.core.localize import SonarBeams, localize_sonar

    # A 0.1 m thick partition: its hidden face is 0.1 m behind the visible one, within reach of
    # nearest-segment pairing after a 10-15 cm offset.
    thin = np.array([[-0.05, -2.0, -0.05, 0.5], [0.05, -2.0, 0.05, 0.5], [-0.05, 0.5, 0.05, 0.5]])
    walls = np.concatenate([ROOM, thin])
    sonar = SonarModel()
    world = World(walls)
    beams = SonarBeams(sonar.angles_rad, sonar.ray_offsets_rad, sonar.config.ring_radius_m,
                       sonar.config.reflect_deg, sonar.config.range_min_m,
                       sonar.config.range_max_m)
    rng = np.random.default_rng(5)
    cfg = LocalizeConfig(estimate_heading=False)
    errors = []
    for i in range(12):
        truth = Pose2D(0.6 + 0.1 * (i % 3), -1.2 + 0.2 * (i % 4), 0.0)
        ranges = sonar.scan(world, truth, rng)
        a = math.pi + rng.uniform(-0.3, 0.3)  # towards the partition: points cross its face
        start = Pose2D(truth.x + 0.14 * math.cos(a), truth.y + 0.14 * math.sin(a), 0.0)
        res = localize_sonar(walls, ranges, beams, start, cfg)
        errors.append(math.hypot(res.pose.x - truth.x, res.pose.y - truth.y))
    assert max(errors) < 0.02, errors
