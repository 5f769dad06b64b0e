"""CARMEN log files: the one parser every tool uses (pure: numpy only).

A CARMEN log is text with one record per line, its first word the record's type. `parse_carmen`
turns the lines into `CarmenRecords`: a typed record for every line of a type it knows (the
parsers in `LINE_PARSERS`: FLASER, ODOM) in file order, and the count of the other lines by
type (NEFF, PARAM, ...). A malformed line of a known type is a `CarmenFormatError` naming the
source and the line number. Supporting another line type (PARAM for the scan geometry, RLASER,
ROBOTLASER1) means a record type and a parser in `LINE_PARSERS`; the views below read only the
record types they know.

Two views of a GMapping-corrected log (../shared/data/README.md) are assembled from the records:

- `carmen_log` -> `CarmenLog`: per scan the logged time, the ranges, the GMapping-corrected pose
  of the FLASER line and the *raw* odometry: every ODOM line is "the corrected pose of the
  previous scan plus the raw odometry accumulated since then", so the raw increment of scan i
  is relative(corrected[i-1], last ODOM before scan i) (before the first scan the previous
  corrected pose is the origin), and the raw poses are these increments composed from the
  origin; every ODOM line as raw odometry too (what the MCAP importer writes, what the offline
  island builder reads);
- `pose_track` -> `PoseTrack`: the GMapping pose and the raw odometry at every FLASER and ODOM
  line after the first scan, in file order (the GMapping trajectory the relations are scored
  against, and the raw odometry that bridges a relation time to the nearest scan).

GMapping writes each scan's corrected pose again as an ODOM line right after the FLASER line
(its timestamp is 0 or garbage): such an echo is flagged (`OdomRecord.echo`) and is odometry in
neither view. Times are the readings' (IPC) timestamps in seconds since the log's start.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from island_msgs_py.geometry import compose_poses, relative_poses
from numpy.typing import NDArray

from island_mapping.core.relations import PoseTrack
from island_mapping.logs.errors import LogFormatError

FloatArray = NDArray[np.float64]
Pose = tuple[float, float, float]
"""(x [m], y [m], theta [rad])."""

FLASER_ANGLE_MIN_RAD = -math.pi / 2
"""The Intel log's FLASER scans: the first beam to the robot's right (-90 deg), counter-
clockwise..."""
FLASER_ANGLE_INCREMENT_RAD = math.pi / 180
"""...at 1 deg steps (180 beams: the last at +89 deg)."""

_FLASER_TAIL = 9  # x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp
_ODOM_FIELDS = 10  # ODOM x y theta tv rv accel ipc_timestamp host logger_timestamp


class CarmenFormatError(LogFormatError):
    """A CARMEN log could not be read or a line could not be parsed (the message names the file
    and the line number)."""


@dataclass(frozen=True)
class LaserRecord:
    """A FLASER line: ranges [m] at beam k of FLASER geometry, the pose the log gives the scan
    (GMapping-corrected in a corrected log) and the odometry pose fields."""

    lineno: int
    ranges_m: tuple[float, ...]
    pose: Pose
    odom_pose: Pose
    time_s: float  # the reading's (IPC) timestamp [s]
    host: str
    logger_time_s: float  # when the logger wrote it [s]


@dataclass(frozen=True)
class OdomRecord:
    """An ODOM line: pose, translational [m/s] and rotational [rad/s] velocity, acceleration;
    echo: GMapping's repeat of the scan just logged (right after its FLASER line, same pose)."""

    lineno: int
    pose: Pose
    tv_mps: float
    rv_radps: float
    accel_mps2: float
    time_s: float
    host: str
    logger_time_s: float
    echo: bool = False


CarmenRecord = LaserRecord | OdomRecord


@dataclass(frozen=True)
class CarmenRecords:
    """The records of a log in file order, and the lines skipped (unknown types) by type."""

    source: str
    records: tuple[CarmenRecord, ...]
    skipped: dict[str, int] = field(default_factory=dict)

    @property
    def scans(self) -> list[LaserRecord]:
        return [r for r in self.records if isinstance(r, LaserRecord)]


def _floats(tokens: list[str], where: str, what: str) -> list[float]:
    try:
        values = [float(t) for t in tokens]
    except ValueError as exc:
        raise CarmenFormatError(f"{where}: {what}: {exc}") from None
    if not all(math.isfinite(v) for v in values):
        raise CarmenFormatError(f"{where}: {what}: NaN or infinite value")
    return values


def _flaser(tok: list[str], lineno: int, where: str) -> LaserRecord:
    if len(tok) < 2:
        raise CarmenFormatError(f"{where}: FLASER line without beam count")
    try:
        n = int(tok[1])
    except ValueError:
        raise CarmenFormatError(
            f"{where}: FLASER beam count {tok[1]!r} is not an integer") from None
    if n <= 0 or len(tok) != 2 + n + _FLASER_TAIL:
        raise CarmenFormatError(
            f"{where}: FLASER with {n} beams needs {2 + n + _FLASER_TAIL} fields, got {len(tok)}"
        )
    vals = _floats(tok[2 : 2 + n + 6], where, "FLASER")
    t = _floats([tok[2 + n + 6]], where, "FLASER timestamp")[0]
    logger_t = _floats([tok[2 + n + 8]], where, "FLASER logger timestamp")[0]
    if min(vals[:n]) < 0:
        raise CarmenFormatError(f"{where}: FLASER has a negative range")
    return LaserRecord(lineno, tuple(vals[:n]), (vals[n], vals[n + 1], vals[n + 2]),
                       (vals[n + 3], vals[n + 4], vals[n + 5]), t, tok[2 + n + 7], logger_t)


def _odom(tok: list[str], lineno: int, where: str) -> OdomRecord:
    if len(tok) != _ODOM_FIELDS:
        raise CarmenFormatError(f"{where}: ODOM needs {_ODOM_FIELDS} fields, got {len(tok)}")
    v = _floats(tok[1:7], where, "ODOM")
    t = _floats([tok[7]], where, "ODOM timestamp")[0]
    logger_t = _floats([tok[9]], where, "ODOM logger timestamp")[0]
    return OdomRecord(lineno, (v[0], v[1], v[2]), v[3], v[4], v[5], t, tok[8], logger_t)


LINE_PARSERS: dict[str, Callable[[list[str], int, str], CarmenRecord]] = {
    "FLASER": _flaser,
    "ODOM": _odom,
}
"""Parsers of the line types read, by the line's first word: (tokens, line number, "file:line")
-> record."""


def parse_carmen(lines: Iterable[str], source: str = "<log>") -> CarmenRecords:
    """Parse a log's lines (see the module docstring); `source` names it in errors."""
    records: list[CarmenRecord] = []
    skipped: dict[str, int] = {}
    prev_kind = ""
    last_scan: LaserRecord | None = None
    for lineno, line in enumerate(lines, start=1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        kind = tok[0]
        parser = LINE_PARSERS.get(kind)
        if parser is None:
            skipped[kind] = skipped.get(kind, 0) + 1
            prev_kind = kind
            continue
        rec = parser(tok, lineno, f"{source}:{lineno}")
        if isinstance(rec, OdomRecord) and prev_kind == "FLASER" and last_scan is not None and (
            rec.pose == last_scan.pose
        ):
            rec = OdomRecord(rec.lineno, rec.pose, rec.tv_mps, rec.rv_radps, rec.accel_mps2,
                             rec.time_s, rec.host, rec.logger_time_s, echo=True)
        if isinstance(rec, LaserRecord):
            last_scan = rec
        records.append(rec)
        prev_kind = kind
    return CarmenRecords(source, tuple(records), skipped)


def read_carmen_records(path: str | os.PathLike[str]) -> CarmenRecords:
    """Parse a log file (see `parse_carmen`)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="strict")
    except (OSError, UnicodeDecodeError) as exc:
        raise CarmenFormatError(f"cannot read CARMEN log {p}: {exc}") from None
    return parse_carmen(text.splitlines(), str(p))


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


def carmen_log(records: CarmenRecords) -> CarmenLog:
    """The scans and the raw odometry of a GMapping-corrected log (see the module docstring)."""
    scans = records.scans
    if not scans:
        raise CarmenFormatError(
            f"{records.source}: no FLASER line found (not a CARMEN laser log?)")
    n_beams = len(scans[0].ranges_m)
    for s in scans:
        if len(s.ranges_m) != n_beams:
            raise CarmenFormatError(
                f"{records.source}:{s.lineno}: FLASER has {len(s.ranges_m)} beams, earlier "
                f"scans had {n_beams}")
    odom_lines: list[tuple[float, float, float, float]] = []  # x y theta t
    odom_scan: list[int] = []
    last_odom_before_scan: list[Pose | None] = []
    last_odom: Pose | None = None
    for rec in records.records:
        if isinstance(rec, LaserRecord):
            last_odom_before_scan.append(last_odom)
            last_odom = None
        elif not rec.echo:
            last_odom = rec.pose
            odom_lines.append((*rec.pose, rec.time_s))
            odom_scan.append(len(last_odom_before_scan))
    corr = np.asarray([s.pose for s in scans], dtype=float)
    raw = _raw_at_scans(corr, last_odom_before_scan)
    # Every ODOM line as raw odometry: relative to the corrected pose of the scan before it.
    odom = np.asarray(odom_lines, dtype=float).reshape(-1, 4)
    scan_idx = np.asarray(odom_scan, dtype=np.int64)
    base_corr = np.vstack([np.zeros((1, 3)), corr])[scan_idx]
    base_raw = np.vstack([np.zeros((1, 3)), raw])[scan_idx]
    odom_raw = odom
    if len(odom):
        odom_raw = compose_poses(base_raw, relative_poses(base_corr, odom[:, :3]))
    scan_times = np.asarray([s.time_s for s in scans], dtype=float)
    odom_log_t, scan_log_t = _file_order_times(odom[:, 3].copy(), scan_idx, scan_times)
    return CarmenLog(
        path=Path(records.source),
        times_s=scan_times,
        scan_log_times_s=scan_log_t,
        ranges_m=np.asarray([s.ranges_m for s in scans], dtype=float),
        corrected=corr,
        raw_odometry=raw,
        odom_times_s=odom_log_t,
        odom_raw=np.asarray(odom_raw, dtype=float).reshape(-1, 3),
        odom_scan_index=scan_idx,
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
    """Poses at every FLASER line and every ODOM line after the first scan (echoes are not
    odometry), in file order: the GMapping pose (corrected for scans; corrected + raw odometry
    between), raw odometry (from the first scan's frame), the latest scan's index. The GMapping
    baseline depends on every such line: a relation time takes the nearest line."""
    times: list[float] = []
    gm: list[Pose] = []
    raw: list[FloatArray] = []
    is_scan: list[bool] = []
    scan_idx: list[int] = []
    n_scans = 0
    last_corrected: FloatArray | None = None  # corrected pose of the latest scan
    last_raw_at_scan = np.zeros(3)  # raw odometry pose of the latest scan
    last_odom: FloatArray | None = None  # pose of the latest ODOM line since that scan
    for rec in records.records:
        pose = np.asarray(rec.pose, dtype=np.float64)
        if isinstance(rec, LaserRecord):
            if last_corrected is not None and last_odom is not None:
                inc = relative_poses(last_corrected, last_odom)
                last_raw_at_scan = compose_poses(last_raw_at_scan, inc)[0]
            last_corrected, last_odom = pose, None
            raw.append(last_raw_at_scan.copy())
            is_scan.append(True)
            scan_idx.append(n_scans)
            n_scans += 1
        elif rec.echo or last_corrected is None:
            continue  # the repeat right after a scan, or odometry before the first scan
        else:
            last_odom = pose
            raw.append(compose_poses(last_raw_at_scan, relative_poses(last_corrected, pose))[0])
            is_scan.append(False)
            scan_idx.append(n_scans - 1)
        times.append(rec.time_s)
        gm.append(rec.pose)
    if n_scans == 0:
        raise CarmenFormatError(f"{records.source}: no FLASER lines")
    return PoseTrack(
        np.asarray(times, dtype=np.float64),
        np.asarray(gm, dtype=np.float64).reshape(-1, 3),
        np.asarray(raw, dtype=np.float64).reshape(-1, 3),
        np.asarray(is_scan, dtype=bool),
        np.asarray(scan_idx, dtype=np.int64),
    )


# ----- scan geometry -----


def flaser_angles(n_beams: int) -> FloatArray:
    """Robot-frame angles [rad] of a FLASER scan's n_beams readings (1 deg apart from -90 deg,
    counter-clockwise; checked on the Intel log: consecutive scans placed by their corrected
    poses overlap to a 3 cm median only with this convention)."""
    return FLASER_ANGLE_MIN_RAD + np.arange(n_beams, dtype=np.float64) * FLASER_ANGLE_INCREMENT_RAD


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
