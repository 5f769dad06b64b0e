"""CARMEN logs into a rosbag2 MCAP (the log is read by island_mapping.logs.carmen, the one
CARMEN parser).

`read_carmen(path) -> CarmenLog`: the log's scans and raw odometry (see logs.carmen.carmen_log);
a malformed log is a CarmenFormatError (a BagError) naming the file and line.

`import_carmen(log, out_dir, beams=None)` writes sensor_msgs/LaserScan on /scan (frame
base_laser; angle_min and angle_increment of the geometry read from the log, `logs.geometry`,
or given as a `GeometryOverride`; a sonar ring of evenly spaced transducers facing outwards as
one scan with ranges from the robot's centre, like the simulator's /sonar/scan; a laser mounted
off the robot's centre, or another ring, is refused: a LaserScan without TF cannot say so), the
raw odometry as nav_msgs/Odometry on /odom
(at every ODOM line, with a covariance grown by a simple drift model), the GMapping pose as
nav_msgs/Odometry on /gmapping_pose (reference only, frame map; not for a log without corrected
poses) and rosgraph_msgs/Clock on
/clock. Times are the log's own timestamps (seconds since the log start) as sim time; the bag's
log times are made non-decreasing in file order (scan header stamps keep the logged times).
A sonar-like mode (`beams=16|24`) keeps that many evenly spaced beams of each scan.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from island_msgs_py.geometry import wrap_angles

from island_mapping.bag.errors import BagError, CarmenFormatError
from island_mapping.logs import carmen as logs_carmen
from island_mapping.logs.carmen import (
    FLASER_ANGLE_INCREMENT_RAD,
    FLASER_ANGLE_MIN_RAD,
    CarmenLog,
    FloatArray,
)
from island_mapping.logs.errors import LogFormatError
from island_mapping.logs.geometry import GeometryOverride

__all__ = [
    "FLASER_ANGLE_INCREMENT_RAD",
    "FLASER_ANGLE_MIN_RAD",
    "CarmenImportConfig",
    "CarmenLog",
    "ImportReport",
    "import_carmen",
    "read_carmen",
    "sonar_like_indices",
]

SICK_MAX_RANGE_M = 80.0
"""Readings of 81.83 m in the Intel log mean 'no return': above this they are invalid."""
SICK_MIN_RANGE_M = 0.0
SONAR_BEAM_CHOICES = (16, 24)
"""Beam counts of the sonar-like mode (a 16-sonar Nomad ring, a 24-sonar SCITOS ring)."""


def read_carmen(path: str | os.PathLike[str], override: GeometryOverride | None = None,
                scan_lines: str | None = None) -> CarmenLog:
    """The scans and raw odometry of a CARMEN log (logs.carmen), bad input (a line, the scan
    geometry, the times) as CarmenFormatError."""
    try:
        records = logs_carmen.read_carmen_records(path).with_scans(scan_lines)
        return logs_carmen.carmen_log(records, override)
    except LogFormatError as exc:
        raise CarmenFormatError(str(exc)) from None


def sonar_like_indices(n_beams_in: int, n_keep: int) -> np.ndarray:
    """Indices of `n_keep` evenly spaced beams out of `n_beams_in` (logs.carmen's), bad counts
    as BagError."""
    try:
        return logs_carmen.sonar_like_indices(n_beams_in, n_keep)
    except logs_carmen.CarmenFormatError:
        raise BagError(f"cannot keep {n_keep} beams of {n_beams_in}") from None


@dataclass(frozen=True)
class CarmenImportConfig:
    """How a CARMEN log becomes a bag (the single source of the importer's defaults)."""

    scan_topic: str = field(default="/scan", metadata={"help": "LaserScan topic"})
    odom_topic: str = field(default="/odom", metadata={"help": "raw odometry topic"})
    reference_topic: str = field(
        default="/gmapping_pose",
        metadata={"help": "GMapping-corrected pose topic (reference only, never for mapping)"},
    )
    laser_frame: str = field(default="base_laser", metadata={"help": "scan frame_id"})
    odom_frame: str = field(default="odom", metadata={"help": "odometry frame_id"})
    base_frame: str = field(default="base_link", metadata={"help": "robot frame"})
    map_frame: str = field(default="map", metadata={"help": "frame of the GMapping pose"})
    trans_var_per_m: float = field(
        default=0.0025,
        metadata={"help": "odometry x/y variance added per metre travelled [m^2/m]"},
    )
    rot_var_per_rad: float = field(
        default=0.0025,
        metadata={"help": "odometry heading variance added per radian turned [rad^2/rad]"},
    )
    rot_var_per_m: float = field(
        default=0.0005,
        metadata={"help": "odometry heading variance added per metre travelled [rad^2/m]"},
    )
    compression: str = field(default="zstd", metadata={"help": "MCAP chunk compression"})


@dataclass(frozen=True)
class ImportReport:
    """What `import_carmen` wrote."""

    out_dir: Path
    scans: int
    odometry: int
    beams: int


def _yaw_quaternion(theta: float) -> tuple[float, float]:
    return math.sin(theta / 2), math.cos(theta / 2)


def _ns(t: float) -> int:
    return round(t * 1e9)


def _set_time(stamp: Any, t_ns: int) -> None:
    stamp.sec, stamp.nanosec = divmod(t_ns, 1_000_000_000)


def _odometry(t_ns: int, frame: str, child: str, pose: FloatArray) -> Any:
    """A nav_msgs/Odometry at pose (x, y, theta) [m, rad]."""
    from nav_msgs.msg import Odometry

    msg = Odometry()
    _set_time(msg.header.stamp, t_ns)
    msg.header.frame_id, msg.child_frame_id = frame, child
    x, y, th = pose
    msg.pose.pose.position.x, msg.pose.pose.position.y = float(x), float(y)
    qz, qw = _yaw_quaternion(float(th))
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = qz, qw
    return msg


def _laser_scan(t_ns: int, frame: str, ranges_m: FloatArray, angle_min_rad: float,
                increment_rad: float) -> Any:
    """A sensor_msgs/LaserScan of the kept beams."""
    from sensor_msgs.msg import LaserScan

    scan = LaserScan()
    _set_time(scan.header.stamp, t_ns)
    scan.header.frame_id = frame
    scan.angle_min = angle_min_rad
    scan.angle_increment = increment_rad
    scan.angle_max = angle_min_rad + increment_rad * (len(ranges_m) - 1)
    scan.range_min = SICK_MIN_RANGE_M
    scan.range_max = SICK_MAX_RANGE_M
    scan.ranges = ranges_m.astype(np.float32).tolist()
    return scan


def _drift_variances(odom_raw: FloatArray, cfg: CarmenImportConfig
                     ) -> tuple[FloatArray, FloatArray]:
    """(x/y variance [m^2], heading variance [rad^2]) at each ODOM line: a diagonal drift
    model accumulated along the raw odometry."""
    steps = np.diff(np.vstack([np.zeros((1, 3)), odom_raw]), axis=0)
    dist = np.hypot(steps[:, 0], steps[:, 1])
    turn = np.abs(wrap_angles(steps[:, 2]))
    var_xy = np.cumsum(cfg.trans_var_per_m * dist)
    var_th = np.cumsum(cfg.rot_var_per_rad * turn + cfg.rot_var_per_m * dist)
    return var_xy, var_th


MAX_LOG_TIME_S = 2**31 - 1
"""Latest log time a ROS stamp holds (builtin_interfaces/Time.sec is an int32) [s]."""


def _check_times(log_path: str | os.PathLike[str], what: str, times_s: Any) -> None:
    """BagError naming the file and the first time outside [0, MAX_LOG_TIME_S]."""
    t = np.asarray(times_s, dtype=np.float64)
    bad = np.flatnonzero(~(np.isfinite(t) & (t >= 0) & (t <= MAX_LOG_TIME_S)))
    if bad.size:
        raise BagError(f"{log_path}: {what} time {t[bad[0]]:.6g} s (record {bad[0]}) is outside "
                       f"[0, {MAX_LOG_TIME_S}] s, the range of a ROS stamp (the limit)")


# How far a sonar ring's transducers may be from evenly spaced and radial to be a LaserScan [rad].
_RING_TOL_RAD = 1e-3


def _scan_fan(log: CarmenLog, log_path: str | os.PathLike[str]
              ) -> tuple[FloatArray, float, float]:
    """(ranges [m] from the LaserScan's origin (S, B), angle_min [rad], angle_increment [rad]):
    a laser's own; a sonar ring's from the robot's centre (range + radius, as the simulator's
    /sonar/scan), when its transducers are evenly spaced and face away from the centre. A
    LaserScan has no room for a laser's mount or an irregular ring: BagError naming the log."""
    geo = log.geometry
    assert geo is not None
    if any(log.mount):
        raise BagError(f"{log_path}: the laser sits at {log.mount} (x [m], y [m], theta [rad]) "
                       "on the robot, which a LaserScan without TF cannot carry: use "
                       "`islands eval-relations` on the log")
    if geo.beam_poses is None:
        return log.ranges_m, geo.angle_min_rad, geo.increment_rad
    pose = np.asarray(geo.beam_poses, dtype=np.float64)
    radius = np.hypot(pose[:, 0], pose[:, 1])
    steps = wrap_angles(np.diff(pose[:, 2]))
    radial = np.abs(wrap_angles(np.arctan2(pose[:, 1], pose[:, 0]) - pose[:, 2]))
    if not (np.ptp(steps) <= _RING_TOL_RAD and np.ptp(radius) <= 1e-3
            and bool(np.all((radial <= _RING_TOL_RAD) | (radius < 1e-6)))):
        raise BagError(f"{log_path}: its {geo.n_beams} sonar transducers are not an evenly "
                       "spaced ring facing outwards, which is all a LaserScan can carry: use "
                       "`islands eval-relations` on the log")
    return log.ranges_m + float(radius.mean()), float(pose[0, 2]), float(steps.mean())


def import_carmen(
    log_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    beams: int | None = None,
    config: CarmenImportConfig | None = None,
    override: GeometryOverride | None = None,
    scan_lines: str | None = None,
) -> ImportReport:
    """Write a CARMEN log as a rosbag2 MCAP directory (see module docstring); `scan_lines`
    chooses the sensor whose lines are the scans (default: the log's first laser, else its
    SONAR lines)."""
    from rosgraph_msgs.msg import Clock

    from island_mapping.bag.writer import BagWriter

    cfg = config or CarmenImportConfig()
    if beams is not None and beams not in SONAR_BEAM_CHOICES:
        raise BagError(f"--beams must be one of {SONAR_BEAM_CHOICES}, got {beams}")
    log = read_carmen(log_path, override, scan_lines)
    assert log.geometry is not None
    _check_times(log_path, "scan", log.scan_log_times_s)
    _check_times(log_path, "ODOM", log.odom_times_s)
    ranges, angle_min, increment = _scan_fan(log, log_path)
    n_in = ranges.shape[1]
    idx = sonar_like_indices(n_in, beams) if beams else np.arange(n_in)
    step = (n_in / beams) if beams else 1.0
    angle_min += float(idx[0]) * increment
    increment *= step
    var_xy, var_th = _drift_variances(log.odom_raw, cfg)
    # Events in file order (ODOM lines before scan i carry odom_scan_index i), log times
    # non-decreasing; scan header stamps keep the logged times.
    events: list[tuple[int, int, int]] = [(int(k), 0, j) for j, k in enumerate(log.odom_scan_index)]
    events += [(i, 1, i) for i in range(log.n_scans)]
    events.sort()
    writer = BagWriter(out_dir, compression=cfg.compression)
    n_odom = 0
    try:
        last_clock = -1
        for _, kind, k in events:
            t_ns = _ns(log.scan_log_times_s[k] if kind == 1 else log.odom_times_s[k])
            if t_ns > last_clock:
                clock = Clock()
                _set_time(clock.clock, t_ns)
                writer.write("/clock", clock)
                last_clock = t_ns
            if kind == 1:
                stamp = _ns(log.times_s[k])
                writer.write(cfg.scan_topic, _laser_scan(stamp, cfg.laser_frame,
                                                         ranges[k, idx], angle_min,
                                                         increment), log_time_ns=t_ns)
                if log.has_corrected:
                    writer.write(cfg.reference_topic,
                                 _odometry(stamp, cfg.map_frame, cfg.base_frame,
                                           log.corrected[k]), log_time_ns=t_ns)
            else:
                odom = _odometry(t_ns, cfg.odom_frame, cfg.base_frame, log.odom_raw[k])
                cov = [0.0] * 36
                cov[0] = cov[7] = float(var_xy[k])
                cov[35] = float(var_th[k])
                odom.pose.covariance = cov
                writer.write(cfg.odom_topic, odom)
                n_odom += 1
    finally:
        writer.close()
    return ImportReport(Path(out_dir), log.n_scans, n_odom, len(idx))
