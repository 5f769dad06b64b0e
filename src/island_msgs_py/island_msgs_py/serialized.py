"""Odometry and LaserScan as the bytes a raw subscription gets (`create_subscription(...,
raw=True)`) and a publisher sends (`publish(bytes)`), read and written by `island_msgs_py.cdr`
without rclpy's message objects: the values `island_msgs_py.conversions` gives for the built
message, for the topics a lockstep run delivers most often (/odom and /ground_truth 50 times a
simulated second, /sonar/scan 10 times, each to several nodes). Bytes in another encapsulation
than plain CDR are deserialized by rclpy and converted as usual; malformed bytes raise
ConversionError naming the message.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import numpy.typing as npt
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import LaserScan

from island_msgs_py import cdr
from island_msgs_py.conversions import (
    ConversionError,
    check_scan_count,
    odometry_to_pose,
    quaternion_components_to_yaw,
    scan_arrays,
    scan_grid,
    scan_to_arrays,
    time_to_ns,
)
from island_msgs_py.limits import MAX_SCAN_RANGES
from island_msgs_py.types import FloatArray, IslandTypeError, Pose2D


def odometry_cdr_to_pose(data: bytes) -> tuple[Pose2D, FloatArray, int]:
    """odometry_to_pose of a serialized Odometry (a raw subscription's bytes), without building
    the message (`island_msgs_py.cdr`); the same values. ConversionError if malformed."""
    pose, cov, t_ns, _ = odometry_cdr_to_pose_twist(data)
    return pose, cov, t_ns


def odometry_cdr_to_pose_twist(data: bytes
                               ) -> tuple[Pose2D, FloatArray, int, tuple[float, float]]:
    """odometry_cdr_to_pose and the twist (linear.x [m/s], angular.z [rad/s])."""
    try:
        f = cdr.read_odometry(data)
    except cdr.CdrUnsupportedError:
        try:
            msg = deserialize_message(data, Odometry)
        except Exception as exc:  # rclpy raises its own error types for bad bytes
            raise ConversionError(f"odometry: cannot deserialize: {exc}") from None
        twist = (float(msg.twist.twist.linear.x), float(msg.twist.twist.angular.z))
        return (*odometry_to_pose(msg), twist)
    except cdr.CdrError as exc:
        raise ConversionError(str(exc)) from None
    try:
        pose = Pose2D(f.x, f.y, quaternion_components_to_yaw(*f.quaternion))
    except IslandTypeError as exc:
        raise ConversionError(f"odometry pose: {exc}") from None
    return pose, np.array(f.cov3x3, dtype=np.float64).reshape(3, 3), f.stamp_ns, (f.v, f.w)


def pose_to_odometry_cdr(
    pose: Pose2D,
    cov: npt.ArrayLike | None,
    t_ns: int,
    frame_id: str,
    child_frame_id: str = "base_link",
    twist: tuple[float, float] = (0.0, 0.0),
) -> bytes:
    """pose_to_odometry serialized (what a publisher sends): the same message, built without
    rclpy's message objects (`island_msgs_py.cdr`)."""
    flat: tuple[float, ...] | None = None
    if cov is not None:
        c = np.asarray(cov, dtype=np.float64)
        flat = tuple(c.reshape(-1).tolist())
        if c.shape != (3, 3) or not all(math.isfinite(v) for v in flat):
            raise ConversionError(f"odometry covariance must be a finite 3x3, got {c.shape}")
    try:
        return cdr.write_odometry(int(t_ns), frame_id, child_frame_id, float(pose.x),
                                  float(pose.y), float(pose.theta), flat, float(twist[0]),
                                  float(twist[1]))
    except cdr.CdrError as exc:
        raise ConversionError(str(exc)) from None


def scan_cdr_to_arrays(data: bytes, max_ranges: int = MAX_SCAN_RANGES
                       ) -> tuple[FloatArray, FloatArray, int]:
    """scan_to_arrays of a serialized LaserScan (a raw subscription's bytes) and its stamp [ns],
    without building the message (`island_msgs_py.cdr`); the same values."""
    try:
        f = cdr.read_scan(data, max_ranges)
    except cdr.CdrUnsupportedError:
        try:
            msg = deserialize_message(data, LaserScan)
        except Exception as exc:  # rclpy raises its own error types for bad bytes
            raise ConversionError(f"scan: cannot deserialize: {exc}") from None
        return (*scan_to_arrays(msg, max_ranges), time_to_ns(msg.header.stamp))
    except cdr.CdrError as exc:
        raise ConversionError(str(exc)) from None
    check_scan_count(f.n_ranges, max_ranges)
    assert f.ranges is not None  # read whenever within the limit
    return (*scan_arrays(f.ranges.astype(np.float64), f.angle_min, f.angle_increment,
                          f.range_min, f.range_max), f.stamp_ns)


def arrays_to_scan_cdr(
    ranges_m: npt.ArrayLike,
    angles_rad: npt.ArrayLike,
    range_limits_m: tuple[float, float],
    t_ns: int,
    frame_id: str = "base_link",
    scan_time_s: float = 0.0,
) -> bytes:
    """arrays_to_scan serialized (what a publisher sends): the same message, built without
    rclpy's message objects (`island_msgs_py.cdr`)."""
    r, (angle_min, angle_max, inc) = scan_grid(ranges_m, angles_rad)
    lo, hi = range_limits_m
    try:
        return cdr.write_scan(int(t_ns), frame_id, (angle_min, angle_max, inc, 0.0,
                                                    float(scan_time_s), float(lo), float(hi)), r)
    except (cdr.CdrError, struct.error, OverflowError) as exc:  # a value float32 cannot hold
        raise ConversionError(f"scan: {exc}") from None
