"""A recording's LaserScan and Odometry as a `logs.report.RecordedLog`: what `islands replay
--passive` builds islands from with the builder's passive mode (any MCAP with scans and
odometry: a recorded real run, an imported CARMEN log, a simulated run of `islands explore`).

The scan topic is the one `sensor_msgs/msg/LaserScan` topic (or `scan_topic`), the odometry
`/odom` (or the one `nav_msgs/msg/Odometry` topic that is not the reference). The reference
trajectory is `reference_topic` if given, else the first of `REFERENCE_TOPICS` the recording
has (`/gmapping_pose`, what `bag import-carmen` writes; `/ground_truth`, what the simulator
publishes): an Odometry topic, taken at each scan by stamp (the nearest message within
`logs.report.REFERENCE_TOLERANCE_S`; a scan without one has no reference pose). Each scan takes
the latest odometry received at or before it (file order); scans before the first odometry
are counted and dropped. The geometry is the LaserScan's own
(`logs.geometry.laserscan_geometry`; beams >= 5 deg apart are a sonar ring); scans of another
length or geometry are an error; NaN, infinite, negative and out-of-limit ranges are no return
(counted). A recording whose only range sensors are `sensor_msgs/msg/Range` topics (one per
sonar transducer) is refused: placing them needs each transducer's pose (TF), which a
recording read without TF does not give.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from island_msgs_py.geometry import compose_poses, relative_poses

from island_mapping.bag.errors import BagError
from island_mapping.bag.reader import BagReader, open_bag
from island_mapping.core.relations import PoseTrack
from island_mapping.logs.errors import LogFormatError
from island_mapping.logs.geometry import GeometryOverride, ScanGeometry, laserscan_geometry
from island_mapping.logs.reference import Reference, at_times
from island_mapping.logs.report import REFERENCE_TOLERANCE_S, RecordedLog
from island_mapping.logs.times import check_scan_times

SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"
RANGE_TYPE = "sensor_msgs/msg/Range"
DEFAULT_REFERENCE_TOPIC = "/gmapping_pose"
REFERENCE_TOPICS = (DEFAULT_REFERENCE_TOPIC, "/ground_truth")
"""Reference trajectories looked for, in this order, when none is named."""

Pose3 = tuple[float, float, float]


def _topic(topics: dict[str, Any], type_name: str, wanted: str | None, exclude: set[str],
           path: str) -> str:
    if wanted is not None:
        if wanted not in topics:
            raise LogFormatError(f"{path}: no topic {wanted} (topics: {', '.join(sorted(topics))})")
        if topics[wanted].type_name != type_name:
            raise LogFormatError(f"{path}: {wanted} is {topics[wanted].type_name}, expected "
                                 f"{type_name}")
        return wanted
    cands = [t for t, info in topics.items() if info.type_name == type_name and t not in exclude]
    if "/odom" in cands and type_name == ODOM_TYPE:
        return "/odom"
    if len(cands) != 1:
        ranges = [t for t, info in topics.items() if info.type_name == RANGE_TYPE]
        why = (f"; its {len(ranges)} {RANGE_TYPE} topics (one per transducer?) cannot be placed "
               "without each transducer's pose (TF): record the ring as one LaserScan"
               if not cands and ranges and type_name == SCAN_TYPE else "")
        raise LogFormatError(f"{path}: {len(cands)} {type_name} topics ({', '.join(cands)}): "
                             f"name the one to use{why}")
    return cands[0]


def _reference_topic(topics: dict[str, Any], wanted: str | None, path: str) -> str | None:
    if wanted is not None:
        return _topic(topics, ODOM_TYPE, wanted, set(), path)
    return next((t for t in REFERENCE_TOPICS
                 if t in topics and topics[t].type_name == ODOM_TYPE), None)


def _pose(msg: Any) -> tuple[float, float, float, float]:
    from island_msgs_py.conversions import odometry_to_pose

    pose, _cov, stamp_ns = odometry_to_pose(msg)
    return pose.x, pose.y, pose.theta, stamp_ns * 1e-9


@dataclass
class _Reading:
    """What is gathered from the messages, in file order."""

    topics: tuple[str, str, str | None]  # scan, odometry, reference
    name: str
    override: GeometryOverride | None
    counts: dict[str, int] = field(
        default_factory=lambda: {"scans_before_odometry": 0, "no_return_ranges": 0})
    geo: ScanGeometry | None = None
    times: list[float] = field(default_factory=list)
    ranges: list[np.ndarray] = field(default_factory=list)
    raw: list[Pose3] = field(default_factory=list)
    ref: list[tuple[float, float, float, float]] = field(default_factory=list)  # x y theta t
    lines: list[tuple[float, bool, Pose3, int]] = field(default_factory=list)
    odom: tuple[float, float, float, float] | None = None

    def scan(self, msg: Any) -> None:
        r = np.asarray(msg.ranges, dtype=np.float64)
        topic = self.topics[0]
        g = laserscan_geometry(r.size, msg.angle_min, msg.angle_max, msg.angle_increment,
                               f"{self.name}: {topic}", self.override)
        if self.geo is None:
            self.geo = g
        elif (g.n_beams, g.angle_min_rad, g.increment_rad) != (
                self.geo.n_beams, self.geo.angle_min_rad, self.geo.increment_rad):
            raise LogFormatError(f"{self.name}: {topic} scan {len(self.times)} has {g.n_beams} "
                                 f"beams or other angles than the first scan's")
        if self.odom is None:
            self.counts["scans_before_odometry"] += 1
            return
        bad = ~np.isfinite(r) | (r < max(msg.range_min, 0.0)) | (r > msg.range_max)
        self.counts["no_return_ranges"] += int(np.sum(bad))
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        self.times.append(t)
        self.ranges.append(np.where(bad, np.inf, r))
        self.raw.append(self.odom[:3])
        self.lines.append((t, True, self.odom[:3], len(self.times) - 1))

    def read(self, reader: BagReader) -> None:
        s_topic, o_topic, r_topic = self.topics
        for m in reader.messages([t for t in self.topics if t is not None]):
            msg = m.deserialize()
            if m.topic == o_topic:
                self.odom = _pose(msg)
                self.lines.append((self.odom[3], False, self.odom[:3], len(self.times) - 1))
            elif m.topic == r_topic:
                self.ref.append(_pose(msg))
            if m.topic == s_topic:
                self.scan(msg)


def read_scan_log(path: str | os.PathLike[str], *, scan_topic: str | None = None,
                  odom_topic: str | None = None, reference_topic: str | None = None,
                  override: GeometryOverride | None = None) -> tuple[RecordedLog, dict[str, int]]:
    """The recording as a RecordedLog (module docstring) and counts of what was skipped."""
    try:
        reader = open_bag(path)
    except BagError as exc:
        raise LogFormatError(f"cannot read {path}: {exc}") from None
    name = os.path.basename(os.path.normpath(str(path)))
    r_topic = _reference_topic(reader.topics, reference_topic, name)
    s_topic = _topic(reader.topics, SCAN_TYPE, scan_topic, set(), name)
    o_topic = _topic(reader.topics, ODOM_TYPE, odom_topic, {r_topic or ""}, name)
    got = _Reading((s_topic, o_topic, r_topic), name, override)
    try:
        got.read(reader)
    except BagError as exc:
        raise LogFormatError(f"cannot read {path}: {exc}") from None
    if got.geo is None or not got.times:
        raise LogFormatError(f"{name}: no {s_topic} scan with odometry before it")
    report = check_scan_times(got.times, f"{name}: {s_topic}")
    times, raw = np.asarray(got.times), np.asarray(got.raw)
    reference = None
    if r_topic is not None and got.ref:
        arr = np.asarray(got.ref, dtype=np.float64)
        reference = Reference(arr[:, 3], arr[:, :3], f"the recording's {r_topic}")
    track, track_name = _track(got.lines, raw, reference, times)
    return RecordedLog(name=name, times_s=times, ranges_m=np.vstack(got.ranges),
                       geometry=got.geo, raw_odometry=raw, track=track, track_name=track_name,
                       times=report, reference=reference), got.counts


def _track(lines: list[tuple[float, bool, Pose3, int]], raw_at_scans: np.ndarray,
           reference: Reference | None, scan_times_s: np.ndarray) -> tuple[PoseTrack, str]:
    """Every scan and odometry message after the first scan, as a PoseTrack: the reference
    pose at scans (when every scan has one; else raw odometry, and the track is no reference),
    and between scans the last scan's reference plus the raw odometry since (how a
    GMapping-corrected log defines its poses between scans)."""
    rows = [(t, s, p, k) for t, s, p, k in lines if k >= 0]
    base, name = raw_at_scans, ""
    if reference is not None:
        at, ok = at_times(reference, scan_times_s, 0.0, REFERENCE_TOLERANCE_S)
        if bool(np.all(ok)):
            base, name = at, reference.name
    times = np.array([r[0] for r in rows])
    raw = np.array([r[2] for r in rows]).reshape(-1, 3)
    is_scan = np.array([r[1] for r in rows], dtype=bool)
    k = np.array([r[3] for r in rows], dtype=np.int64)
    gm = compose_poses(base[k], relative_poses(raw_at_scans[k], raw))
    return PoseTrack(times, gm, raw, is_scan, k), name

