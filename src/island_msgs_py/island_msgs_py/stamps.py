"""Pairing each scan with the odometry pose of its own stamp, whatever the delivery order.

The simulator publishes /odom (50 Hz) and the sonar publishes /sonar/scan (10 Hz) on the same
stamps; DDS may deliver the odometry of the next period before this period's scan, or the scan
before its odometry. A controller that paired a scan with "the latest odometry" would decide on
a pose that depends on arrival order. `ScanOdomPairer` holds scans until odometry of their stamp
(or later) has arrived and pairs each with the pose of its stamp, or the newest older one when
that stamp has none. Used by the hall follower and the island localizer nodes (through
`scan_inputs.subscribe_paired_scans`); the island builder, which must see every odometry message
in order, still has its own `StampSync`. Pure Python (no ROS).
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass
from typing import Generic, TypeVar

from island_msgs_py.errors import InputError
from island_msgs_py.types import Pose2D

T = TypeVar("T")


class StampError(InputError):
    """Bad pairing parameter (the message names it)."""


@dataclass(frozen=True)
class Paired(Generic[T]):
    """A scan's payload with the odometry pose it was paired with."""

    stamp_ns: int
    payload: T
    pose: Pose2D
    exact: bool  # the pose has the scan's own stamp (else the newest older one)


class ScanOdomPairer(Generic[T]):
    """Pairs scans (any payload) with odometry poses by stamp [ns].

    Never blocks; both buffers hold at most `max_buffer` entries: the oldest odometry is
    forgotten, and a scan still waiting when the buffer overflows (no odometry is arriving) is
    dropped and counted in `dropped_scans`, as is a scan older than every odometry kept.
    """

    def __init__(self, max_buffer: int = 200) -> None:
        if max_buffer < 1:
            raise StampError(f"ScanOdomPairer.max_buffer: expected >= 1, got {max_buffer}")
        self.max_buffer = max_buffer
        self._stamps: list[int] = []  # sorted [ns]
        self._poses: list[Pose2D] = []
        self._scans: deque[tuple[int, T]] = deque()
        self.dropped_scans = 0

    @property
    def scans_waiting(self) -> int:
        return len(self._scans)

    def odometry(self, t_ns: int, pose: Pose2D) -> list[Paired[T]]:
        """An odometry pose; returns the scans it released, in stamp order."""
        i = bisect.bisect_left(self._stamps, t_ns)
        if i < len(self._stamps) and self._stamps[i] == t_ns:
            self._poses[i] = pose
        else:
            self._stamps.insert(i, t_ns)
            self._poses.insert(i, pose)
        if len(self._stamps) > self.max_buffer:
            del self._stamps[0], self._poses[0]
        return self._drain()

    def scan(self, t_ns: int, payload: T) -> list[Paired[T]]:
        """A scan; returns every scan that can be paired now (this one and older), in order."""
        i = len(self._scans)
        while i > 0 and self._scans[i - 1][0] > t_ns:
            i -= 1
        self._scans.insert(i, (t_ns, payload))
        if len(self._scans) > self.max_buffer:
            self._scans.popleft()
            self.dropped_scans += 1
        return self._drain()

    def _drain(self) -> list[Paired[T]]:
        out: list[Paired[T]] = []
        while self._scans and self._stamps and self._scans[0][0] <= self._stamps[-1]:
            t_ns, payload = self._scans.popleft()
            k = bisect.bisect_right(self._stamps, t_ns) - 1
            if k < 0:  # older than every odometry kept
                self.dropped_scans += 1
                continue
            out.append(Paired(t_ns, payload, self._poses[k], self._stamps[k] == t_ns))
        return out
