"""A recording's LaserScan and Odometry as a `logs.report.RecordedLog`: what `islands replay
--passive` builds islands from with the builder's passive mode (any MCAP with scans and
odometry: a recorded real run, an imported CARMEN log).

The scan topic is the one `sensor_msgs/msg/LaserScan` topic (or `scan_topic`), the odometry
`/odom` (or the one `nav_msgs/msg/Odometry` topic that is not the reference); a
`reference_topic` (default /gmapping_pose, what `bag import-carmen` writes) gives the reference
trajectory. Each scan takes the latest odometry received at or before it (file order); scans
before the first odometry are counted and dropped. The geometry is the LaserScan's own
(`logs.geometry.laserscan_geometry`); scans of another length or geometry are an error; NaN,
infinite, negative and out-of-limit ranges are no return (counted).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from island_msgs_py.geometry import compose_poses, relative_poses

from island_mapping.bag.errors import BagError
from island_mapping.bag.reader import open_bag
from island_mapping.core.relations import PoseTrack
from island_mapping.logs.errors import LogFormatError
from island_mapping.logs.geometry import GeometryOverride, ScanGeometry, laserscan_geometry
from island_mapping.logs.report import RecordedLog
from island_mapping.logs.times import check_scan_times

SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"
DEFAULT_REFERENCE_TOPIC = "/gmapping_pose"


def _topic(topics: dict[str, Any], type_name: str, wanted: str | None, exclude: set[str],
           path: str) -> str:
    if wanted is not None:
        if wanted not in topics:
            raise LogFormatError(f"{path}: no topic {wanted} (topics: {', '.join(sorted(topics))})")
        return wanted
    cands = [t for t, info in topics.items() if info.type_name == type_name and t not in exclude]
    if "/odom" in cands and type_name == ODOM_TYPE:
        return "/odom"
    if len(cands) != 1:
        raise LogFormatError(f"{path}: {len(cands)} {type_name} topics ({', '.join(cands)}): "
                             f"name the one to use")
    return cands[0]


def _pose(msg: Any) -> tuple[float, float, float, float]:
    from island_msgs_py.conversions import odometry_to_pose

    pose, _cov, stamp_ns = odometry_to_pose(msg)
    return pose.x, pose.y, pose.theta, stamp_ns * 1e-9


def read_scan_log(path: str | os.PathLike[str], *, scan_topic: str | None = None,
                  odom_topic: str | None = None, reference_topic: str = DEFAULT_REFERENCE_TOPIC,
                  override: GeometryOverride | None = None) -> tuple[RecordedLog, dict[str, int]]:
    """The recording as a RecordedLog (module docstring) and counts of what was skipped."""
    try:
        reader = open_bag(path)
    except BagError as exc:
        raise LogFormatError(f"cannot read {path}: {exc}") from None
    name = os.path.basename(os.path.normpath(str(path)))
    ref_topic = reference_topic if reference_topic in reader.topics else None
    s_topic = _topic(reader.topics, SCAN_TYPE, scan_topic, set(), name)
    o_topic = _topic(reader.topics, ODOM_TYPE, odom_topic, {ref_topic or ""}, name)
    counts = {"scans_before_odometry": 0, "no_return_ranges": 0}
    geo: ScanGeometry | None = None
    times: list[float] = []
    ranges: list[np.ndarray] = []
    raw: list[tuple[float, float, float]] = []
    ref: list[tuple[float, float, float]] = []
    lines: list[tuple[float, bool, tuple[float, float, float], int]] = []
    odom: tuple[float, float, float, float] | None = None
    last_ref = (math.nan, math.nan, math.nan)
    wanted = [t for t in (s_topic, o_topic, ref_topic) if t is not None]
    try:
        for m in reader.messages(wanted):
            msg = m.deserialize()
            if m.topic == o_topic:
                odom = _pose(msg)
                lines.append((odom[3], False, odom[:3], len(times) - 1))
            elif m.topic == ref_topic:
                last_ref = _pose(msg)[:3]
                if ref and len(ref) == len(times):
                    ref[-1] = last_ref
            else:
                r = np.asarray(msg.ranges, dtype=np.float64)
                g = laserscan_geometry(r.size, msg.angle_min, msg.angle_max, msg.angle_increment,
                                       f"{name}: {s_topic}", override)
                if geo is None:
                    geo = g
                elif (g.n_beams, g.angle_min_rad, g.increment_rad) != (
                        geo.n_beams, geo.angle_min_rad, geo.increment_rad):
                    raise LogFormatError(f"{name}: {s_topic} scan {len(times)} has {g.n_beams} "
                                         f"beams or other angles than the first scan's")
                if odom is None:
                    counts["scans_before_odometry"] += 1
                    continue
                bad = ~np.isfinite(r) | (r < max(msg.range_min, 0.0)) | (r > msg.range_max)
                counts["no_return_ranges"] += int(np.sum(bad))
                t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
                times.append(t)
                ranges.append(np.where(bad, np.inf, r))
                raw.append(odom[:3])
                ref.append(last_ref)
                lines.append((t, True, odom[:3], len(times) - 1))
    except BagError as exc:
        raise LogFormatError(f"cannot read {path}: {exc}") from None
    if geo is None or not times:
        raise LogFormatError(f"{name}: no {s_topic} scan with odometry before it")
    report = check_scan_times(times, f"{name}: {s_topic}")
    track, track_name = _track(lines, np.asarray(raw), np.asarray(ref), ref_topic)
    return RecordedLog(name=name, times_s=np.asarray(times), ranges_m=np.vstack(ranges),
                       geometry=geo, raw_odometry=np.asarray(raw), track=track,
                       track_name=track_name, times=report), counts


def _track(lines: list[tuple[float, bool, tuple[float, float, float], int]],
           raw_at_scans: np.ndarray, ref_at_scans: np.ndarray, ref_topic: str | None
           ) -> tuple[PoseTrack, str]:
    """Every scan and odometry message after the first scan, as a PoseTrack: the reference pose
    at scans (else raw odometry), and between scans the last scan's reference plus the raw
    odometry since (how a GMapping-corrected log defines its poses between scans)."""
    rows = [(t, s, p, k) for t, s, p, k in lines if k >= 0]
    has_ref = ref_topic is not None and bool(np.all(np.isfinite(ref_at_scans)))
    base = ref_at_scans if has_ref else raw_at_scans
    times = np.array([r[0] for r in rows])
    raw = np.array([r[2] for r in rows]).reshape(-1, 3)
    is_scan = np.array([r[1] for r in rows], dtype=bool)
    k = np.array([r[3] for r in rows], dtype=np.int64)
    gm = compose_poses(base[k], relative_poses(raw_at_scans[k], raw))
    name = f"the recording's {ref_topic}" if has_ref else ""
    return PoseTrack(times, gm, raw, is_scan, k), name
