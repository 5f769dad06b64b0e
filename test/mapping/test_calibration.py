"""The odometry's systematic heading error, learnt online from docks (core.builder.calibration,
off by default, turned on here).

A simulated robot (island_sim's SimRobot: a wheelbase 0.5 % longer than odometry assumes,
wheel radii 0.05 % apart, random drift on top, seeded, a tenth of the default's heading noise
so that a few rounds show what an hour of stars shows: the systematic part dominates) drives
rounds from one island's origin and back: a star-like spin of two full turns the same way and
a square, or a shuttle. At the end of each round it docks: its true pose in the island's frame
(the origin, plus a localization's error) gives the origin as odometry puts it now, which the
`Recognizer` remembers. Public APIs: `OdometryCalibration`, `Recognizer.remember` /
`estimates`, `BuilderConfig`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from island_mapping.core.builder import (
    BuilderConfig,
    BuilderError,
    CalibrationConfig,
    OdometryCalibration,
    PoseSnapshot,
    Recognizer,
)
from island_msgs_py.types import Pose2D, wrap_angle
from island_sim.core.robot import OdometryConfig, SimRobot

_DT_S = 0.02
_ISLAND = 3
_ON = BuilderConfig(calibration=CalibrationConfig(enabled=True))
_OFF = BuilderConfig(calibration=CalibrationConfig(enabled=False))


def _drive(robot: SimRobot, rec: Recognizer, v: float, w: float, seconds: float) -> None:
    for _ in range(round(seconds / _DT_S)):
        robot.step(v, w, _DT_S)
        rec.calibration.update(robot.odom_pose)


def _round(robot: SimRobot, rec: Recognizer, kind: int = 0) -> None:
    """Even kinds: two full turns on the spot and a 3 m square (left turns); odd: a 4 m
    shuttle, turned round left and right (travel, no net turn)."""
    if kind % 2 == 0:
        _drive(robot, rec, 0.0, 1.0, 4 * math.pi)
        for _ in range(4):
            _drive(robot, rec, 0.5, 0.0, 6.0)
            _drive(robot, rec, 0.0, 1.0, 0.5 * math.pi)
        return
    for w in (1.0, -1.0, 1.0, -1.0):
        _drive(robot, rec, 0.5, 0.0, 8.0)
        _drive(robot, rec, 0.0, w, math.pi)


def _dock(robot: SimRobot, rec: Recognizer, gen: np.random.Generator) -> None:
    """The robot localizes in the island (its origin at the start pose, the true frame's
    identity) within 2 cm / 1 deg, and the recognizer remembers the origin by odometry."""
    seen = robot.true_pose.compose(Pose2D(*gen.normal(0.0, [0.02, 0.02, math.radians(1.0)])))
    rec.remember(_ISLAND, robot.odom_pose.compose(seen.inverse()), robot.odom_covariance)


def _snapshot(robot: SimRobot) -> PoseSnapshot:
    return PoseSnapshot(robot.odom_pose, robot.odom_covariance, 0.1, 0.01, None, 50.0)


def _heading_error_deg(rec: Recognizer, robot: SimRobot) -> tuple[float, float]:
    """(error of the by-odometry estimate of the robot's heading in the island, its sigma),
    both in degrees."""
    origin, _, sigma = rec.estimates(_ISLAND, _snapshot(robot))[0]
    est = robot.odom_pose.relative_to(origin)
    return (abs(math.degrees(wrap_angle(est.theta - robot.true_pose.theta))),
            math.degrees(sigma))


def _explore(config: BuilderConfig, rounds: int, seed: int = 2) -> tuple[SimRobot, Recognizer]:
    gen = np.random.default_rng(seed)
    odometry = OdometryConfig(var_heading_rad2_per_rad=5e-5, var_heading_rad2_per_m=1e-5)
    robot = SimRobot(None, Pose2D(0.0, 0.0, 0.0), gen, odometry=odometry)
    rec = Recognizer(config)
    rec.calibration.update(robot.odom_pose)
    rec.remember(_ISLAND, robot.odom_pose, robot.odom_covariance)
    for k in range(rounds):
        _round(robot, rec, k)
        _dock(robot, rec, gen)
    return robot, rec


def test_docks_teach_the_rotation_scale_and_the_estimate_follows() -> None:
    raw, raw_sigma, calibrated, sigma = [], [], [], []
    for seed in (1, 2, 3):
        robot, rec = _explore(_ON, 12, seed)
        cal = rec.calibration
        assert cal.used == 12 and cal.refused == 0
        # the simulated wheelbase is 0.5 % longer than odometry assumes: turns over-reported
        assert 0.0025 < cal.estimate[0] < 0.0075, cal.summary()
        # sixteen more rounds without docking: raw odometry turns by the systematic error,
        # the calibrated estimate of the island stays nearer the truth
        plain_robot, plain = _explore(_OFF, 12, seed)
        for r, k in ((robot, rec), (plain_robot, plain)):
            for i in range(16):
                _round(r, k, i)
        for errs, sigmas, (e, s) in ((calibrated, sigma, _heading_error_deg(rec, robot)),
                                     (raw, raw_sigma, _heading_error_deg(plain, plain_robot))):
            errs.append(e)
            sigmas.append(s)
        assert calibrated[-1] < 2.0 * sigma[-1]  # its sigma allows for what is left
    # what the gate was told without calibration is not the truth: errors of 3+ sigmas
    assert min(e / s for e, s in zip(raw, raw_sigma, strict=True)) > 3.0, (raw, raw_sigma)
    assert sum(calibrated) < 0.5 * sum(raw), (calibrated, raw)


def test_a_wrong_dock_is_not_learnt() -> None:
    robot, rec = _explore(_ON, 4)
    before = rec.calibration.estimate.copy()
    _round(robot, rec)
    turned = robot.odom_pose.compose(Pose2D(0.0, 0.0, 0.5 * math.pi))  # a quarter-turned alias
    rec.remember(_ISLAND, turned.compose(robot.true_pose.inverse()), robot.odom_covariance)
    assert rec.calibration.refused == 1
    assert not rec.calibration.measurements[-1].used
    np.testing.assert_array_equal(rec.calibration.estimate, before)


def test_disabled_calibration_leaves_odometry_alone() -> None:
    robot, rec = _explore(BuilderConfig(), 3)  # off by default
    cal = rec.calibration
    assert cal.transform == Pose2D(0.0, 0.0, 0.0)
    assert cal.used == 0 and np.all(cal.estimate == 0.0)
    known = rec.known(_ISLAND)
    assert known is not None
    origin, _ = known
    # the origin is where the last dock put it, in raw odometry
    assert math.hypot(origin.x, origin.y) > 0.0 or origin.theta != 0.0
    assert rec.estimates(_ISLAND, _snapshot(robot))[0][0] == origin


def test_stream_without_turns_or_docks_is_the_identity() -> None:
    cal = OdometryCalibration(CalibrationConfig(enabled=True))
    for x in np.linspace(0.0, 5.0, 20):
        cal.update(Pose2D(float(x), 0.0, 0.0))
    assert cal.transform == Pose2D(0.0, 0.0, 0.0)


@pytest.mark.parametrize("field", ["rotation_scale_sigma", "curvature_sigma_radpm",
                                   "dock_heading_sigma_deg", "gate_sigmas"])
def test_config_refuses_bad_numbers_by_name(field: str) -> None:
    for bad in (0.0, -1.0, math.nan):
        with pytest.raises(BuilderError, match=f"CalibrationConfig.{field}"):
            dataclasses.replace(CalibrationConfig(), **{field: bad})
