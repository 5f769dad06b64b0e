"""nav_msgs/Odometry read from and written to CDR bytes without rclpy's message objects
(island_msgs_py.cdr): the same values as rclpy's own (de)serialization, bad bytes refused."""

from __future__ import annotations

import math
import random
import struct

import numpy as np
import pytest
from island_msgs_py.conversions import (
    ConversionError,
    odometry_cdr_to_pose,
    odometry_cdr_to_pose_twist,
    odometry_to_pose,
    pose_to_odometry,
    pose_to_odometry_cdr,
)
from island_msgs_py.types import Pose2D
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message

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
