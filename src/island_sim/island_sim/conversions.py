"""Simulator messages <-> core values: LaserScan, Odometry, TwistStamped, Clock and stamps.

Stamps are carried as integer nanoseconds inside the simulator so that pairing messages by
stamp is exact (sim time advances in whole physics steps).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Twist, TwistStamped
from island_msgs_py.conversions import quaternion_to_yaw
from island_msgs_py.types import FloatArray, IslandTypeError, Pose2D
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan, Range

NS_PER_S = 1_000_000_000
_COV_INDEX = (0, 1, 5)  # x, y, yaw rows/cols of ROS's 6x6 pose covariance
_COV_ROWS, _COV_COLS = np.ix_(_COV_INDEX, _COV_INDEX)
# Evenly spaced bearings may differ from a perfect grid by this much (float32 fields) [rad].
_ANGLE_GRID_TOL_RAD = 1e-4


class ConversionError(ValueError):
    """A message (or value for one) is malformed; the message says which field and why."""


# ----------------------------------------------------------------------------- time


def ns_to_time(t_ns: int) -> Time:
    """builtin_interfaces/Time of `t_ns` nanoseconds (>= 0)."""
    if t_ns < 0:
        raise ConversionError(f"stamp must be >= 0 ns, got {t_ns}")
    return Time(sec=int(t_ns // NS_PER_S), nanosec=int(t_ns % NS_PER_S))


def time_to_ns(t: Time) -> int:
    """Nanoseconds of a builtin_interfaces/Time."""
    return int(t.sec) * NS_PER_S + int(t.nanosec)


def clock_msg(t_ns: int) -> Clock:
    """rosgraph_msgs/Clock for sim time `t_ns` [ns]."""
    return Clock(clock=ns_to_time(t_ns))


# ----------------------------------------------------------------------------- LaserScan


def arrays_to_scan(
    ranges_m: npt.ArrayLike,
    angles_rad: npt.ArrayLike,
    range_limits_m: tuple[float, float],
    t_ns: int,
    frame_id: str = "base_link",
    scan_time_s: float = 0.0,
) -> LaserScan:
    """LaserScan of ranges (N,) [m] at evenly spaced bearings (N,) [rad]; inf = no echo."""
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if r.shape != a.shape or r.size == 0:
        raise ConversionError(f"scan: {r.size} ranges but {a.size} angles (need N >= 1 of each)")
    inc = float(a[1] - a[0]) if a.size > 1 else 0.0
    if a.size > 1 and not np.allclose(np.diff(a), inc, atol=_ANGLE_GRID_TOL_RAD):
        raise ConversionError("scan: bearings must be evenly spaced for a LaserScan")
    lo, hi = range_limits_m
    msg = LaserScan()
    msg.header.stamp = ns_to_time(t_ns)
    msg.header.frame_id = frame_id
    msg.angle_min = float(a[0])
    msg.angle_max = float(a[-1])
    msg.angle_increment = inc
    msg.time_increment = 0.0
    msg.scan_time = float(scan_time_s)
    msg.range_min = float(lo)
    msg.range_max = float(hi)
    msg.ranges = [float(v) if math.isfinite(v) else math.inf for v in r]
    return msg


def scan_to_arrays(msg: LaserScan) -> tuple[FloatArray, FloatArray]:
    """(ranges (N,) [m], bearings (N,) [rad]); NaN and out-of-limit readings become inf."""
    r = np.asarray(msg.ranges, dtype=np.float64)
    if r.size == 0:
        raise ConversionError("scan: no ranges")
    if not (math.isfinite(msg.angle_min) and math.isfinite(msg.angle_increment)):
        raise ConversionError(
            f"scan: angle_min/angle_increment must be finite, got {msg.angle_min}, "
            f"{msg.angle_increment}"
        )
    a = msg.angle_min + msg.angle_increment * np.arange(r.size, dtype=np.float64)
    ok = np.isfinite(r) & (r >= msg.range_min) & (r <= msg.range_max)
    return np.where(ok, r, np.inf), a


def range_msg(
    range_m: float, fov_rad: float, limits_m: tuple[float, float], t_ns: int, frame_id: str
) -> Range:
    """sensor_msgs/Range of one ultrasonic transducer (inf = no echo)."""
    msg = Range()
    msg.header.stamp = ns_to_time(t_ns)
    msg.header.frame_id = frame_id
    msg.radiation_type = Range.ULTRASOUND
    msg.field_of_view = float(fov_rad)
    msg.min_range = float(limits_m[0])
    msg.max_range = float(limits_m[1])
    msg.range = float(range_m) if math.isfinite(range_m) else math.inf
    return msg


# ----------------------------------------------------------------------------- Odometry


def pose_to_odometry(
    pose: Pose2D,
    cov: npt.ArrayLike | None,
    t_ns: int,
    frame_id: str,
    child_frame_id: str = "base_link",
    twist: tuple[float, float] = (0.0, 0.0),
) -> Odometry:
    """Odometry with the pose, its 3x3 (x, y, theta) covariance in the 6x6, and (v, w) twist."""
    return fill_odometry(Odometry(), pose, cov, t_ns, frame_id, child_frame_id, twist)


def fill_odometry(
    msg: Odometry,
    pose: Pose2D,
    cov: npt.ArrayLike | None,
    t_ns: int,
    frame_id: str,
    child_frame_id: str = "base_link",
    twist: tuple[float, float] = (0.0, 0.0),
) -> Odometry:
    """Overwrite `msg` in place (publishers reuse one message: building one costs ~0.2 ms)."""
    msg.header.stamp.sec = int(t_ns // NS_PER_S)
    msg.header.stamp.nanosec = int(t_ns % NS_PER_S)
    msg.header.frame_id = frame_id
    msg.child_frame_id = child_frame_id
    position = msg.pose.pose.position
    position.x = pose.x
    position.y = pose.y
    q = msg.pose.pose.orientation
    q.z = math.sin(pose.theta / 2.0)
    q.w = math.cos(pose.theta / 2.0)
    full = np.zeros((6, 6), dtype=np.float64)
    if cov is not None:
        c = np.asarray(cov, dtype=np.float64)
        if c.shape != (3, 3) or not np.all(np.isfinite(c)):
            raise ConversionError(f"odometry covariance must be a finite 3x3, got {c.shape}")
        full[_COV_ROWS, _COV_COLS] = c
    msg.pose.covariance = full.reshape(-1)
    msg.twist.twist.linear.x = float(twist[0])
    msg.twist.twist.angular.z = float(twist[1])
    return msg


def odometry_to_pose(msg: Odometry) -> tuple[Pose2D, FloatArray, int]:
    """(pose, 3x3 covariance, stamp [ns]) of an Odometry message; ConversionError if malformed."""
    p = msg.pose.pose.position
    try:
        theta = quaternion_to_yaw(msg.pose.pose.orientation)
        pose = Pose2D(float(p.x), float(p.y), theta)
    except IslandTypeError as exc:
        raise ConversionError(f"odometry pose: {exc}") from None
    full = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
    return pose, full[_COV_ROWS, _COV_COLS], time_to_ns(msg.header.stamp)


# ----------------------------------------------------------------------------- Twist


def twist_to_command(msg: Twist) -> tuple[float, float]:
    """(v [m/s], w [rad/s]) of a Twist; ConversionError naming the field if NaN or infinite."""
    v, w = float(msg.linear.x), float(msg.angular.z)
    if not math.isfinite(v):
        raise ConversionError(f"cmd_vel linear.x is not finite ({v})")
    if not math.isfinite(w):
        raise ConversionError(f"cmd_vel angular.z is not finite ({w})")
    return v, w


def command_to_twist(v_mps: float, w_radps: float) -> Twist:
    """Twist with linear.x = v [m/s] and angular.z = w [rad/s]."""
    msg = Twist()
    msg.linear.x = float(v_mps)
    msg.angular.z = float(w_radps)
    return msg


def command_to_twist_stamped(
    v_mps: float, w_radps: float, stamp_ns: int, frame_id: str = "base_link"
) -> TwistStamped:
    """The /cmd_vel message: TwistStamped whose stamp is the sensor stamp [ns] it answers."""
    msg = TwistStamped()
    msg.header.stamp = ns_to_time(stamp_ns)
    msg.header.frame_id = frame_id
    msg.twist = command_to_twist(v_mps, w_radps)
    return msg


def twist_stamped_to_command(msg: TwistStamped) -> tuple[float, float, int]:
    """(v [m/s], w [rad/s], stamp [ns]) of a TwistStamped; ConversionError if not finite."""
    v, w = twist_to_command(msg.twist)
    return v, w, time_to_ns(msg.header.stamp)
