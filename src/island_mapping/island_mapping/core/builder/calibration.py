"""Online calibration of the odometry's systematic heading error (beyond the paper).

Wheel odometry turns by a wrong amount in a systematic way: a wrong wheelbase scales every
rotation (Borenstein's E_b), unequal wheel radii curve every straight drive (E_d). The random
part is in the odometry's covariance; the systematic part is not, and after an hour of stars
(each turns a full circle or two, always the same way) it dominates: heading errors of tens of
degrees the covariance does not allow for, so an island seen long ago is looked for at the
wrong heading (docs/exploration.md, session 23).

Model: each odometry increment (travel ds [m], turn dtheta [rad], both as odometry reports
them) adds a heading error e * dtheta + k * ds, with (e, k) unknown constants. Whenever the
robot localizes at an island it has localized at before (a dock, a revisit), the island's
origin as odometry puts it now has turned, since then, by the heading error accumulated in
between: a scalar measurement of (e, k) with regressor (signed turn, signed travel) over the
interval. A Kalman filter over (e, k), from a prior, takes each one whose innovation lies
within `gate_sigmas` (a wrong dock does not teach it), and the odometry is corrected step by
step by the current estimate: `transform` maps the raw odometry frame onto the corrected one
at the present pose (`Recognizer` keeps origins in the corrected frame and hands them out in
the raw one, so nothing else changes frame). `residual_var` is the heading variance that the
estimate's own uncertainty adds over an interval. Disabled (the default), `transform` is the
identity and nothing is learnt: with the stars and looks unwinding their turns
(`StarConfig.unwind_turns`) the rotation scale leaves little heading error, and the 6-10
docks an hour of exploration makes at islands it knew do not pin the curvature down
(docs/exploration.md, session 23).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from island_msgs_py.types import FloatArray, Pose2D, wrap_angle

from island_mapping.core.builder.errors import check_numbers as _check

_IDENTITY = Pose2D(0.0, 0.0, 0.0)


@dataclass(frozen=True)
class CalibrationConfig:
    """Learning the odometry's systematic heading error from the islands it localizes at."""

    enabled: bool = field(
        default=False,
        metadata={"help": "learn the rotation scale and curvature of the odometry from docks "
                          "and revisits and correct the odometry by them [bool]"},
    )
    rotation_scale_sigma: float = field(
        default=0.01,
        metadata={"help": "prior sigma of the relative error of every odometric turn (the "
                          "wheelbase's) [-]"},
    )
    curvature_sigma_radpm: float = field(
        default=0.002,
        metadata={"help": "prior sigma of the heading error per metre driven (unequal "
                          "wheels) [rad/m]"},
    )
    dock_heading_sigma_deg: float = field(
        default=2.0,
        metadata={"help": "heading sigma of one localization at an island [deg]"},
    )
    gate_sigmas: float = field(
        default=3.0,
        metadata={"help": "a measurement whose innovation exceeds this many sigmas is not "
                          "used (a wrong dock) [-]"},
    )
    honest_gate: bool = field(
        default=True,
        metadata={"help": "the loop-closure gate adds the estimate's remaining heading "
                          "uncertainty over the interval to the odometry's [bool]"},
    )

    def __post_init__(self) -> None:
        _check("CalibrationConfig", self, (
            "rotation_scale_sigma", "curvature_sigma_radpm", "dock_heading_sigma_deg",
            "gate_sigmas"), strict=True)


@dataclass(frozen=True)
class Mark:
    """The calibration's counters at one moment: signed odometric turn [rad] and travel [m]
    since the start, and the heading correction applied since [rad]."""

    turn_rad: float = 0.0
    travel_m: float = 0.0
    applied_rad: float = 0.0


@dataclass(frozen=True)
class Measurement:
    """One heading measurement: innovation [rad], its sigma [rad], whether it was used."""

    innovation_rad: float
    sigma_rad: float
    used: bool


class OdometryCalibration:
    """The (e, k) filter and the corrected odometry (module docstring)."""

    def __init__(self, config: CalibrationConfig | None = None) -> None:
        self.config = config if config is not None else CalibrationConfig()
        c = self.config
        self.estimate = np.zeros(2)  # (e [-], k [rad/m])
        self.covariance = np.diag([c.rotation_scale_sigma ** 2, c.curvature_sigma_radpm ** 2])
        self._raw: Pose2D | None = None
        self._corrected: Pose2D | None = None
        self._mark = Mark()
        self.measurements: list[Measurement] = []  # bounded: the last _KEEP
        self.used = 0
        self.refused = 0

    # ----- the odometry stream -----

    def update(self, raw: Pose2D) -> None:
        """Feed one raw odometric pose [m, rad]."""
        if self._raw is None or self._corrected is None or not self.config.enabled:
            self._raw = self._corrected = raw
            return
        step = raw.relative_to(self._raw)
        ds = math.hypot(step.x, step.y)
        if step.x * math.cos(0.5 * step.theta) + step.y * math.sin(0.5 * step.theta) < 0.0:
            ds = -ds
        fix = float(self.estimate[0] * step.theta + self.estimate[1] * ds)
        c, s = math.cos(-0.5 * fix), math.sin(-0.5 * fix)
        moved = Pose2D(c * step.x - s * step.y, s * step.x + c * step.y, step.theta - fix)
        self._corrected = self._corrected.compose(moved)
        m = self._mark
        self._mark = Mark(m.turn_rad + step.theta, m.travel_m + ds, m.applied_rad + fix)
        self._raw = raw

    @property
    def transform(self) -> Pose2D:
        """The corrected odometry frame from the raw one at the present pose (identity before
        the first pose and when disabled): corrected = transform.compose(raw)."""
        if not self.active or self._raw is None or self._corrected is None:
            return _IDENTITY
        return self._corrected.compose(self._raw.inverse())

    @property
    def active(self) -> bool:
        """Enabled: the corrected frame may differ from the raw one."""
        return self.config.enabled

    @property
    def mark(self) -> Mark:
        return self._mark

    # ----- what the docks teach -----

    def _regressor(self, since: Mark) -> FloatArray:
        m = self._mark
        return np.array([m.turn_rad - since.turn_rad, m.travel_m - since.travel_m])

    def residual_var(self, since: Mark) -> float:
        """The heading variance [rad^2] the estimate's uncertainty adds since `since` (0
        when disabled or without honest_gate)."""
        if not (self.config.enabled and self.config.honest_gate):
            return 0.0
        h = self._regressor(since)
        return float(h @ self.covariance @ h)

    def measure(self, turned_rad: float, since: Mark, random_var_rad2: float) -> Measurement:
        """An island's origin, predicted by the corrected odometry since `since`, was found
        turned by turned_rad [rad] (found minus predicted), the odometry's random heading
        variance since being random_var_rad2 [rad^2]: update (e, k) unless the innovation is
        outside the gate."""
        c = self.config
        h = self._regressor(since)
        y = wrap_angle(turned_rad) + (self._mark.applied_rad - since.applied_rad)
        z = y - float(h @ self.estimate)
        noise = max(random_var_rad2, 0.0) + 2.0 * math.radians(c.dock_heading_sigma_deg) ** 2
        s = float(h @ self.covariance @ h) + noise
        used = c.enabled and z * z <= c.gate_sigmas ** 2 * s
        if used:
            gain = self.covariance @ h / s
            self.estimate = self.estimate + gain * z
            self.covariance = self.covariance - np.outer(gain, h @ self.covariance)
            self.covariance = 0.5 * (self.covariance + self.covariance.T)
            self.used += 1
        else:
            self.refused += 1
        out = Measurement(z, math.sqrt(s), used)
        self.measurements = [*self.measurements[-(_KEEP - 1):], out]
        return out

    def summary(self) -> dict[str, float | int]:
        """The estimate and its sigmas, and how many measurements were used and refused."""
        sig = np.sqrt(np.maximum(np.diag(self.covariance), 0.0))
        return {"rotation_scale": float(self.estimate[0]),
                "rotation_scale_sigma": float(sig[0]),
                "curvature_radpm": float(self.estimate[1]),
                "curvature_sigma_radpm": float(sig[1]),
                "used": self.used, "refused": self.refused}


_KEEP = 64  # measurements kept for diagnostics
