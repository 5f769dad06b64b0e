"""Where each island's origin was last known in the odometry frame (`KnownOrigins`), for the
`Recognizer`: kept in the calibrated odometry frame (`core.builder.calibration`) and handed
out in the raw one as it lies now, so a known origin moves as the calibration corrects the
heading odometry accumulated since. Localizing at a known island again is a measurement of
that correction's error; it teaches the calibration before the origin is replaced."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from island_msgs_py.types import FloatArray, Pose2D, wrap_angle

from island_mapping.core.builder.calibration import Mark, Measurement, OdometryCalibration


@dataclass(frozen=True)
class _Known:
    origin: Pose2D  # in the calibrated frame
    cov: FloatArray  # the raw odometry's 3x3 covariance then
    cov_at: Pose2D  # the raw odometric pose the covariance was taken at
    mark: Mark  # the calibration's counters then


class KnownOrigins:
    """Known origins by island id (module docstring)."""

    def __init__(self, calibration: OdometryCalibration) -> None:
        self.calibration = calibration
        self._known: dict[int, _Known] = {}

    def remember(self, island_id: int, origin_odom: Pose2D, odom_cov: FloatArray,
                 cov_at: Pose2D | None = None) -> Measurement | None:
        """Island island_id's origin is at origin_odom (raw odometry) now, with the
        odometry's covariance odom_cov taken at raw pose cov_at (default the origin). When the
        island was known, the turn between where it was predicted and where it is found is
        measured first (returned)."""
        cal = self.calibration
        old = self._known.get(island_id)
        found = None
        if old is not None and cal.active:
            turned = wrap_angle(origin_odom.theta - self.origin(island_id).theta)
            found = cal.measure(turned, old.mark, float(odom_cov[2, 2] - old.cov[2, 2]))
        stored = cal.transform.compose(origin_odom) if cal.active else origin_odom
        self._known[island_id] = _Known(stored, odom_cov,
                                        origin_odom if cov_at is None else cov_at, cal.mark)
        return found

    def __contains__(self, island_id: object) -> bool:
        return island_id in self._known

    def __len__(self) -> int:
        return len(self._known)

    def __iter__(self) -> Iterator[int]:
        return iter(sorted(self._known))

    def origin(self, island_id: int) -> Pose2D:
        """The island's origin in the raw odometry frame as it lies now [m, rad]."""
        stored = self._known[island_id].origin
        cal = self.calibration
        return cal.transform.inverse().compose(stored) if cal.active else stored

    def get(self, island_id: int) -> tuple[Pose2D, FloatArray] | None:
        """(origin in the raw frame now, the odometry's covariance then), or None."""
        k = self._known.get(island_id)
        return None if k is None else (self.origin(island_id), k.cov)

    def cov(self, island_id: int) -> FloatArray:
        return self._known[island_id].cov

    def cov_at(self, island_id: int) -> Pose2D:
        return self._known[island_id].cov_at

    def residual_var(self, island_id: int) -> float:
        """The heading variance [rad^2] the calibration's own uncertainty adds since the
        island's origin was last known."""
        return self.calibration.residual_var(self._known[island_id].mark)
