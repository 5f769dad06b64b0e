"""Differential-drive robot: kinematics, wall stops, systematic and random odometry drift."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from island_msgs_py.types import Pose2D
from island_sim.core.robot import (
    OdometryConfig,
    RobotConfig,
    RobotError,
    SimRobot,
    arc_update,
    epsilon_from_covariance,
)
from island_sim.core.sim_loop import SimLoopConfig
from island_sim.core.world import World

FAST = RobotConfig(max_linear_accel_mps2=100.0, max_angular_accel_radps2=100.0)


def _rng(seed: int = 0) -> np.random.Generator:
    return np.random.default_rng(seed)


def test_arc_update_follows_the_exact_circle() -> None:
    pose = np.array([1.0, 2.0, 0.3])
    r, n = 2.0, 37
    total = 2.0 * math.pi * 0.8
    for _ in range(n):
        pose = arc_update(pose, r * total / n, total / n)
    # centre of the circle is to the left of the start heading
    cx, cy = 1.0 - r * math.sin(0.3), 2.0 + r * math.cos(0.3)
    assert math.hypot(pose[0] - cx, pose[1] - cy) == pytest.approx(r, abs=1e-9)
    th_end = 0.3 + total
    assert pose[0] == pytest.approx(cx + r * math.sin(th_end), abs=1e-9)
    assert pose[1] == pytest.approx(cy - r * math.cos(th_end), abs=1e-9)


def test_exact_odometry_equals_truth_and_speeds_are_limited() -> None:
    bot = SimRobot(None, Pose2D(0, 0, 0), _rng(), RobotConfig(), OdometryConfig.exact())
    bot.step(5.0, 0.0, 0.1)
    assert bot.velocity[0] == pytest.approx(0.1)  # 1 m/s^2 * 0.1 s
    for _ in range(50):
        bot.step(5.0, 3.0, 0.1)
    assert bot.velocity == pytest.approx((0.6, 1.2))
    assert np.allclose(bot.true_pose.as_array(), bot.odom_pose.as_array(), atol=1e-12)
    assert bot.epsilon_m == 0.0
    assert bot.time_s == pytest.approx(5.1)


def test_wall_stops_the_disk_and_counts_one_collision() -> None:
    world = World(np.array([[2.0, -5.0, 2.0, 5.0]]))
    bot = SimRobot(world, Pose2D(0, 0, 0), _rng(), FAST, OdometryConfig.exact())
    for _ in range(400):
        bot.step(0.5, 0.0, 0.02)
    assert bot.collisions == 1
    assert bot.blocked_steps > 100
    assert 0.0 <= bot.clearance_m < 0.02
    assert bot.true_pose.x == pytest.approx(1.75, abs=0.02)
    # wheels did not turn while blocked: odometry agrees with the truth
    assert bot.odom_pose.x == pytest.approx(bot.true_pose.x, abs=1e-12)
    # rotating in place is allowed, backing away is allowed and ends the contact
    for _ in range(20):
        bot.step(0.0, 1.0, 0.02)
    assert bot.true_pose.theta == pytest.approx(0.4, abs=0.05)
    for _ in range(20):
        bot.step(-0.5, 0.0, 0.02)
    assert bot.true_pose.x < 1.6
    assert bot.collisions == 1


def test_wheel_radius_error_bends_a_straight_drive_into_the_predicted_arc() -> None:
    e, length = 0.01, 10.0
    odo = OdometryConfig(wheel_radius_ratio_error=e, wheelbase_error=0.0, var_dist_m2_per_m=0.0,
                         var_heading_rad2_per_m=0.0, var_heading_rad2_per_rad=0.0)
    bot = SimRobot(None, Pose2D(0, 0, 0), _rng(), RobotConfig(), odo)
    while bot.distance_m < length - 1e-9:
        bot.step(min(0.5, (length - bot.distance_m) / 0.02), 0.0, 0.02)
    assert bot.true_pose.y == pytest.approx(0.0, abs=1e-12)
    assert bot.distance_m == pytest.approx(length, abs=1e-9)
    b = RobotConfig().wheelbase_m
    length_odom = length / (1.0 - e * e / 4.0)
    kappa = -e / b  # right wheel bigger -> right encoder under-counts -> odometry turns right
    expect_x = math.sin(kappa * length_odom) / kappa
    expect_y = (1.0 - math.cos(kappa * length_odom)) / kappa
    got = bot.odom_pose
    assert got.theta == pytest.approx(kappa * length_odom, rel=1e-6)
    assert got.x == pytest.approx(expect_x, abs=1e-6)
    assert got.y == pytest.approx(expect_y, abs=1e-6)
    assert got.y < -0.9  # about e L^2 / (2 b) = 1 m of sideways drift over 10 m


def test_wheelbase_error_scales_odometric_rotations() -> None:
    odo = OdometryConfig(wheel_radius_ratio_error=0.0, wheelbase_error=0.04, var_dist_m2_per_m=0.0,
                         var_heading_rad2_per_m=0.0, var_heading_rad2_per_rad=0.0)
    bot = SimRobot(None, Pose2D(0, 0, 0), _rng(), FAST, odo)
    for _ in range(50):
        bot.step(0.0, 1.0, 0.02)  # a true 1 rad turn in place
    assert bot.true_pose.theta == pytest.approx(1.0, abs=1e-9)
    assert bot.odom_pose.theta == pytest.approx(1.04, abs=1e-9)


@pytest.mark.parametrize("rho", [0.0, 0.6])
def test_empirical_odometry_spread_matches_the_propagated_covariance(rho: float) -> None:
    odo = OdometryConfig(wheel_radius_ratio_error=0.0, wheelbase_error=0.0,
                         var_dist_m2_per_m=2e-3, var_heading_rad2_per_m=1e-3,
                         var_heading_rad2_per_rad=2e-3, dist_heading_correlation=rho)
    runs, errs, covs = 300, [], []
    rng = _rng(42)
    for _ in range(runs):
        bot = SimRobot(None, Pose2D(0, 0, 0), rng, FAST, odo)
        for _ in range(60):
            bot.step(0.5, 0.0, 0.1)  # 3 m
        for _ in range(16):
            bot.step(0.0, math.pi / 3.2, 0.1)  # ~ quarter turn left
        for _ in range(40):
            bot.step(0.5, 0.0, 0.1)  # 2 m
        e = bot.odom_pose.as_array() - bot.true_pose.as_array()
        e[2] = math.atan2(math.sin(e[2]), math.cos(e[2]))
        errs.append(e)
        covs.append(bot.odom_covariance)
    emp = np.cov(np.array(errs).T)
    pred = np.mean(covs, axis=0)
    assert np.all(np.abs(np.mean(errs, axis=0)) < 3.0 * np.sqrt(np.diag(pred) / runs) + 1e-12)
    for i in range(3):
        assert emp[i, i] == pytest.approx(pred[i, i], rel=0.25), (i, emp, pred)
    # correlations (x-theta, y-theta, x-y) agree too
    corr_e = emp / np.sqrt(np.outer(np.diag(emp), np.diag(emp)))
    corr_p = pred / np.sqrt(np.outer(np.diag(pred), np.diag(pred)))
    assert np.allclose(corr_e, corr_p, atol=0.15), (corr_e, corr_p)
    eps = epsilon_from_covariance(pred)
    assert eps == pytest.approx(math.sqrt(np.linalg.eigvalsh(emp[:2, :2])[-1]), rel=0.2)


def test_epsilon_grows_with_distance_and_same_seed_same_run() -> None:
    def run(seed: int) -> tuple[list[float], np.ndarray]:
        bot = SimRobot(None, Pose2D(0, 0, 0), _rng(seed))
        eps = []
        for k in range(500):
            bot.step(0.5, 0.3 * math.sin(k / 30.0), 0.02)
            eps.append(bot.epsilon_m)
        return eps, bot.odom_pose.as_array()

    eps_a, end_a = run(7)
    eps_b, end_b = run(7)
    _, end_c = run(8)
    assert eps_a == eps_b and np.array_equal(end_a, end_b)
    assert not np.array_equal(end_a, end_c)
    assert all(b >= a - 1e-15 for a, b in itertools.pairwise(eps_a))
    assert eps_a[-1] > 2.0 * eps_a[100] > 0.0


@pytest.mark.parametrize(
    ("factory", "needle"),
    [
        (lambda: RobotConfig(radius_m=-1.0), "radius_m"),
        (lambda: RobotConfig(max_linear_speed_mps=float("nan")), "max_linear_speed_mps"),
        (lambda: OdometryConfig(var_dist_m2_per_m=-1e-3), "var_dist_m2_per_m"),
        (lambda: OdometryConfig(dist_heading_correlation=1.5), "dist_heading_correlation"),
        (lambda: SimLoopConfig(physics_rate_hz=50.0, sensor_rate_hz=7.0), "sensor_rate_hz"),
        (lambda: SimLoopConfig(real_time_factor=-1.0), "real_time_factor"),
    ],
)
def test_bad_configuration_names_the_field(factory: object, needle: str) -> None:
    with pytest.raises(RobotError, match=needle):
        factory()  # type: ignore[operator]


def test_bad_step_arguments_are_rejected() -> None:
    bot = SimRobot(None, Pose2D(0, 0, 0), _rng())
    with pytest.raises(RobotError, match="finite"):
        bot.step(float("nan"), 0.0, 0.02)
    with pytest.raises(RobotError, match="dt_s"):
        bot.step(0.1, 0.0, 0.0)
    with pytest.raises(RobotError, match="Generator"):
        SimRobot(None, Pose2D(0, 0, 0), 3)  # type: ignore[arg-type]
    assert SimLoopConfig().steps_per_sensor_period == 5


def test_real_time_pacer_keeps_sim_time_at_the_factor_and_never_bursts() -> None:
    from island_sim.core.sim_loop import RealTimePacer

    pacer = RealTimePacer(real_time_factor=2.0, dt_ns=20_000_000, max_steps=50)  # 50 Hz, 2x
    steps = 0
    for k in range(101):  # 1 s of wall time in 10 ms ticks
        steps += pacer.steps_due(k * 0.01, steps)
    assert steps == 100  # 2 s of sim time at 20 ms a step
    # Far behind (a 10 s stall): at most max_steps now, and no catch-up burst afterwards: the
    # pacing restarts from the stall, so the next step waits until wall time has caught up.
    assert pacer.steps_due(11.0, steps) == 50
    assert pacer.steps_due(11.01, steps + 50) == 0
    assert pacer.steps_due(11.515, steps + 50) == 1
    with pytest.raises(RobotError, match="real_time_factor"):
        RealTimePacer(0.0, 20_000_000, 50)


def test_command_gate_waits_by_stamp_and_duplicate_answers_do_not_run_it_ahead() -> None:
    from island_sim.core.sim_loop import CommandGate

    period = 100_000_000  # 10 Hz sensor boundaries [ns]
    gate = CommandGate(lockstep=True, cmd_timeout_ns=500_000_000)
    assert gate.current(0) == (0.0, 0.0)  # nothing taken yet
    assert gate.must_wait(0)
    assert gate.offer(0.2, 0.0, 0, now_ns=0)  # the answer to the scan at 0 releases the wait
    # Two controllers answer the scan at 0.1 s (a hand-over): the second must not count for 0.2 s.
    assert gate.must_wait(period)
    assert gate.offer(0.3, 0.1, period, now_ns=period)
    assert not gate.offer(0.0, 0.5, period, now_ns=period)  # same stamp: taken, no wait to end
    assert gate.current(period) == (0.0, 0.5)
    assert gate.must_wait(2 * period)  # still waits for an answer to the scan at 0.2 s
    assert not gate.offer(9.0, 9.0, period - 1, now_ns=2 * period)  # older: stale, ignored
    assert gate.stale == 1 and gate.current(2 * period) == (0.0, 0.5)
    gate.give_up()  # the wall-clock timeout: step on, that period counts as answered
    assert gate.waiting_for_ns is None and not gate.must_wait(2 * period)
    assert gate.current(period + 500_000_001) == (0.0, 0.0)  # no command for too long: stop
    free = CommandGate(lockstep=False, cmd_timeout_ns=1)
    assert not free.must_wait(0)
    assert not free.offer(0.1, 0.0, 0, now_ns=5) and free.answered_ns == 5  # stamp 0 = now
    with pytest.raises(RobotError, match="cmd_timeout_ns"):
        CommandGate(lockstep=True, cmd_timeout_ns=0)


def test_sim_clock_publishes_every_step_and_marks_sensor_boundaries_and_the_end() -> None:
    from island_sim.core.sim_loop import SimClock

    clock = SimClock(SimLoopConfig(stop_after_s=0.2))  # 50 Hz physics, 10 Hz sensor
    assert clock.at_boundary and clock.sim_time_ns == 0 and not clock.finished
    published, boundaries = [], []
    while not clock.finished:
        published.append(clock.advance())
        boundaries.append(clock.at_boundary)
    assert clock.step_count == 10 and clock.sim_time_ns == 200_000_000
    assert published == [clock.steps_per_publish == 1 or (k + 1) % clock.steps_per_publish == 0
                         for k in range(10)]
    assert [k + 1 for k, b in enumerate(boundaries) if b] == [5, 10]  # every 0.1 s
    assert not SimClock(SimLoopConfig(stop_after_s=0.0)).finished  # 0 = run forever


def test_truth_and_clock_rates_divide_the_publish_rate_and_follow_the_sensor() -> None:
    from island_sim.core.sim_loop import SimClock

    cfg = SimLoopConfig(truth_rate_hz=10.0, clock_rate_hz=25.0, sensor_rate_hz=5.0,
                        stop_after_s=0.4)
    assert (cfg.steps_per_truth, cfg.steps_per_clock) == (5, 2)
    clock = SimClock(cfg)
    due = []
    while not clock.finished:
        clock.advance()
        due.append((clock.due(clock.steps_per_truth), clock.due(clock.steps_per_clock)))
    assert [k + 1 for k, (t, _) in enumerate(due) if t] == [5, 10, 15, 20]  # every 0.1 s
    assert [k + 1 for k, (_, c) in enumerate(due) if c] == list(range(2, 21, 2))
    for bad in ({"truth_rate_hz": 15.0}, {"clock_rate_hz": 100.0}, {"truth_rate_hz": 5.0},
                {"clock_rate_hz": -10.0}):
        name = next(iter(bad))
        with pytest.raises(RobotError, match=name):
            SimLoopConfig(**bad)  # not dividing 50, above /odom's 50, below the 10 Hz sensor
    same = SimLoopConfig(publish_rate_hz=10.0)  # 0 (the default): at the rate of /odom
    assert same.steps_per_truth == same.steps_per_clock == same.steps_per_publish == 5
