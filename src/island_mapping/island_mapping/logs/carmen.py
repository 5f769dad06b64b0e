"""CARMEN log files: the views every tool reads of the one parser's records (pure: numpy only).

The lines are parsed by `logs.carmen_lines` (`parse_carmen`, `read_carmen_records` ->
`CarmenRecords`, re-exported here). The scans of a log are the lines of one range sensor
(`CarmenRecords.scan_kind`: FLASER if any, else ROBOTLASER1, else RLASER, else SONAR, or the
user's choice); where its beams point and where it sits on the robot are read from the data
(`logs.geometry`: the lines' own fields, PARAM lines, the format), never assumed.

Two views of a GMapping-corrected log (../shared/data/README.md) are assembled from the records:

- `carmen_log` -> `CarmenLog`: per scan the logged time, the ranges, the GMapping-corrected pose
  of the robot at the scan and the *raw* odometry: every ODOM line is "the corrected pose of the
  previous scan plus the raw odometry accumulated since then", so the raw increment of scan i
  is relative(corrected[i-1], last ODOM before scan i) (before the first scan the previous
  corrected pose is the origin), and the raw poses are these increments composed from the
  origin; every ODOM line as raw odometry too (what the MCAP importer writes, what the offline
  island builder reads). A FLASER/RLASER line's pose is the laser's (CARMEN's definition): the
  robot's is that composed with the inverse of the laser's mount (`logs.geometry.carmen_mount`,
  0 when the log has no offset PARAM lines, as the Intel log). SONAR lines carry no pose: the
  raw odometry at a sonar scan is the last ODOM line's pose, and the log has no corrected poses
  (`has_corrected`). A log without ODOM lines is refused: its raw odometry is not in it;
- `pose_track` -> `PoseTrack`: the GMapping pose and the raw odometry at every scan and ODOM
  line after the first scan, in file order (the GMapping trajectory the relations are scored
  against, and the raw odometry that bridges a relation time to the nearest scan).

GMapping writes each scan's corrected pose again as an ODOM line right after the FLASER line
(its timestamp is 0 or garbage): such an echo is flagged (`OdomRecord.echo`) and is odometry in
neither view. Times are the readings' (IPC) timestamps in seconds since the log's start.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from island_msgs_py.geometry import compose_poses, relative_poses
from numpy.typing import NDArray

from island_mapping.core.relations import PoseTrack
from island_mapping.logs.carmen_lines import (
    LASER_KINDS,
    LINE_PARSERS,
    SCAN_KINDS,
    CarmenFormatError,
    CarmenRecord,
    CarmenRecords,
    LaserRecord,
    OdomRecord,
    Pose,
    parse_carmen,
    read_carmen_records,
)
from island_mapping.logs.geometry import (
    GeometryOverride,
    ScanGeometry,
    ScanGeometryError,
    SensorKind,
    carmen_geometry,
    carmen_mount,
)
from island_mapping.logs.times import TimeReport, check_scan_times

__all__ = [
    "LASER_KINDS", "LINE_PARSERS", "SCAN_KINDS", "CarmenFormatError", "CarmenLog",
    "CarmenRecord", "CarmenRecords", "LaserRecord", "OdomRecord", "Pose", "carmen_log",
    "flaser_angles", "parse_carmen", "pose_track", "read_carmen_records", "scan_geometry",
    "sonar_like_indices",
]

FloatArray = NDArray[np.float64]
NO_ECHO_MIN_FRACTION = 0.01
"""A SONAR log's largest reading is its no-echo value when at least this fraction of all its
readings equal it (a sonar reports its maximum when nothing echoes) [-]."""

FLASER_ANGLE_MIN_RAD = -math.pi / 2
"""A FLASER scan without PARAM lines: the first beam to the robot's right (-90 deg), counter-
clockwise (`logs.geometry`)..."""
FLASER_ANGLE_INCREMENT_RAD = math.pi / 180
"""...at 1 deg steps for 180 beams (the Intel log: the last at +89 deg)."""


# ----- the scans and the raw odometry -----


@dataclass(frozen=True)
class CarmenLog:
    """A parsed CARMEN log. Poses are (x [m], y [m], theta [rad]) rows; times in s since start."""

    path: Path
    times_s: FloatArray
    """(S,) scan times as logged (they match intel.relations) [s]."""
    scan_log_times_s: FloatArray
    """(S,) scan times made non-decreasing together with the ODOM times (bag log times) [s]."""
    ranges_m: FloatArray
    """(S, B) ranges [m] (values above the sensor's maximum mean no return)."""
    corrected: FloatArray
    """(S, 3) the robot's GMapping-corrected poses at the scans (reference, not odometry; the
    raw odometry when `has_corrected` is False)."""
    raw_odometry: FloatArray
    """(S, 3) raw odometry poses at the scans, composed from the origin."""
    odom_times_s: FloatArray
    """(M,) times of the ODOM lines that are odometry, non-decreasing in file order [s]."""
    odom_raw: FloatArray
    """(M, 3) raw odometry poses at those ODOM lines (same frame as raw_odometry)."""
    odom_scan_index: NDArray[np.int64] = field(repr=False)
    """(M,) index of the next scan after each ODOM line (S when after the last scan)."""
    geometry: ScanGeometry | None = None
    """Where the beams point (logs.geometry; read from the data, or given)."""
    mount: Pose = (0.0, 0.0, 0.0)
    """The sensor's pose on the robot (ROBOTLASER1's fields; PARAM offsets for FLASER/RLASER,
    the rear laser turned by pi; 0 for SONAR, whose transducers have their own) [m, m, rad]."""
    times: TimeReport | None = None
    """The scan times' check (steps back counted)."""
    skipped: dict[str, int] = field(default_factory=dict)
    """Lines not read, by type (other sensors' lines as e.g. RLASER), and SONAR readings at
    the no-echo value (`no_echo_readings`)."""
    has_corrected: bool = True
    """Whether the scans carry corrected poses (SONAR lines do not)."""

    @property
    def ranges(self) -> FloatArray:
        """Alias of ranges_m: (S, B) [m]."""
        return self.ranges_m

    @property
    def n_scans(self) -> int:
        return int(self.times_s.shape[0])


def scan_geometry(records: CarmenRecords,
                  override: GeometryOverride | None = None) -> ScanGeometry:
    """The geometry of the log's scans (logs.geometry): given, the scans' own (ROBOTLASER1 and
    SONAR, which must agree from line to line), or from the PARAM lines and the beam count;
    ScanGeometryError when it cannot be known."""
    scans = records.scans
    if not scans:
        raise CarmenFormatError(f"{records.source}: no {', '.join(SCAN_KINDS)} line (not a "
                                "CARMEN log of a range sensor?)")
    n_beams = len(scans[0].ranges_m)
    for s in scans:
        if len(s.ranges_m) != n_beams:
            raise CarmenFormatError(
                f"{records.source}:{s.lineno}: {s.kind} has {len(s.ranges_m)} beams, earlier "
                f"scans had {n_beams} (mixed scan lengths)")
    first = scans[0].geometry
    given = override is not None and override.given
    if records.scan_kind == "SONAR" and given:
        raise ScanGeometryError(f"{records.source}: --fov-deg/--angle-min-deg do not apply to "
                                "SONAR lines (each gives its transducers' poses)")
    if first is None or given:
        return carmen_geometry(records.scan_kind, n_beams, records.params, records.source,
                               override)
    for s in scans:
        g = s.geometry
        if g is None or not (math.isclose(g.angle_min_rad, first.angle_min_rad, abs_tol=1e-6)
                             and math.isclose(g.increment_rad, first.increment_rad,
                                              abs_tol=1e-9)) or s.mount != scans[0].mount or (
                g.beam_poses != first.beam_poses):
            raise CarmenFormatError(f"{records.source}:{s.lineno}: {s.kind} geometry or sensor "
                                    "mount differs from the first scan's")
    return first


def _mount(records: CarmenRecords) -> Pose:
    """The scanning sensor's pose on the robot (see CarmenLog.mount)."""
    kind = records.scan_kind
    if kind in ("FLASER", "RLASER"):
        return carmen_mount(kind, records.params, records.source)
    return records.scans[0].mount if kind == "ROBOTLASER1" else (0.0, 0.0, 0.0)


def _robot_poses(records: CarmenRecords, mount: Pose) -> FloatArray:
    """(S, 3) the robot's pose at each scan as the lines give it: a FLASER/RLASER line's pose is
    the laser's, so the robot's is it composed with the mount's inverse; ROBOTLASER1 gives the
    robot's; SONAR none (NaN)."""
    poses = np.asarray([s.pose for s in records.scans], dtype=np.float64).reshape(-1, 3)
    if records.scan_kind in ("FLASER", "RLASER") and any(mount):
        inv = relative_poses(np.asarray(mount, dtype=np.float64), np.zeros(3))
        poses = compose_poses(poses, inv)
    return poses


def _no_echo(ranges_m: FloatArray) -> tuple[FloatArray, int]:
    """A sonar ring's readings at its no-echo value (NO_ECHO_MIN_FRACTION) as inf, and how
    many there were."""
    if ranges_m.size == 0:
        return ranges_m, 0
    top = float(ranges_m.max())
    hit = ranges_m == top
    if np.sum(hit) < NO_ECHO_MIN_FRACTION * ranges_m.size:
        return ranges_m, 0
    return np.where(hit, np.inf, ranges_m), int(np.sum(hit))


def carmen_log(records: CarmenRecords, override: GeometryOverride | None = None) -> CarmenLog:
    """The scans and the raw odometry of a GMapping-corrected log (see the module docstring);
    the scan geometry (`scan_geometry`) and times (`logs.times.check_scan_times`) checked."""
    scans = records.scans
    geometry = scan_geometry(records, override)
    times = check_scan_times([s.time_s for s in scans], records.source,
                             [s.lineno for s in scans])
    odom_lines: list[tuple[float, float, float, float]] = []  # x y theta t
    odom_scan: list[int] = []
    last_odom_before_scan: list[Pose | None] = []
    last_odom: Pose | None = None
    skipped = dict(records.skipped)
    for rec in records.records:
        if isinstance(rec, LaserRecord):
            if not records.is_scan(rec):
                skipped[rec.kind] = skipped.get(rec.kind, 0) + 1
                continue
            last_odom_before_scan.append(last_odom)
            last_odom = None if records.scans_have_poses else last_odom
        elif not rec.echo:
            last_odom = rec.pose
            odom_lines.append((*rec.pose, rec.time_s))
            odom_scan.append(len(last_odom_before_scan))
    if not odom_lines and len(scans) > 1:
        raise CarmenFormatError(f"{records.source}: no ODOM lines: the robot's raw odometry is "
                                f"not in the log, and islands cannot be built without it")
    mount = _mount(records)
    ranges = np.asarray([s.ranges_m for s in scans], dtype=float)
    if geometry.sensor is SensorKind.SONAR_RING:
        ranges, skipped["no_echo_readings"] = _no_echo(ranges)
    odom = np.asarray(odom_lines, dtype=float).reshape(-1, 4)
    scan_idx = np.asarray(odom_scan, dtype=np.int64)
    if records.scans_have_poses:
        corr = _robot_poses(records, mount)
        raw = _raw_at_scans(corr, last_odom_before_scan)
        # Every ODOM line as raw odometry: relative to the corrected pose of the scan before it.
        base_corr = np.vstack([np.zeros((1, 3)), corr])[scan_idx]
        base_raw = np.vstack([np.zeros((1, 3)), raw])[scan_idx]
        odom_raw = compose_poses(base_raw, relative_poses(base_corr, odom[:, :3]))
    else:  # no poses in the scan lines: the ODOM lines are the raw odometry
        first = odom[0, :3] if len(odom) else np.zeros(3)  # one scan and no ODOM line
        raw = np.asarray([first if p is None else p for p in last_odom_before_scan], dtype=float)
        corr, odom_raw = raw, odom[:, :3]
    scan_times = np.asarray([s.time_s for s in scans], dtype=float)
    odom_log_t, scan_log_t = _file_order_times(odom[:, 3].copy(), scan_idx, scan_times)
    return CarmenLog(
        path=Path(records.source), times_s=scan_times, scan_log_times_s=scan_log_t,
        ranges_m=ranges, corrected=corr, raw_odometry=raw, odom_times_s=odom_log_t,
        odom_raw=np.asarray(odom_raw, dtype=float).reshape(-1, 3), odom_scan_index=scan_idx,
        geometry=geometry, mount=mount, times=times, skipped=skipped,
        has_corrected=records.scans_have_poses,
    )


def _raw_at_scans(corr: FloatArray, last_odom_before_scan: list[Pose | None]) -> FloatArray:
    """Raw odometry at the scans: the increment of scan i is relative(corrected[i-1], last ODOM
    before scan i) (0 when no ODOM line came since the previous scan: no motion reported),
    composed from the origin."""
    s = corr.shape[0]
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
    return raw


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


# ----- the GMapping trajectory -----


def pose_track(records: CarmenRecords) -> PoseTrack:
    """Poses at every scan line and every ODOM line after the first scan (echoes are not
    odometry), in file order: the GMapping pose (the robot's corrected pose for scans,
    corrected + raw odometry between), raw odometry (from the first scan's frame), the latest
    scan's index. The GMapping baseline depends on every such line: a relation time takes the
    nearest line. A log whose scans carry no pose (SONAR): both are the ODOM lines' poses."""
    times: list[float] = []
    gm: list[FloatArray] = []
    raw: list[FloatArray] = []
    is_scan: list[bool] = []
    scan_idx: list[int] = []
    n_scans = 0
    posed = records.scans_have_poses
    robot = _robot_poses(records, _mount(records)) if records.scans else np.zeros((0, 3))
    last_corrected: FloatArray | None = None  # corrected pose of the latest scan
    last_raw_at_scan = np.zeros(3)  # raw odometry pose of the latest scan
    if not posed:  # scans before any ODOM line: where the first ODOM line has the robot
        last_raw_at_scan = next((np.asarray(r.pose, dtype=np.float64) for r in records.records
                                 if isinstance(r, OdomRecord) and not r.echo), last_raw_at_scan)
    last_odom: FloatArray | None = None  # pose of the latest ODOM line since that scan
    for rec in records.records:
        if isinstance(rec, LaserRecord) and not records.is_scan(rec):
            continue  # another sensor's line
        if isinstance(rec, LaserRecord):
            if not posed:
                last_raw_at_scan = last_odom if last_odom is not None else last_raw_at_scan
                pose = last_raw_at_scan
            else:
                pose = robot[n_scans]
                if last_corrected is not None and last_odom is not None:
                    inc = relative_poses(last_corrected, last_odom)
                    last_raw_at_scan = compose_poses(last_raw_at_scan, inc)[0]
                last_odom = None
            last_corrected = pose
            raw.append(last_raw_at_scan.copy())
            is_scan.append(True)
            scan_idx.append(n_scans)
            n_scans += 1
        elif rec.echo or (last_corrected is None and posed):
            continue  # the repeat right after a scan, or odometry before the first scan
        else:
            last_odom = pose = np.asarray(rec.pose, dtype=np.float64)
            if last_corrected is None:
                continue  # odometry before the first (pose-less) scan: its raw pose only
            raw.append(pose.copy() if not posed else
                       compose_poses(last_raw_at_scan, relative_poses(last_corrected, pose))[0])
            is_scan.append(False)
            scan_idx.append(n_scans - 1)
        times.append(rec.time_s)
        gm.append(pose)
    if n_scans == 0:
        raise CarmenFormatError(f"{records.source}: no {', '.join(SCAN_KINDS)} lines")
    return PoseTrack(
        np.asarray(times, dtype=np.float64),
        np.asarray(gm, dtype=np.float64).reshape(-1, 3),
        np.asarray(raw, dtype=np.float64).reshape(-1, 3),
        np.asarray(is_scan, dtype=bool),
        np.asarray(scan_idx, dtype=np.int64),
    )


# ----- scan geometry -----


def flaser_angles(n_beams: int) -> FloatArray:
    """Robot-frame angles [rad] of a FLASER scan's n_beams readings by the format's own rule
    (a 180 deg scan from -90 deg, counter-clockwise: `logs.geometry.carmen_geometry` without
    PARAM lines; 180 beams are 1 deg apart, checked on the Intel log: consecutive scans placed
    by their corrected poses overlap to a 3 cm median only with this convention).
    ScanGeometryError for a beam count the format does not fix."""
    return carmen_geometry("FLASER", n_beams, {}, f"a FLASER scan of {n_beams} beams").angles()


def sonar_like_indices(n_beams_in: int, n_keep: int) -> NDArray[np.int64]:
    """Indices of `n_keep` evenly spaced beams out of `n_beams_in`, each centred in its sector
    (the sonar-like modes: a 16-sonar Nomad ring, a 24-sonar SCITOS ring).

    With 180 beams at 1 deg and 16 kept, the spacing is 11.25 deg; a beam's real angle differs
    from angle_min + k * increment by at most half a beam (0.5 deg).
    """
    if n_keep <= 0 or n_keep > n_beams_in:
        raise CarmenFormatError(f"beams: expected 1..{n_beams_in} beams to keep, got {n_keep}")
    step = n_beams_in / n_keep
    return np.floor(step / 2 + step * np.arange(n_keep)).astype(np.int64)
