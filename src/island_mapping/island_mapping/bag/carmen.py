"""CARMEN logs (FLASER / ODOM lines) as arrays, and their import into a rosbag2 MCAP.

`read_carmen(path) -> CarmenLog` parses a log (numpy only, no rclpy): per scan the time, the 180
ranges and the GMapping-corrected pose of the FLASER line, and the *raw* odometry reconstructed
as ../shared/data/README.md explains for GMapping-corrected logs: every ODOM line is "the
corrected pose of the previous scan plus the raw odometry accumulated since then", so the raw
increment of scan step i is `relative_poses(corrected[i-1], last ODOM before scan i)` (file order;
before the first scan the previous corrected pose is the origin), and the raw odometry poses are
these increments composed from the origin. GMapping also writes each scan's corrected pose as an
ODOM line right after the FLASER line (its timestamp is 0 or garbage): skipped, not odometry.
Log timestamps jitter, so the bag's log times (and `odom_times_s`) are made non-decreasing in
file order; scan header stamps keep the logged times (the relations refer to them).

`import_carmen(log, out_dir, beams=None)` writes sensor_msgs/LaserScan on /scan (frame
base_laser, angle_min -90 deg, 1 deg increment), the raw odometry as nav_msgs/Odometry on /odom
(at every ODOM line, with a covariance grown by a simple drift model), the GMapping pose as
nav_msgs/Odometry on /gmapping_pose (reference only, frame map) and rosgraph_msgs/Clock on
/clock. Times are the log's own timestamps (seconds since the log start) as sim time.
A sonar-like mode (`beams=16|24`) keeps that many evenly spaced beams of each scan.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from island_msgs_py.geometry import compose_poses, relative_poses, wrap_angles
from numpy.typing import NDArray

from island_mapping.bag.errors import BagError, CarmenFormatError

FLASER_BEAMS = 180
"""The Intel log's SICK scans: 180 beams."""
FLASER_ANGLE_MIN_RAD = -math.pi / 2
"""First beam to the robot's right (-90 deg), counter-clockwise..."""
FLASER_ANGLE_INCREMENT_RAD = math.pi / 180
"""...at 1 deg steps (the last beam at +89 deg)."""
SICK_MAX_RANGE_M = 80.0
"""Readings of 81.83 m in the Intel log mean 'no return': above this they are invalid."""
SICK_MIN_RANGE_M = 0.0
INTEL_RELATIONS_TIME_OFFSET_S = 976052857.338
"""Add to an Intel log timestamp to get the UNIX time used by intel.relations (README)."""
SONAR_BEAM_CHOICES = (16, 24)
"""Beam counts of the sonar-like mode (a 16-sonar Nomad ring, a 24-sonar SCITOS ring)."""

_FLASER_TAIL = 9  # x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp
_ODOM_FIELDS = 10  # ODOM x y theta tv rv accel ipc_timestamp host logger_timestamp


FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CarmenLog:
    """A parsed CARMEN log. Poses are (x [m], y [m], theta [rad]) rows; times in s since start."""

    path: Path
    times_s: FloatArray
    """(S,) scan times as logged (they match intel.relations) [s]."""
    scan_log_times_s: FloatArray
    """(S,) scan times made non-decreasing together with the ODOM times (bag log times) [s]."""
    ranges_m: FloatArray
    """(S, B) ranges [m] (values above SICK_MAX_RANGE_M mean no return)."""
    corrected: FloatArray
    """(S, 3) GMapping-corrected poses of the FLASER lines (reference, not odometry)."""
    raw_odometry: FloatArray
    """(S, 3) raw odometry poses at the scans, composed from the origin."""
    odom_times_s: FloatArray
    """(M,) times of the ODOM lines that are odometry, non-decreasing in file order [s]."""
    odom_raw: FloatArray
    """(M, 3) raw odometry poses at those ODOM lines (same frame as raw_odometry)."""
    odom_scan_index: NDArray[np.int64] = field(repr=False)
    """(M,) index of the next scan after each ODOM line (S when after the last scan)."""

    @property
    def ranges(self) -> FloatArray:
        """Alias of ranges_m: (S, B) [m]."""
        return self.ranges_m

    @property
    def n_scans(self) -> int:
        return int(self.times_s.shape[0])


def _floats(tokens: list[str], path: Path, lineno: int, what: str) -> list[float]:
    try:
        values = [float(t) for t in tokens]
    except ValueError as exc:
        raise CarmenFormatError(f"{path}:{lineno}: {what}: {exc}") from None
    if not all(math.isfinite(v) for v in values):
        raise CarmenFormatError(f"{path}:{lineno}: {what}: NaN or infinite value")
    return values


def read_carmen(path: str | os.PathLike[str]) -> CarmenLog:
    """Parse FLASER and ODOM lines of a CARMEN log (other line types are skipped).

    A malformed FLASER/ODOM line raises CarmenFormatError naming the file and line number.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="strict")
    except (OSError, UnicodeDecodeError) as exc:
        raise BagError(f"cannot read CARMEN log {p}: {exc}") from None
    times: list[float] = []
    ranges: list[list[float]] = []
    corrected: list[tuple[float, float, float]] = []
    odom_lines: list[tuple[float, float, float, float]] = []  # x y theta t
    odom_scan: list[int] = []
    last_odom_before_scan: list[tuple[float, float, float] | None] = []
    last_odom: tuple[float, float, float] | None = None
    n_beams: int | None = None
    prev_kind = ""
    for lineno, line in enumerate(text.splitlines(), start=1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        kind = tok[0]
        if kind not in ("FLASER", "ODOM"):
            prev_kind = kind
            continue
        if kind == "FLASER":
            if len(tok) < 2:
                raise CarmenFormatError(f"{p}:{lineno}: FLASER line without beam count")
            try:
                n = int(tok[1])
            except ValueError:
                raise CarmenFormatError(
                    f"{p}:{lineno}: FLASER beam count {tok[1]!r} is not an integer"
                ) from None
            if n <= 0 or len(tok) != 2 + n + _FLASER_TAIL:
                raise CarmenFormatError(
                    f"{p}:{lineno}: FLASER with {n} beams needs {2 + n + _FLASER_TAIL} fields, "
                    f"got {len(tok)}"
                )
            if n_beams is None:
                n_beams = n
            elif n != n_beams:
                raise CarmenFormatError(
                    f"{p}:{lineno}: FLASER has {n} beams, earlier scans had {n_beams}"
                )
            vals = _floats(tok[2 : 2 + n + 6], p, lineno, "FLASER")
            t = _floats([tok[2 + n + 6]], p, lineno, "FLASER timestamp")[0]
            if min(vals[:n]) < 0:
                raise CarmenFormatError(f"{p}:{lineno}: FLASER has a negative range")
            ranges.append(vals[:n])
            corrected.append((vals[n], vals[n + 1], vals[n + 2]))
            times.append(t)
            last_odom_before_scan.append(last_odom)
            last_odom = None
        elif kind == "ODOM":
            if len(tok) != _ODOM_FIELDS:
                raise CarmenFormatError(
                    f"{p}:{lineno}: ODOM needs {_ODOM_FIELDS} fields, got {len(tok)}"
                )
            v = _floats(tok[1:7], p, lineno, "ODOM")
            t = _floats([tok[7]], p, lineno, "ODOM timestamp")[0]
            if prev_kind == "FLASER" and tuple(v[:3]) == corrected[-1]:
                prev_kind = kind
                continue  # GMapping's echo of the corrected pose of the scan just logged
            last_odom = (v[0], v[1], v[2])
            odom_lines.append((v[0], v[1], v[2], t))
            odom_scan.append(len(times))
        prev_kind = kind
    if not times:
        raise CarmenFormatError(f"{p}: no FLASER line found (not a CARMEN laser log?)")
    corr = np.asarray(corrected, dtype=float)
    s = len(times)
    # Raw increment of scan i: relative(corrected[i-1], last ODOM before scan i); with no ODOM
    # line since the previous scan the robot reported no motion (increment 0).
    prev_corr = np.vstack([np.zeros((1, 3)), corr[:-1]])
    increments = np.zeros((s, 3))
    for i, od in enumerate(last_odom_before_scan):
        if od is not None:
            increments[i] = relative_poses(prev_corr[i], np.asarray(od))[0]
    raw = np.zeros((s, 3))
    pose = np.zeros(3)
    for i in range(s):
        pose = compose_poses(pose, increments[i])[0]
        raw[i] = pose
    # Every ODOM line as raw odometry: relative to the corrected pose of the scan before it.
    odom = np.asarray(odom_lines, dtype=float).reshape(-1, 4)
    scan_idx = np.asarray(odom_scan, dtype=np.int64)
    base_corr = np.vstack([np.zeros((1, 3)), corr])[scan_idx]
    base_raw = np.vstack([np.zeros((1, 3)), raw])[scan_idx]
    odom_raw = odom
    if len(odom):
        odom_raw = compose_poses(base_raw, relative_poses(base_corr, odom[:, :3]))
    scan_times = np.asarray(times, dtype=float)
    odom_log_t, scan_log_t = _file_order_times(odom[:, 3].copy(), scan_idx, scan_times)
    return CarmenLog(
        path=p,
        times_s=scan_times,
        scan_log_times_s=scan_log_t,
        ranges_m=np.asarray(ranges, dtype=float),
        corrected=corr,
        raw_odometry=raw,
        odom_times_s=odom_log_t,
        odom_raw=np.asarray(odom_raw, dtype=float).reshape(-1, 3),
        odom_scan_index=scan_idx,
    )


def _file_order_times(
    odom_t_s: FloatArray, scan_idx: NDArray[np.int64], scan_t_s: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """(ODOM times, scan times) made non-decreasing in file order [s].

    Timestamps in CARMEN logs jitter (in the Intel log 629 of 13631 ODOM stamps and 4 of 910
    scan stamps go backwards, by up to 1 s) while the file order is the order of motion: a
    reverse running minimum over the interleaved sequence lowers the stamps that ran ahead.
    """
    keys = [(int(k), 0, j) for j, k in enumerate(scan_idx)]
    keys += [(i, 1, i) for i in range(len(scan_t_s))]
    keys.sort()
    seq = np.array([odom_t_s[j] if kind == 0 else scan_t_s[j] for _, kind, j in keys])
    fixed = np.minimum.accumulate(seq[::-1])[::-1] if seq.size else seq
    odom_out = np.empty_like(odom_t_s)
    scan_out = np.empty_like(scan_t_s)
    for (_, kind, j), t in zip(keys, fixed, strict=True):
        if kind == 0:
            odom_out[j] = t
        else:
            scan_out[j] = t
    return odom_out, scan_out


def sonar_like_indices(n_beams_in: int, n_keep: int) -> NDArray[np.int64]:
    """Indices of `n_keep` evenly spaced beams out of `n_beams_in` (centred in their sectors).

    With 180 beams at 1 deg and 16 kept, the spacing is 11.25 deg; a beam's real angle differs
    from angle_min + k * increment by at most half a beam (0.5 deg).
    """
    if n_keep <= 0 or n_keep > n_beams_in:
        raise BagError(f"cannot keep {n_keep} beams of {n_beams_in}")
    step = n_beams_in / n_keep
    return np.floor(step / 2 + step * np.arange(n_keep)).astype(np.int64)


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


def import_carmen(
    log_path: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
    beams: int | None = None,
    config: CarmenImportConfig | None = None,
) -> ImportReport:
    """Write a CARMEN log as a rosbag2 MCAP directory (see module docstring)."""
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan

    from island_mapping.bag.writer import BagWriter

    cfg = config or CarmenImportConfig()
    if beams is not None and beams not in SONAR_BEAM_CHOICES:
        raise BagError(f"--beams must be one of {SONAR_BEAM_CHOICES}, got {beams}")
    log = read_carmen(log_path)
    n_in = log.ranges_m.shape[1]
    idx = sonar_like_indices(n_in, beams) if beams else np.arange(n_in)
    step = (n_in / beams) if beams else 1.0
    angle_min = FLASER_ANGLE_MIN_RAD + float(idx[0]) * FLASER_ANGLE_INCREMENT_RAD
    increment = step * FLASER_ANGLE_INCREMENT_RAD

    def ns(t: float) -> int:
        return round(t * 1e9)

    def set_time(stamp: Any, t_ns: int) -> None:
        stamp.sec, stamp.nanosec = divmod(t_ns, 1_000_000_000)

    # Odometry covariance: a diagonal drift model accumulated along the raw odometry.
    steps = np.diff(np.vstack([np.zeros((1, 3)), log.odom_raw]), axis=0)
    dist = np.hypot(steps[:, 0], steps[:, 1])
    turn = np.abs(wrap_angles(steps[:, 2]))
    var_xy = np.cumsum(cfg.trans_var_per_m * dist)
    var_th = np.cumsum(cfg.rot_var_per_rad * turn + cfg.rot_var_per_m * dist)

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
            t_ns = ns(log.scan_log_times_s[k] if kind == 1 else log.odom_times_s[k])
            if t_ns > last_clock:
                clock = Clock()
                set_time(clock.clock, t_ns)
                writer.write("/clock", clock)
                last_clock = t_ns
            if kind == 1:
                scan = LaserScan()
                set_time(scan.header.stamp, ns(log.times_s[k]))
                scan.header.frame_id = cfg.laser_frame
                scan.angle_min = angle_min
                scan.angle_increment = increment
                scan.angle_max = angle_min + increment * (len(idx) - 1)
                scan.range_min = SICK_MIN_RANGE_M
                scan.range_max = SICK_MAX_RANGE_M
                scan.ranges = log.ranges_m[k, idx].astype(np.float32).tolist()
                writer.write(cfg.scan_topic, scan, log_time_ns=t_ns)
                ref = Odometry()
                set_time(ref.header.stamp, ns(log.times_s[k]))
                ref.header.frame_id, ref.child_frame_id = cfg.map_frame, cfg.base_frame
                x, y, th = log.corrected[k]
                ref.pose.pose.position.x, ref.pose.pose.position.y = float(x), float(y)
                qz, qw = _yaw_quaternion(float(th))
                ref.pose.pose.orientation.z, ref.pose.pose.orientation.w = qz, qw
                writer.write(cfg.reference_topic, ref, log_time_ns=t_ns)
            else:
                odom = Odometry()
                set_time(odom.header.stamp, t_ns)
                odom.header.frame_id, odom.child_frame_id = cfg.odom_frame, cfg.base_frame
                x, y, th = log.odom_raw[k]
                odom.pose.pose.position.x, odom.pose.pose.position.y = float(x), float(y)
                qz, qw = _yaw_quaternion(float(th))
                odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = qz, qw
                cov = [0.0] * 36
                cov[0] = cov[7] = float(var_xy[k])
                cov[35] = float(var_th[k])
                odom.pose.covariance = cov
                writer.write(cfg.odom_topic, odom)
                n_odom += 1
    finally:
        writer.close()
    return ImportReport(Path(out_dir), log.n_scans, n_odom, len(idx))
