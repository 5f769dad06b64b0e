"""Scan geometry read from the data, never assumed (pure: numpy only).

A `ScanGeometry` is where a scan's beams point: `n_beams` readings from `angle_min_rad`,
`increment_rad` apart (counter-clockwise, robot frame), and where that came from (`source`);
for a sonar ring (`SensorKind.SONAR_RING`) each transducer may also have its own pose on the
robot (`beam_poses`: a CARMEN `SONAR` line's offsets; ranges are then from the transducer).
A laser's geometry is determined, in this order, by

1. the user (`--fov-deg`, `--angle-min-deg`: `GeometryOverride`);
2. the message itself (a `ROBOTLASER1` line's start angle and resolution; a ROS `LaserScan`'s
   angle_min / angle_increment);
3. the log's `PARAM` lines (`laser_front_laser_resolution` [deg], `laser_front_laser_fov` [deg]
   (CARMEN's default 180), `laser_front_laser_flipped`; `laser_rear_laser_*` for `RLASER`):
   CARMEN's laser module centres the field of view on the laser's axis;
4. the format's own definition: a CARMEN `FLASER`/`RLASER` line is a 180 deg scan from -90 deg;
   its beam count then gives the resolution only where it is unambiguous for a SICK-style
   scanner: 180/181 beams are 1 deg, 360/361 are 0.5 deg, 720/721 are 0.25 deg (180, 360, 720:
   fov / n apart, CARMEN's rule, checked on the Intel log; 181, 361, 721: both ends included).

Anything else is a `ScanGeometryError` naming the log and what to pass; a geometry is never
guessed (a wrong one turns walls into spirals while the metrics still look plausible).

Which sensor a scan is, is read from the data too: a CARMEN `SONAR` line is a sonar ring; a ROS
`LaserScan` whose beams are at least `RING_MIN_INCREMENT_DEG` apart is a ring of range sensors
(one beam per transducer, as the simulator's /sonar/scan: ranges from the robot's centre), and
islands are built from it with sonar settings (`logs.islands.for_sensor`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from island_mapping.logs.errors import LogFormatError

FloatArray = NDArray[np.float64]

CARMEN_FOV_DEG = 180.0
"""A CARMEN laser's field of view unless its PARAM lines say otherwise (the laser module's
default, and the definition of the old FLASER/RLASER messages) [deg]."""
STANDARD_RESOLUTIONS_DEG = (1.0, 0.5, 0.25)
"""The angular resolutions a 180 deg SICK-style scan is read at from its beam count alone."""
_REL_TOL = 1e-6  # relative tolerance when comparing a beam count with fov / resolution
# How far a LaserScan's angle_max may differ from angle_min + (n - 1) * increment [increments].
_ANGLE_MAX_TOL_STEPS = 0.5
RING_MIN_INCREMENT_DEG = 5.0
"""A LaserScan whose beams are at least this far apart is a ring of range sensors (sonar: a
16-ring is 22.5 deg, a 24-ring 15 deg apart), not a laser (0.25-1 deg) [deg]."""


class SensorKind(StrEnum):
    """What produced a scan: a laser's fan of beams, or a ring of sonar transducers."""

    LASER = "laser"
    SONAR_RING = "sonar ring"


class ScanGeometryError(LogFormatError):
    """A scan's geometry cannot be determined from the data; the message names the log and the
    options that give it (--fov-deg, --angle-min-deg)."""


@dataclass(frozen=True)
class ScanGeometry:
    """Beam k points at angle_min_rad + k * increment_rad [rad] (robot frame, CCW) from the
    sensor's origin; with `beam_poses`, beam k starts at (x, y) [m] and points at theta [rad]
    of its own pose on the robot (a sonar ring's transducers)."""

    n_beams: int
    angle_min_rad: float
    increment_rad: float
    source: str
    sensor: SensorKind = SensorKind.LASER
    beam_poses: tuple[tuple[float, float, float], ...] | None = None

    def __post_init__(self) -> None:
        if self.beam_poses is not None and len(self.beam_poses) != self.n_beams:
            raise ScanGeometryError(f"{self.source}: {len(self.beam_poses)} beam poses for "
                                    f"{self.n_beams} beams")

    def angles(self) -> FloatArray:
        """(n_beams,) beam angles [rad]."""
        if self.beam_poses is not None:
            return np.array([p[2] for p in self.beam_poses], dtype=np.float64)
        return self.angle_min_rad + np.arange(self.n_beams, dtype=np.float64) * self.increment_rad

    def origins(self) -> FloatArray:
        """(n_beams, 2) where each beam starts on the sensor [m] (0 but for a ring's
        transducers)."""
        if self.beam_poses is None:
            return np.zeros((self.n_beams, 2))
        return np.array([p[:2] for p in self.beam_poses], dtype=np.float64).reshape(-1, 2)

    @property
    def fov_deg(self) -> float:
        """Angle from the first to the last beam [deg]."""
        return math.degrees(self.increment_rad * (self.n_beams - 1))

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "beams": self.n_beams, "sensor": self.sensor.value,
            "angle_min_deg": round(math.degrees(self.angle_min_rad), 6),
            "increment_deg": round(math.degrees(self.increment_rad), 6), "source": self.source,
            "description": self.describe()}
        if self.beam_poses is not None:
            out["transducers_m_m_deg"] = [[round(x, 4), round(y, 4), round(math.degrees(t), 3)]
                                          for x, y, t in self.beam_poses]
        return out

    def describe(self) -> str:
        """One line for the console: the sensor, its beams and where they were read from."""
        if self.beam_poses is not None:
            r = np.hypot(*self.origins().T)
            return (f"{self.n_beams} {self.sensor.value} transducers {float(r.min()):.3f}-"
                    f"{float(r.max()):.3f} m from the centre ({self.source})")
        kind = "" if self.sensor is SensorKind.LASER else f" ({self.sensor.value})"
        return (f"{self.n_beams} beams{kind} from {math.degrees(self.angle_min_rad):g} deg every "
                f"{math.degrees(self.increment_rad):g} deg ({self.source})")


@dataclass(frozen=True)
class GeometryOverride:
    """The user's word on the scan geometry: the field of view from the first to the last beam
    [deg] and the first beam's angle [deg] (default: centred on the robot's x axis)."""

    fov_deg: float | None = None
    angle_min_deg: float | None = None

    def __post_init__(self) -> None:
        if self.fov_deg is not None and not (math.isfinite(self.fov_deg)
                                             and 0 < self.fov_deg <= 360):
            raise ScanGeometryError(f"--fov-deg: expected a number in (0, 360], got "
                                    f"{self.fov_deg!r}")
        if self.angle_min_deg is not None and not (math.isfinite(self.angle_min_deg)
                                                   and -360 <= self.angle_min_deg <= 360):
            raise ScanGeometryError(f"--angle-min-deg: expected a number in [-360, 360], got "
                                    f"{self.angle_min_deg!r}")

    @property
    def given(self) -> bool:
        return self.fov_deg is not None

    def geometry(self, n_beams: int) -> ScanGeometry:
        assert self.fov_deg is not None
        inc = math.radians(self.fov_deg) / max(n_beams - 1, 1)
        amin = (math.radians(self.angle_min_deg) if self.angle_min_deg is not None
                else -0.5 * inc * (n_beams - 1))
        return ScanGeometry(n_beams, amin, inc, "command line (--fov-deg, --angle-min-deg)")


def _help(source: str, kind: str, n: int, why: str) -> ScanGeometryError:
    return ScanGeometryError(
        f"{source}: cannot tell the geometry of its {kind} scans ({n} beams): {why}; pass "
        f"--fov-deg (first to last beam) and, if the scan is not centred on the robot's x "
        f"axis, --angle-min-deg")


def _param(params: dict[str, str], name: str, source: str) -> float | None:
    if name not in params:
        return None
    try:
        v = float(params[name])
    except ValueError:
        raise ScanGeometryError(
            f"{source}: PARAM {name} {params[name]!r} is not a number") from None
    if not math.isfinite(v):
        raise ScanGeometryError(f"{source}: PARAM {name} is not finite")
    return v


def _from_fov(n: int, fov_deg: float, res_deg: float | None) -> tuple[float, str] | None:
    """(increment [deg], rule) of n beams spanning fov_deg: fov / n (CARMEN's rule) or
    fov / (n - 1) (both ends included); with a resolution, the one that agrees with it."""
    options = [(fov_deg / n, "fov / beams"), (fov_deg / max(n - 1, 1), "both ends included")]
    for inc, rule in options:
        if res_deg is None and any(math.isclose(inc, s, rel_tol=_REL_TOL)
                                   for s in STANDARD_RESOLUTIONS_DEG):
            return inc, rule
        if res_deg is not None and math.isclose(inc, res_deg, rel_tol=_REL_TOL):
            return inc, rule
    return None


def carmen_geometry(kind: str, n_beams: int, params: dict[str, str], source: str,
                    override: GeometryOverride | None = None) -> ScanGeometry:
    """The geometry of a CARMEN FLASER or RLASER line's n_beams readings (module docstring)."""
    if override is not None and override.given:
        return override.geometry(n_beams)
    prefix = "laser_rear_laser_" if kind == "RLASER" else "laser_front_laser_"
    res = _param(params, prefix + "resolution", source)
    fov = _param(params, prefix + "fov", source)
    flipped = (_param(params, prefix + "flipped", source) or 0.0) != 0.0
    if (res is not None and res <= 0) or (fov is not None and fov <= 0):
        raise ScanGeometryError(f"{source}: PARAM {prefix}resolution/fov must be > 0")
    fov_deg = fov if fov is not None else CARMEN_FOV_DEG
    got = _from_fov(n_beams, fov_deg, res)
    if got is None and res is not None and fov is None:
        # A resolution alone: the scan is centred (CARMEN's laser module) whatever its width.
        got = (res, "resolution, centred")
        fov_deg = res * (n_beams - 1)
    if got is None:
        why = (f"PARAM {prefix}fov {fov_deg:g} and resolution {res:g} do not fit"
               if res is not None else
               f"no PARAM {prefix}resolution, and {n_beams} beams over {fov_deg:g} deg is no "
               f"standard resolution ({', '.join(f'{s:g}' for s in STANDARD_RESOLUTIONS_DEG)} deg)")
        raise _help(source, kind, n_beams, why)
    inc_deg, rule = got
    amin = -0.5 * fov_deg if rule != "resolution, centred" else -0.5 * inc_deg * (n_beams - 1)
    src = "PARAM lines" if res is not None or fov is not None else f"{kind} format (180 deg)"
    geo = ScanGeometry(n_beams, math.radians(amin), math.radians(inc_deg), f"{src}, {rule}")
    if flipped:  # mounted upside down: the beams run clockwise
        geo = ScanGeometry(n_beams, -geo.angle_min_rad, -geo.increment_rad,
                           geo.source + ", flipped")
    return geo


def carmen_mount(kind: str, params: dict[str, str], source: str) -> tuple[float, float, float]:
    """Where a FLASER or RLASER laser sits on the robot (x [m], y [m], theta [rad]), from the
    log's PARAM lines as CARMEN defines them: the front laser `robot_frontlaser_offset` ahead
    of the centre (`_side_offset` to the left, `_angular_offset` [rad] turned); the rear laser faces
    backwards, `robot_rearlaser_offset` behind the centre (CARMEN's localize places it at the
    robot's pose + offset along theta + pi, turned by pi). 0 offsets when the log says nothing.
    """
    prefix = "robot_rearlaser_" if kind == "RLASER" else "robot_frontlaser_"
    off = _param(params, prefix + "offset", source) or 0.0
    side = _param(params, prefix + "side_offset", source) or 0.0
    ang = _param(params, prefix + "angular_offset", source) or 0.0  # [rad], as CARMEN's poses
    if kind != "RLASER":
        return (off, side, ang)
    return (-off, -side, math.atan2(math.sin(math.pi + ang), math.cos(math.pi + ang)))


def laserscan_geometry(n_beams: int, angle_min_rad: float, angle_max_rad: float,
                       increment_rad: float, source: str,
                       override: GeometryOverride | None = None) -> ScanGeometry:
    """The geometry of a ROS LaserScan: its own angle_min and angle_increment, checked against
    angle_max (a zero, non-finite or inconsistent increment is an error, not a guess)."""
    if override is not None and override.given:
        return override.geometry(n_beams)
    vals = (angle_min_rad, angle_max_rad, increment_rad)
    if not all(math.isfinite(v) for v in vals) or increment_rad == 0.0 or n_beams < 1:
        raise _help(source, "LaserScan", n_beams,
                    f"angle_min {angle_min_rad}, angle_max {angle_max_rad}, angle_increment "
                    f"{increment_rad} do not describe the beams")
    end = angle_min_rad + increment_rad * (n_beams - 1)
    if n_beams > 1 and abs(end - angle_max_rad) > _ANGLE_MAX_TOL_STEPS * abs(increment_rad) + 1e-6:
        raise _help(source, "LaserScan", n_beams,
                    f"angle_min {math.degrees(angle_min_rad):.3f} deg + {n_beams - 1} x "
                    f"angle_increment {math.degrees(increment_rad):.4f} deg = "
                    f"{math.degrees(end):.3f} deg, but angle_max is "
                    f"{math.degrees(angle_max_rad):.3f} deg")
    ring = abs(math.degrees(increment_rad)) >= RING_MIN_INCREMENT_DEG
    return ScanGeometry(n_beams, angle_min_rad, increment_rad, "LaserScan fields",
                        SensorKind.SONAR_RING if ring else SensorKind.LASER)
