"""CARMEN log lines: the one parser every tool uses (pure: numpy only).

A CARMEN log is text with one record per line, its first word the record's type. `parse_carmen`
turns the lines into `CarmenRecords`: a typed record for every line of a type it knows (the
parsers in `LINE_PARSERS`: FLASER, RLASER, ROBOTLASER1, SONAR, ODOM) in file order, the `PARAM`
lines (name -> value: the scan geometry and the lasers' mounts, `logs.geometry`), and the count
of the other lines by type (NEFF, ...). A malformed line of a known type is a
`CarmenFormatError` naming the source and the line number. The scans of a log are the lines of
one range sensor (`scan_kind`: FLASER if any, else ROBOTLASER1, else RLASER, else SONAR); the
other sensors' lines are counted, not read. The views of the records (scans, raw odometry, the
GMapping trajectory) are in `logs.carmen`.

Poses, as CARMEN defines them: a FLASER/RLASER line's first pose is the laser's, its second the
robot's; a ROBOTLASER1 line gives both (`LaserRecord.pose` is the first, the laser's, for
FLASER/RLASER, and the robot's for ROBOTLASER1, whose mount is computed from the two); a SONAR
line gives no pose, only each transducer's pose on the robot (`cone_angle n ranges (x y theta) *
n`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from island_msgs_py.geometry import relative_poses

from island_mapping.logs.errors import LogFormatError
from island_mapping.logs.geometry import ScanGeometry, SensorKind

Pose = tuple[float, float, float]
"""(x [m], y [m], theta [rad])."""

_FLASER_TAIL = 9  # x y theta odom_x odom_y odom_theta ipc_timestamp host logger_timestamp
_ODOM_FIELDS = 10  # ODOM x y theta tv rv accel ipc_timestamp host logger_timestamp


class CarmenFormatError(LogFormatError):
    """A CARMEN log could not be read or a line could not be parsed (the message names the file
    and the line number)."""


@dataclass(frozen=True)
class LaserRecord:
    """A FLASER, RLASER, ROBOTLASER1 or SONAR line: ranges [m], the pose the log gives the scan
    (GMapping-corrected in a corrected log; NaN for SONAR, which gives none) and the odometry
    pose fields; a ROBOTLASER1 or SONAR line also its own geometry, and ROBOTLASER1 the laser's
    pose on the robot (x [m], y [m], theta [rad])."""

    lineno: int
    ranges_m: tuple[float, ...]
    pose: Pose
    odom_pose: Pose
    time_s: float  # the reading's (IPC) timestamp [s]
    host: str
    logger_time_s: float  # when the logger wrote it [s]
    kind: str = "FLASER"
    geometry: ScanGeometry | None = None
    mount: Pose = (0.0, 0.0, 0.0)


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
    params: dict[str, str] = field(default_factory=dict)

    chosen: str | None = None
    """The scans' line type when the user chose it (`with_scans`); else `SCAN_KINDS` order."""

    @property
    def scan_kind(self) -> str:
        """The sensor whose lines are the scans: the chosen one, else FLASER if any, else
        ROBOTLASER1, else RLASER, else SONAR."""
        if self.chosen is not None:
            return self.chosen
        kinds = {r.kind for r in self.records if isinstance(r, LaserRecord)}
        return next((k for k in SCAN_KINDS if k in kinds), "FLASER")

    def with_scans(self, kind: str | None) -> CarmenRecords:
        """These records with `kind`'s lines as the scans (None: the default order);
        CarmenFormatError when the log has no such line."""
        if kind is None:
            return self
        if kind not in SCAN_KINDS:
            raise CarmenFormatError(f"scan lines: expected one of {', '.join(SCAN_KINDS)}, got "
                                    f"{kind!r}")
        if not any(isinstance(r, LaserRecord) and r.kind == kind for r in self.records):
            raise CarmenFormatError(f"{self.source}: no {kind} lines")
        return CarmenRecords(self.source, self.records, self.skipped, self.params, kind)

    @property
    def scans_have_poses(self) -> bool:
        """Whether the scan lines carry the robot's pose (SONAR lines do not)."""
        return self.scan_kind != "SONAR"

    def is_scan(self, rec: CarmenRecord) -> bool:
        return isinstance(rec, LaserRecord) and rec.kind == self.scan_kind

    @property
    def scans(self) -> list[LaserRecord]:
        kind = self.scan_kind
        return [r for r in self.records if isinstance(r, LaserRecord) and r.kind == kind]

    @property
    def other_laser_lines(self) -> int:
        """Lines of the lasers that are not the scans (e.g. RLASER beside FLASER)."""
        return sum(1 for r in self.records if isinstance(r, LaserRecord)) - len(self.scans)


def _floats(tokens: list[str], where: str, what: str) -> list[float]:
    try:
        values = [float(t) for t in tokens]
    except ValueError as exc:
        raise CarmenFormatError(f"{where}: {what}: {exc}") from None
    if not all(math.isfinite(v) for v in values):
        raise CarmenFormatError(f"{where}: {what}: NaN or infinite value")
    return values


def _count(tok: list[str], i: int, where: str, what: str) -> int:
    if len(tok) <= i:
        raise CarmenFormatError(f"{where}: {tok[0]} line without {what}")
    try:
        n = int(tok[i])
    except ValueError:
        raise CarmenFormatError(f"{where}: {tok[0]} {what} {tok[i]!r} is not an integer") from None
    if n < 0:
        raise CarmenFormatError(f"{where}: {tok[0]} {what} {n} is negative")
    return n


def _ranges(vals: list[float], where: str, kind: str) -> tuple[float, ...]:
    if vals and min(vals) < 0:
        raise CarmenFormatError(f"{where}: {kind} has a negative range")
    return tuple(vals)


def _flaser(tok: list[str], lineno: int, where: str) -> LaserRecord:
    """FLASER or RLASER: n ranges, pose, odometry pose, time, host, logger time."""
    kind = tok[0]
    n = _count(tok, 1, where, "beam count")
    if n <= 0 or len(tok) != 2 + n + _FLASER_TAIL:
        raise CarmenFormatError(
            f"{where}: {kind} with {n} beams needs {2 + n + _FLASER_TAIL} fields, got {len(tok)}"
        )
    vals = _floats(tok[2 : 2 + n + 6], where, kind)
    t = _floats([tok[2 + n + 6]], where, f"{kind} timestamp")[0]
    logger_t = _floats([tok[2 + n + 8]], where, f"{kind} logger timestamp")[0]
    return LaserRecord(lineno, _ranges(vals[:n], where, kind), (vals[n], vals[n + 1], vals[n + 2]),
                       (vals[n + 3], vals[n + 4], vals[n + 5]), t, tok[2 + n + 7], logger_t,
                       kind=kind)


# ROBOTLASER1 laser_type start_angle fov angular_resolution max_range accuracy remission_mode
#   n [ranges] n_remissions [remissions] laser_x laser_y laser_theta robot_x robot_y robot_theta
#   tv rv forward_safety side_safety turn_axis timestamp host logger_timestamp
_RL1_HEAD = 8
_RL1_TAIL = 14


def _robotlaser1(tok: list[str], lineno: int, where: str) -> LaserRecord:
    """ROBOTLASER1: the scan carries its own start angle and resolution [rad]."""
    n = _count(tok, _RL1_HEAD, where, "beam count")
    nrem = _count(tok, _RL1_HEAD + 1 + n, where, "remission count")
    need = _RL1_HEAD + 2 + n + nrem + _RL1_TAIL
    if n <= 0 or len(tok) != need:
        raise CarmenFormatError(f"{where}: ROBOTLASER1 with {n} beams and {nrem} remissions "
                                f"needs {need} fields, got {len(tok)}")
    head = _floats(tok[2:5], where, "ROBOTLASER1 angles")
    rng = _floats(tok[_RL1_HEAD + 1 : _RL1_HEAD + 1 + n], where, "ROBOTLASER1 ranges")
    k = _RL1_HEAD + 2 + n + nrem
    tail = _floats(tok[k : k + 11], where, "ROBOTLASER1 poses")
    t = _floats([tok[k + 11]], where, "ROBOTLASER1 timestamp")[0]
    logger_t = _floats([tok[k + 13]], where, "ROBOTLASER1 logger timestamp")[0]
    start, _fov, res = head
    if res == 0.0:
        raise CarmenFormatError(f"{where}: ROBOTLASER1 angular resolution is 0")
    laser, robot = np.asarray(tail[0:3]), np.asarray(tail[3:6])
    mount = relative_poses(robot, laser)[0]
    return LaserRecord(lineno, _ranges(rng, where, "ROBOTLASER1"), (tail[3], tail[4], tail[5]),
                       (tail[3], tail[4], tail[5]), t, tok[k + 12], logger_t, kind="ROBOTLASER1",
                       geometry=ScanGeometry(n, start, res, "ROBOTLASER1 fields"),
                       mount=(float(mount[0]), float(mount[1]), float(mount[2])))


# SONAR cone_angle n [ranges] [x y theta] * n timestamp host logger_timestamp
_SONAR_TAIL = 3


def _sonar(tok: list[str], lineno: int, where: str) -> LaserRecord:
    """SONAR: a ring of n transducers, each with its pose on the robot; ranges from each."""
    n = _count(tok, 2, where, "transducer count")
    need = 3 + 4 * n + _SONAR_TAIL
    if n <= 0 or len(tok) != need:
        raise CarmenFormatError(f"{where}: SONAR with {n} transducers needs {need} fields, got "
                                f"{len(tok)}")
    rng = _floats(tok[3 : 3 + n], where, "SONAR ranges")
    offs = _floats(tok[3 + n : 3 + 4 * n], where, "SONAR transducer poses")
    t = _floats([tok[3 + 4 * n]], where, "SONAR timestamp")[0]
    logger_t = _floats([tok[5 + 4 * n]], where, "SONAR logger timestamp")[0]
    poses = tuple((offs[3 * k], offs[3 * k + 1], offs[3 * k + 2]) for k in range(n))
    inc = (poses[1][2] - poses[0][2]) if n > 1 else 0.0
    geo = ScanGeometry(n, poses[0][2], inc, "SONAR transducer poses", SensorKind.SONAR_RING,
                       poses)
    nan = (math.nan, math.nan, math.nan)
    return LaserRecord(lineno, _ranges(rng, where, "SONAR"), nan, nan, t, tok[4 + 4 * n],
                       logger_t, kind="SONAR", geometry=geo)


def _odom(tok: list[str], lineno: int, where: str) -> OdomRecord:
    if len(tok) != _ODOM_FIELDS:
        raise CarmenFormatError(f"{where}: ODOM needs {_ODOM_FIELDS} fields, got {len(tok)}")
    v = _floats(tok[1:7], where, "ODOM")
    t = _floats([tok[7]], where, "ODOM timestamp")[0]
    logger_t = _floats([tok[9]], where, "ODOM logger timestamp")[0]
    return OdomRecord(lineno, (v[0], v[1], v[2]), v[3], v[4], v[5], t, tok[8], logger_t)


LINE_PARSERS: dict[str, Callable[[list[str], int, str], CarmenRecord]] = {
    "FLASER": _flaser,
    "RLASER": _flaser,
    "ROBOTLASER1": _robotlaser1,
    "SONAR": _sonar,
    "ODOM": _odom,
}
"""Parsers of the line types read, by the line's first word: (tokens, line number, "file:line")
-> record."""
LASER_KINDS = ("FLASER", "ROBOTLASER1", "RLASER")
"""The laser line types."""
SCAN_KINDS = (*LASER_KINDS, "SONAR")
"""The range sensors' line types, in the order a log's scans are chosen from."""


def parse_carmen(lines: Iterable[str], source: str = "<log>") -> CarmenRecords:
    """Parse a log's lines (see the module docstring); `source` names it in errors."""
    records: list[CarmenRecord] = []
    skipped: dict[str, int] = {}
    params: dict[str, str] = {}
    prev_kind = ""
    last_scan: LaserRecord | None = None
    for lineno, line in enumerate(lines, start=1):
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        kind = tok[0]
        if kind == "PARAM" and len(tok) >= 3:
            params[tok[1]] = tok[2]
            continue
        parser = LINE_PARSERS.get(kind)
        if parser is None:
            skipped[kind] = skipped.get(kind, 0) + 1
            prev_kind = kind
            continue
        rec = parser(tok, lineno, f"{source}:{lineno}")
        if isinstance(rec, OdomRecord) and prev_kind in SCAN_KINDS and last_scan is not None and (
            rec.pose == last_scan.pose
        ):
            rec = OdomRecord(rec.lineno, rec.pose, rec.tv_mps, rec.rv_radps, rec.accel_mps2,
                             rec.time_s, rec.host, rec.logger_time_s, echo=True)
        if isinstance(rec, LaserRecord):
            last_scan = rec
        records.append(rec)
        prev_kind = kind
    return CarmenRecords(source, tuple(records), skipped, params)


def read_carmen_records(path: str | os.PathLike[str]) -> CarmenRecords:
    """Parse a log file (see `parse_carmen`)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="strict")
    except (OSError, UnicodeDecodeError) as exc:
        raise CarmenFormatError(f"cannot read CARMEN log {p}: {exc}") from None
    return parse_carmen(text.splitlines(), str(p))

