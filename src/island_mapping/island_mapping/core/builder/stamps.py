"""Scan/odometry stamp pairing for the island builder (live: DDS may deliver out of order).

To be unified with island_msgs_py's scan/odometry pairer (issue 15): one pairer for the project.
"""

from __future__ import annotations

import bisect
from collections import deque
from typing import Protocol

import numpy as np
import numpy.typing as npt
from island_msgs_py.types import FloatArray, Pose2D

from island_mapping.core.builder.config import BuilderError
from island_mapping.core.builder.events import BuilderCommand


class BuilderInputs(Protocol):
    """What StampSync feeds (an IslandBuilder)."""

    def on_odometry(self, t_s: float, odom_pose: Pose2D, cov3x3: npt.ArrayLike) -> None: ...

    def on_ground_truth(self, pose: Pose2D) -> None: ...

    def on_scan(self, t_s: float, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike) -> None: ...

    def command(self, t_s: float) -> BuilderCommand: ...


class StampSync:
    """Feeds an `IslandBuilder` so each scan meets the odometry (and ground truth) of its stamp.

    Live, DDS may deliver the odometry of the next sensor period before the scan of this one;
    feeding odometry at arrival would make a scan's decision use a later pose, so a run would
    depend on arrival order. Here odometry and ground truth wait in stamp-ordered buffers and a
    scan is processed (in stamp order) once odometry of its stamp or later has arrived: the
    builder is first fed every odometry stamped at or before the scan (so it holds the pose of
    the same stamp, or the newest older one), then the scan, then asked for its command. Never
    blocks; buffers are bounded by `max_buffer`: surplus odometry (no scan is waiting for it)
    is fed to the builder oldest first, surplus scans (no odometry is arriving) are dropped
    oldest first and counted in `dropped_scans`. Odometry stamped at or before what the
    builder was already fed cannot be applied in order and is counted in `stale_odometry`.
    """

    def __init__(self, builder: BuilderInputs, max_buffer: int = 200) -> None:
        if max_buffer < 1:
            raise BuilderError(f"StampSync.max_buffer: expected >= 1, got {max_buffer}")
        self.builder = builder
        self.max_buffer = max_buffer
        self._odom: list[tuple[int, Pose2D, FloatArray]] = []  # sorted by stamp [ns]
        self._truth: list[tuple[int, Pose2D]] = []  # sorted by stamp [ns]
        self._scans: deque[tuple[int, FloatArray, FloatArray]] = deque()
        self._fed_ns: int | None = None  # stamp of the newest odometry fed to the builder
        self.dropped_scans = 0
        self.stale_odometry = 0

    @property
    def scans_waiting(self) -> int:
        """Scans taken but not processed yet (their odometry has not come)."""
        return len(self._scans)

    def odometry(
        self, t_ns: int, pose: Pose2D, cov3x3: npt.ArrayLike
    ) -> list[tuple[int, BuilderCommand]]:
        """An odometry message; returns (stamp [ns], command) of every scan it released."""
        cov = np.asarray(cov3x3, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise BuilderError(
                f"odometry: covariance must be a finite 3x3 matrix, got shape {cov.shape}"
            )
        if self._fed_ns is not None and t_ns <= self._fed_ns:
            self.stale_odometry += 1
            return []
        i = bisect.bisect_left(self._odom, t_ns, key=lambda o: o[0])
        if i < len(self._odom) and self._odom[i][0] == t_ns:
            self._odom[i] = (t_ns, pose, cov)
        else:
            self._odom.insert(i, (t_ns, pose, cov))
        return self._drain()

    def ground_truth(self, t_ns: int, pose: Pose2D) -> list[tuple[int, BuilderCommand]]:
        """A true pose (evaluation only); it reaches the builder with the scans of its stamp."""
        bisect.insort(self._truth, (t_ns, pose), key=lambda o: o[0])
        if len(self._truth) > self.max_buffer:
            self.builder.on_ground_truth(self._truth.pop(0)[1])
        return []

    def scan(
        self, t_ns: int, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike
    ) -> list[tuple[int, BuilderCommand]]:
        """A scan; returns (stamp [ns], command) of every scan processed now (this and older)."""
        r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
        a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
        if r.shape != a.shape:
            raise BuilderError(f"scan: {r.shape[0]} ranges but {a.shape[0]} angles")
        i = len(self._scans)
        while i > 0 and self._scans[i - 1][0] > t_ns:
            i -= 1
        self._scans.insert(i, (t_ns, r, a))
        if len(self._scans) > self.max_buffer:
            self._scans.popleft()
            self.dropped_scans += 1
        return self._drain()

    def _feed_odometry_until(self, t_ns: int) -> None:
        n = bisect.bisect_right(self._odom, t_ns, key=lambda o: o[0])
        for stamp, pose, cov in self._odom[:n]:
            self.builder.on_odometry(stamp * 1e-9, pose, cov)
            self._fed_ns = stamp
        del self._odom[:n]
        m = bisect.bisect_right(self._truth, t_ns, key=lambda o: o[0])
        if m:
            self.builder.on_ground_truth(self._truth[m - 1][1])
            del self._truth[:m]

    def _drain(self) -> list[tuple[int, BuilderCommand]]:
        out: list[tuple[int, BuilderCommand]] = []
        while self._scans:
            newest = self._odom[-1][0] if self._odom else self._fed_ns
            t_ns, r, a = self._scans[0]
            if newest is None or newest < t_ns:
                break  # its odometry may still come
            self._scans.popleft()
            self._feed_odometry_until(t_ns)
            t = t_ns * 1e-9
            self.builder.on_scan(t, r, a)
            out.append((t_ns, self.builder.command(t)))
        while len(self._odom) > self.max_buffer:  # no scan is waiting for these
            self._feed_odometry_until(self._odom[0][0])
        return out
