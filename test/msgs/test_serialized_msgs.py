"""nav_msgs/Odometry read from and written to CDR bytes, and sensor_msgs/LaserScan read from
them, without rclpy's message objects (island_msgs_py.serialized, .cdr): the same values as
rclpy's own (de)serialization and island_msgs_py.conversions, bad bytes refused."""

from __future__ import annotations

import math
import random
import struct

import numpy as np
import pytest
from island_msgs_py.conversions import (
    ConversionError,
    arrays_to_scan,
    odometry_to_pose,
    pose_to_odometry,
    scan_to_arrays,
    time_to_ns,
)
from island_msgs_py.serialized import (
    arrays_to_scan_cdr,
    odometry_cdr_to_pose,
    odometry_cdr_to_pose_twist,
    pose_to_odometry_cdr,
    scan_cdr_to_arrays,
)
from island_msgs_py.types import Pose2D
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import LaserScan

from island_msgs_py import cdr


def _random_odometry(rng: random.Random) -> Odometry:
    """Frame ids of every length mod 8 (the pose's alignment padding varies with them)."""
    m = Odometry()
    m.header.frame_id = "f" * rng.randint(0, 13)
    m.child_frame_id = "\u00e9" * rng.randint(0, 9)  # two UTF-8 bytes each
    m.header.stamp.sec = rng.randint(0, 2**31 - 1)
    m.header.stamp.nanosec = rng.randint(0, 10**9 - 1)
    m.pose.pose.position.x = rng.uniform(-1e3, 1e3)
    m.pose.pose.position.y = rng.uniform(-1e3, 1e3)
    m.pose.pose.position.z = rng.uniform(-1, 1)
    q = m.pose.pose.orientation
    q.x, q.y, q.z, q.w = (rng.uniform(-1, 1) for _ in range(4))
    m.pose.covariance = [rng.uniform(-1, 1) for _ in range(36)]
    m.twist.twist.linear.x = rng.uniform(-1, 1)
    m.twist.twist.angular.z = rng.uniform(-2, 2)
    m.twist.covariance = [rng.uniform(-1, 1) for _ in range(36)]
    return m


def test_reading_the_bytes_gives_what_the_deserialized_message_gives() -> None:
    rng = random.Random(7)
    for _ in range(300):
        m = _random_odometry(rng)
        pose, cov, t_ns, twist = odometry_cdr_to_pose_twist(serialize_message(m))
        want_pose, want_cov, want_t = odometry_to_pose(m)
        assert pose == want_pose and t_ns == want_t
        assert np.array_equal(cov, want_cov) and cov.shape == (3, 3)
        assert twist == (m.twist.twist.linear.x, m.twist.twist.angular.z)
        assert odometry_cdr_to_pose(serialize_message(m))[0] == want_pose


def test_written_bytes_are_the_message_fill_odometry_builds() -> None:
    rng = random.Random(11)
    for _ in range(300):
        pose = Pose2D(rng.uniform(-50, 50), rng.uniform(-50, 50), rng.uniform(-3.1, 3.1))
        cov = None if rng.random() < 0.3 else np.array(
            [[rng.uniform(-1, 1) for _ in range(3)] for _ in range(3)])
        t_ns = rng.randint(0, 10**15)
        frame, child = "odom"[:rng.randint(0, 4)], "robot1/base_link"[:rng.randint(0, 16)]
        twist = (rng.uniform(-1, 1), rng.uniform(-1, 1))
        data = pose_to_odometry_cdr(pose, cov, t_ns, frame, child, twist)
        assert data[:4] == cdr.ENCAPSULATION_LE
        assert deserialize_message(data, Odometry) == pose_to_odometry(
            pose, cov, t_ns, frame, child, twist)


def _big_endian(m: Odometry) -> bytes:
    """m as big-endian CDR, written independently of island_msgs_py.cdr."""
    out = bytearray(b"\x00\x00\x00\x00")
    out += struct.pack(">iI", m.header.stamp.sec, m.header.stamp.nanosec)
    for text in (m.header.frame_id, m.child_frame_id):
        while (len(out) - 4) % 4:
            out += b"\x00"
        raw = text.encode() + b"\x00"
        out += struct.pack(">I", len(raw)) + raw
    while (len(out) - 4) % 8:
        out += b"\x00"
    p, q = m.pose.pose.position, m.pose.pose.orientation
    t = m.twist.twist
    out += struct.pack(">85d", p.x, p.y, p.z, q.x, q.y, q.z, q.w, *m.pose.covariance,
                       t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y,
                       t.angular.z, *m.twist.covariance)
    return bytes(out)


def test_big_endian_cdr_is_read_too() -> None:
    rng = random.Random(3)
    for _ in range(50):
        m = _random_odometry(rng)
        pose, cov, t_ns, twist = odometry_cdr_to_pose_twist(_big_endian(m))
        want_pose, want_cov, want_t = odometry_to_pose(m)
        assert (pose, t_ns) == (want_pose, want_t) and np.array_equal(cov, want_cov)
        assert twist == (m.twist.twist.linear.x, m.twist.twist.angular.z)


def test_truncated_or_malformed_bytes_are_a_conversion_error() -> None:
    data = serialize_message(_random_odometry(random.Random(1)))
    for n in range(len(data)):  # every truncation: refused, never another exception
        with pytest.raises(ConversionError):
            odometry_cdr_to_pose(data[:n])
    huge = bytearray(data)
    huge[12:16] = struct.pack("<I", 2**31)  # header.frame_id claims 2 GB
    with pytest.raises(ConversionError, match="string"):
        odometry_cdr_to_pose(bytes(huge))
    nan = pose_to_odometry(Pose2D(0.0, 0.0, 0.0), None, 5, "odom")
    nan.pose.pose.orientation.w = math.nan
    with pytest.raises(ConversionError, match="NaN"):
        odometry_cdr_to_pose(serialize_message(nan))


def test_another_encapsulation_goes_to_rclpy() -> None:
    data = serialize_message(_random_odometry(random.Random(2)))
    other = b"\x00\x0b" + data[2:]  # not plain CDR
    with pytest.raises(cdr.CdrUnsupportedError):
        cdr.read_odometry(other)
    with pytest.raises(ConversionError, match="deserialize"):  # rclpy cannot read it either
        odometry_cdr_to_pose(b"\x00\x0b\x00\x00" + b"\xff" * 7)


def test_writing_refuses_what_the_message_cannot_hold() -> None:
    bad_cov = np.eye(3)
    bad_cov[1, 1] = math.inf
    with pytest.raises(ConversionError, match="covariance"):
        pose_to_odometry_cdr(Pose2D(0.0, 0.0, 0.0), bad_cov, 0, "odom")
    with pytest.raises(ConversionError, match="covariance"):
        pose_to_odometry_cdr(Pose2D(0.0, 0.0, 0.0), np.eye(2), 0, "odom")
    with pytest.raises(ConversionError, match="stamp"):
        pose_to_odometry_cdr(Pose2D(0.0, 0.0, 0.0), None, 2**31 * 10**9, "odom")
    with pytest.raises(ConversionError, match="stamp"):
        pose_to_odometry_cdr(Pose2D(0.0, 0.0, 0.0), None, -1, "odom")


def _random_scan(rng: random.Random, n: int) -> LaserScan:
    m = LaserScan()
    m.header.frame_id = "robot1/base_link"[:rng.randint(0, 16)]
    m.header.stamp.sec = rng.randint(0, 2**31 - 1)
    m.header.stamp.nanosec = rng.randint(0, 10**9 - 1)
    m.angle_min, m.angle_increment = rng.uniform(-3.2, 3.2), rng.uniform(-0.5, 0.5)
    m.range_min, m.range_max = rng.uniform(0.0, 0.3), rng.uniform(3.0, 8.0)
    m.ranges = [rng.choice((math.nan, math.inf, -1.0, 0.1, 9.0, rng.uniform(0.0, 10.0)))
                for _ in range(n)]
    m.intensities = [rng.uniform(0, 1) for _ in range(rng.randint(0, 3))]
    return m


def test_a_scan_read_from_its_bytes_is_what_scan_to_arrays_gives() -> None:
    rng = random.Random(5)
    for _ in range(300):
        m = _random_scan(rng, rng.randint(1, 40))
        data = serialize_message(m)
        ranges, angles, t_ns = scan_cdr_to_arrays(data)
        want_r, want_a = scan_to_arrays(deserialize_message(data, LaserScan))  # float32 fields
        assert np.array_equal(ranges, want_r) and np.array_equal(angles, want_a)
        assert ranges.dtype == want_r.dtype == np.float64 and t_ns == time_to_ns(m.header.stamp)


def test_bad_scan_bytes_are_refused_like_bad_scans() -> None:
    rng = random.Random(6)
    data = serialize_message(_random_scan(rng, 16))
    for n in range(len(data)):  # cut anywhere: header, fields, ranges, intensities
        with pytest.raises(ConversionError):
            scan_cdr_to_arrays(data[:n])
    with pytest.raises(ConversionError, match="no ranges"):
        scan_cdr_to_arrays(serialize_message(_random_scan(rng, 0)))
    with pytest.raises(ConversionError, match="limit is 8"):  # refused before reading them
        scan_cdr_to_arrays(data, max_ranges=8)
    bad = _random_scan(rng, 4)
    bad.angle_increment = math.nan
    with pytest.raises(ConversionError, match="finite"):
        scan_cdr_to_arrays(serialize_message(bad))
    with pytest.raises(ConversionError, match="deserialize"):
        scan_cdr_to_arrays(b"\x00\x0b\x00\x00" + b"\xff" * 7)


def test_a_scan_written_as_bytes_is_the_message_arrays_to_scan_builds() -> None:
    rng = random.Random(8)
    for _ in range(200):
        n = rng.randint(1, 24)
        first, step = rng.uniform(-3.2, 3.2), rng.uniform(-0.4, 0.4)
        angles = first + step * np.arange(n)
        ranges = [rng.choice((math.nan, math.inf, -math.inf, rng.uniform(0.0, 7.0)))
                  for _ in range(n)]
        args = (ranges, angles, (rng.uniform(0, 0.3), rng.uniform(3, 8)),
                rng.randint(0, 10**15), "robot1/base_link"[:rng.randint(0, 16)],
                rng.uniform(0, 0.2))
        data = arrays_to_scan_cdr(*args)
        assert deserialize_message(data, LaserScan) == deserialize_message(
            serialize_message(arrays_to_scan(*args)), LaserScan)  # float32 fields, both ways
    with pytest.raises(ConversionError, match="evenly spaced"):
        arrays_to_scan_cdr([1.0, 2.0, 3.0], [0.0, 0.1, 0.5], (0.1, 5.0), 0)
    with pytest.raises(ConversionError, match="stamp"):
        arrays_to_scan_cdr([1.0], [0.0], (0.1, 5.0), -5)
