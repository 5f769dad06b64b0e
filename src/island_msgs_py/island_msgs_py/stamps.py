"""The one scan/odometry stamp pairer of the project, whatever the delivery order.

The simulator publishes /odom (50 Hz) and the sonar publishes /sonar/scan (10 Hz) on the same
stamps; DDS may deliver the odometry of the next period before this period's scan, or the scan
before its odometry. A controller that paired a scan with "the latest odometry" would decide on
a pose that depends on arrival order. `ScanOdomPairer` holds scans until odometry of their stamp
(or later) has arrived and releases each with the pose of its stamp, or the newest older one
when that stamp has none. Pure Python (no ROS).

Two modes, one algorithm:

- pairing (the default; the hall follower and the island localizer nodes, through
  `scan_inputs.subscribe_paired_scans`): each released scan is a `Paired`;
- every odometry (`every_odometry=True`; the island builder node, whose eq. 3 integrates every
  odometry increment): the pairer also releases every odometry message as an `OdometrySample`,
  in stamp order, each before the scans stamped at or after it.

Extra pose streams (`streams`, e.g. the simulator's ground truth) wait in their own buffers;
before each released scan comes a `StreamSample` with the newest sample of each stream stamped
at or before the scan (older ones are passed over).

What bad input does, in both modes (memory stays bounded by `max_buffer` per buffer):

- a scan waiting when the scan buffer overflows (no odometry is arriving) is dropped, oldest
  first, and counted in `dropped_scans`; so is a scan that cannot meet odometry of its stamp or
  an older one (older than every odometry kept; with `every_odometry`, also older than the
  odometry already released, which has moved past it);
- odometry overflow: when no scan is waiting, pairing forgets the oldest odometry, while
  `every_odometry` releases it (oldest first, with the streams' samples up to its stamp), so
  that no increment is lost;
- with `every_odometry`, odometry stamped at or before the newest odometry already released
  cannot be applied in order: it is ignored and counted in `stale_odometry`;
- a covariance that is not a finite 3x3 matrix and an unknown stream raise `StampError`.
"""

from __future__ import annotations

import bisect
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np
import numpy.typing as npt

from island_msgs_py.errors import InputError
from island_msgs_py.types import FloatArray, Pose2D

T = TypeVar("T")


class StampError(InputError):
    """Bad pairing parameter or input (the message names it)."""


@dataclass(frozen=True)
class Paired(Generic[T]):
    """A scan's payload with the odometry pose it was paired with."""

    stamp_ns: int
    payload: T
    pose: Pose2D
    exact: bool  # the pose has the scan's own stamp (else the newest older one)


@dataclass(frozen=True)
class OdometrySample:
    """One odometry message, released in stamp order (`every_odometry` mode)."""

    stamp_ns: int
    pose: Pose2D
    cov: FloatArray | None  # 3x3 (x, y, theta) [m, rad], if the odometry carried one


@dataclass(frozen=True)
class StreamSample:
    """The newest sample of an extra pose stream at or before the scan released next."""

    stream: str
    stamp_ns: int
    pose: Pose2D


Released = Paired[T] | OdometrySample | StreamSample
"""What the pairer releases, in the order to apply it."""


def paired_only(released: Sequence[Released[T]]) -> list[Paired[T]]:
    """The scans among what a pairer released (all of it in pairing mode without streams)."""
    return [r for r in released if isinstance(r, Paired)]


def _checked_cov(cov3x3: npt.ArrayLike | None) -> FloatArray | None:
    if cov3x3 is None:
        return None
    cov = np.asarray(cov3x3, dtype=np.float64)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise StampError(
            f"odometry: covariance must be a finite 3x3 matrix, got shape {cov.shape}")
    return cov


class ScanOdomPairer(Generic[T]):
    """Pairs scans (any payload) with odometry poses by stamp [ns] (module docstring).

    Never blocks. `odometry`, `scan` and `stream` each return what they released, in order.
    """

    def __init__(self, max_buffer: int = 200, *, every_odometry: bool = False,
                 streams: Sequence[str] = ()) -> None:
        if max_buffer < 1:
            raise StampError(f"ScanOdomPairer.max_buffer: expected >= 1, got {max_buffer}")
        self.max_buffer = max_buffer
        self.every_odometry = every_odometry
        self._odom: list[OdometrySample] = []  # sorted by stamp; with every_odometry: unreleased
        self._released: OdometrySample | None = None  # newest released (every_odometry)
        self._streams: dict[str, list[StreamSample]] = {name: [] for name in streams}
        self._scans: deque[tuple[int, T]] = deque()
        self.dropped_scans = 0
        self.stale_odometry = 0

    @property
    def scans_waiting(self) -> int:
        """Scans taken but not released yet (their odometry has not come)."""
        return len(self._scans)

    def odometry(self, t_ns: int, pose: Pose2D,
                 cov3x3: npt.ArrayLike | None = None) -> list[Released[T]]:
        """An odometry pose (and covariance); returns what it released."""
        sample = OdometrySample(t_ns, pose, _checked_cov(cov3x3))
        if self._released is not None and t_ns <= self._released.stamp_ns:
            self.stale_odometry += 1
            return []
        i = bisect.bisect_left(self._odom, t_ns, key=lambda o: o.stamp_ns)
        if i < len(self._odom) and self._odom[i].stamp_ns == t_ns:
            self._odom[i] = sample
        else:
            self._odom.insert(i, sample)
        return self._drain()

    def scan(self, t_ns: int, payload: T) -> list[Released[T]]:
        """A scan; returns what can be released now (this scan and older ones), in order."""
        i = len(self._scans)
        while i > 0 and self._scans[i - 1][0] > t_ns:
            i -= 1
        self._scans.insert(i, (t_ns, payload))
        if len(self._scans) > self.max_buffer:
            self._scans.popleft()
            self.dropped_scans += 1
        return self._drain()

    def stream(self, name: str, t_ns: int, pose: Pose2D) -> list[Released[T]]:
        """A sample of an extra stream; it is released before the scans of its stamp (or, when
        the stream's buffer overflows, at once, oldest first)."""
        if name not in self._streams:
            raise StampError(f"ScanOdomPairer.stream: unknown stream {name!r} "
                             f"(declared: {sorted(self._streams)})")
        buf = self._streams[name]
        bisect.insort(buf, StreamSample(name, t_ns, pose), key=lambda s: s.stamp_ns)
        if len(buf) > self.max_buffer:
            return [buf.pop(0)]
        return []

    def _newest_stamp(self) -> int | None:
        if self._odom:
            return self._odom[-1].stamp_ns
        return self._released.stamp_ns if self._released is not None else None

    def _release_odometry(self, t_ns: int) -> list[Released[T]]:
        """Every unreleased odometry stamped at or before t_ns (every_odometry)."""
        n = bisect.bisect_right(self._odom, t_ns, key=lambda o: o.stamp_ns)
        out: list[Released[T]] = list(self._odom[:n])
        if n:
            self._released = self._odom[n - 1]
        del self._odom[:n]
        return out

    def _release_streams(self, t_ns: int) -> list[Released[T]]:
        out: list[Released[T]] = []
        for buf in self._streams.values():
            m = bisect.bisect_right(buf, t_ns, key=lambda s: s.stamp_ns)
            if m:
                out.append(buf[m - 1])
                del buf[:m]
        return out

    def _pose_for(self, t_ns: int) -> OdometrySample | None:
        """The odometry a scan of stamp t_ns is paired with, or None (it cannot be)."""
        if self.every_odometry:
            last = self._released
            return last if last is not None and last.stamp_ns <= t_ns else None
        k = bisect.bisect_right(self._odom, t_ns, key=lambda o: o.stamp_ns) - 1
        return self._odom[k] if k >= 0 else None

    def _drain(self) -> list[Released[T]]:
        out: list[Released[T]] = []
        while self._scans:
            newest = self._newest_stamp()
            t_ns, payload = self._scans[0]
            if newest is None or newest < t_ns:
                break  # its odometry may still come
            self._scans.popleft()
            stale = self._released is not None and t_ns < self._released.stamp_ns
            if self.every_odometry and not stale:
                out += self._release_odometry(t_ns)
            odom = self._pose_for(t_ns)
            if odom is None or stale:  # older than every odometry kept, or passed over
                self.dropped_scans += 1
                continue
            out += self._release_streams(t_ns)
            out.append(Paired(t_ns, payload, odom.pose, odom.stamp_ns == t_ns))
        while len(self._odom) > self.max_buffer:  # no scan is waiting for the oldest
            if self.every_odometry:
                oldest = self._odom[0].stamp_ns
                out += self._release_odometry(oldest)
                out += self._release_streams(oldest)
            else:
                del self._odom[0]
        return out


U = TypeVar("U")


class StampJoin(Generic[T, U]):
    """Joins two streams that carry one item per stamp each, in stamp order (e.g. the paired
    scans a node got and another node's verdict on each): `left`/`right` add an item and return
    the (stamp [ns], left item, right item) pairs now complete. An item whose counterpart can no
    longer come (the other stream is past its stamp) is dropped and counted; each side keeps at
    most `max_buffer` items waiting (the oldest beyond are dropped and counted)."""

    def __init__(self, max_buffer: int) -> None:
        if max_buffer < 1:
            raise ValueError(f"StampJoin: max_buffer must be >= 1, got {max_buffer}")
        self.max_buffer = max_buffer
        self._left: deque[tuple[int, T]] = deque()
        self._right: deque[tuple[int, U]] = deque()
        self.unmatched_left = 0  # dropped: the right stream passed its stamp
        self.unmatched_right = 0
        self.overflow_left = 0  # dropped: more than max_buffer waiting
        self.overflow_right = 0

    def left(self, t_ns: int, item: T) -> list[tuple[int, T, U]]:
        self._left.append((t_ns, item))
        return self._join()

    def right(self, t_ns: int, item: U) -> list[tuple[int, T, U]]:
        self._right.append((t_ns, item))
        return self._join()

    def _join(self) -> list[tuple[int, T, U]]:
        out: list[tuple[int, T, U]] = []
        while self._left and self._right:
            (t_l, a), (t_r, b) = self._left[0], self._right[0]
            if t_l < t_r:
                self._left.popleft()
                self.unmatched_left += 1
            elif t_r < t_l:
                self._right.popleft()
                self.unmatched_right += 1
            else:
                self._left.popleft()
                self._right.popleft()
                out.append((t_l, a, b))
        while len(self._left) > self.max_buffer:
            self._left.popleft()
            self.overflow_left += 1
        while len(self._right) > self.max_buffer:
            self._right.popleft()
            self.overflow_right += 1
        return out
