"""Stamp, LaserScan, Odometry and Twist conversions (island_msgs_py.conversions): round trips on
messages built in memory."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_msgs_py.conversions import (
    ConversionError,
    arrays_to_scan,
    check_stamp,
    command_to_twist,
    command_to_twist_stamped,
    ns_to_time,
    odometry_to_pose,
    pose_to_odometry,
    scan_to_arrays,
    time_to_ns,
    twist_stamped_to_command,
    twist_to_command,
)
from island_msgs_py.limits import MAX_SCAN_RANGES, MAX_STAMP_AHEAD_S
from island_msgs_py.types import Pose2D
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import LaserScan


def test_stamps_are_exact_nanoseconds() -> None:
    for t_ns in (0, 1, 20_000_000, 599_980_000_000, 1_700_000_000_123_456_789):
        assert time_to_ns(ns_to_time(t_ns)) == t_ns
    t = ns_to_time(3_250_000_000)
    assert (t.sec, t.nanosec) == (3, 250_000_000)
    with pytest.raises(ConversionError, match=">= 0"):
        ns_to_time(-1)


def test_scan_round_trip_keeps_inf_and_limits() -> None:
    angles = np.arange(16) * (2 * math.pi / 16)
    ranges = np.linspace(0.5, 6.0, 16)
    ranges[[3, 7]] = np.inf
    msg = arrays_to_scan(ranges, angles, (0.375, 6.725), 1_500_000_000, "base_link", 0.1)
    back = deserialize_message(serialize_message(msg), LaserScan)
    r, a = scan_to_arrays(back)
    assert np.allclose(a, angles, atol=1e-6)
    assert np.array_equal(np.isinf(r), np.isinf(ranges))
    assert np.allclose(r[np.isfinite(r)], ranges[np.isfinite(ranges)], atol=1e-6)
    assert back.range_min == pytest.approx(0.375) and back.range_max == pytest.approx(6.725)
    assert back.header.frame_id == "base_link" and time_to_ns(back.header.stamp) == 1_500_000_000
    assert back.angle_increment == pytest.approx(2 * math.pi / 16)


def test_scan_outside_limits_or_nan_reads_as_no_echo() -> None:
    msg = arrays_to_scan([1.0, 2.0, 3.0], [0.0, 0.5, 1.0], (0.4, 2.5), 0)
    msg.ranges = [float("nan"), 0.1, 2.0]
    r, _ = scan_to_arrays(msg)
    assert np.isinf(r[0]) and np.isinf(r[1]) and r[2] == pytest.approx(2.0)
    with pytest.raises(ConversionError, match="evenly spaced"):
        arrays_to_scan([1.0, 1.0, 1.0], [0.0, 0.1, 0.5], (0.1, 5.0), 0)
    with pytest.raises(ConversionError, match="ranges"):
        arrays_to_scan([1.0, 1.0], [0.0, 0.1, 0.2], (0.1, 5.0), 0)
    with pytest.raises(ConversionError, match="no ranges"):
        scan_to_arrays(LaserScan())


def test_odometry_round_trip_with_covariance() -> None:
    pose = Pose2D(3.5, -2.25, -2.9)
    cov = np.array([[0.04, 0.01, 0.002], [0.01, 0.09, -0.003], [0.002, -0.003, 0.0025]])
    msg = pose_to_odometry(pose, cov, 12_340_000_000, "odom", "base_link", (0.4, -0.2))
    back, cov_back, t_ns = odometry_to_pose(deserialize_message(serialize_message(msg),
                                                                type(msg)))
    assert back.x == pytest.approx(3.5) and back.y == pytest.approx(-2.25)
    assert back.theta == pytest.approx(-2.9)
    assert np.allclose(cov_back, cov) and t_ns == 12_340_000_000
    full = np.asarray(msg.pose.covariance).reshape(6, 6)
    assert full[5, 5] == pytest.approx(0.0025) and full[0, 5] == pytest.approx(0.002)
    assert full[2, 2] == 0.0 and msg.child_frame_id == "base_link"
    assert msg.twist.twist.linear.x == pytest.approx(0.4)
    with pytest.raises(ConversionError, match="3x3"):
        pose_to_odometry(pose, np.eye(2), 0, "odom")
    msg.pose.pose.orientation.w = float("nan")
    with pytest.raises(ConversionError, match="odometry pose"):
        odometry_to_pose(msg)


def test_twist_is_validated() -> None:
    assert twist_to_command(command_to_twist(0.3, -0.7)) == pytest.approx((0.3, -0.7))
    with pytest.raises(ConversionError, match=r"linear\.x"):
        twist_to_command(command_to_twist(float("nan"), 0.0))
    with pytest.raises(ConversionError, match=r"angular\.z"):
        twist_to_command(command_to_twist(0.0, float("-inf")))


def test_twist_stamped_round_trip_keeps_the_answered_stamp() -> None:
    msg = command_to_twist_stamped(0.25, 0.5, 12_300_000_000)
    assert msg.header.frame_id == "base_link"
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (12, 300_000_000)
    assert twist_stamped_to_command(msg) == pytest.approx((0.25, 0.5, 12_300_000_000))
    with pytest.raises(ConversionError, match=r"angular\.z"):
        twist_stamped_to_command(command_to_twist_stamped(0.0, float("nan"), 0))
    with pytest.raises(ConversionError, match="stamp"):
        command_to_twist_stamped(0.0, 0.0, -1)


def test_a_scan_longer_than_any_sensor_is_refused_before_conversion() -> None:
    msg = LaserScan(angle_increment=0.001, range_max=10.0)
    msg.ranges = [1.0] * MAX_SCAN_RANGES
    assert scan_to_arrays(msg)[0].shape == (MAX_SCAN_RANGES,)
    msg.ranges = [1.0] * (MAX_SCAN_RANGES + 1)
    with pytest.raises(ConversionError, match=f"{MAX_SCAN_RANGES + 1} values .*limit is "
                       f"{MAX_SCAN_RANGES}"):
        scan_to_arrays(msg)


def test_a_stamp_far_ahead_of_the_clock_is_refused_naming_the_topic() -> None:
    now = 100 * 10**9
    limit_ns = round(MAX_STAMP_AHEAD_S * 1e9)
    check_stamp(now + limit_ns, now, "/odom")
    check_stamp(0, now, "/odom")  # old stamps are the subscriber's business
    with pytest.raises(ConversionError, match=r"/cmd_vel: header.stamp .* ahead .*limit"):
        check_stamp(now + limit_ns + 1, now, "/cmd_vel")
    check_stamp((2**31 - 1) * 10**9, 0, "/odom")  # a clock that has not started cannot judge
