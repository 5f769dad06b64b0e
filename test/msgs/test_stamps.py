"""Scan/odometry pairing by stamp (island_msgs_py.stamps)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from island_msgs_py.stamps import (
    OdometrySample,
    Paired,
    Released,
    ScanOdomPairer,
    StampError,
    StreamSample,
    paired_only,
)
from island_msgs_py.types import Pose2D


def _pose(t_ns: int) -> Pose2D:
    return Pose2D(t_ns * 1e-9, 0.0, 0.0)  # x encodes the stamp it belongs to


# Each publisher delivers in order (reliable DDS); the two streams interleave in any way.
INTERLEAVINGS = sorted({
    p for p in itertools.permutations(["o0", "s0", "o1", "s1", "o2"])
    if [x for x in p if x[0] == "o"] == ["o0", "o1", "o2"]
    and [x for x in p if x[0] == "s"] == ["s0", "s1"]
})


@pytest.mark.parametrize("order", INTERLEAVINGS)
def test_each_scan_gets_the_pose_of_its_own_stamp_whatever_the_arrival_order(
    order: tuple[str, ...],
) -> None:
    pairer: ScanOdomPairer[str] = ScanOdomPairer()
    out = []
    for item in order:
        k = int(item[1]) * 100_000_000  # 0.1 s periods
        if item[0] == "o":
            out += pairer.odometry(k, _pose(k))
        else:
            out += pairer.scan(k, f"scan{item[1]}")
    assert [(p.payload, p.pose.x, p.exact) for p in out] == [
        ("scan0", 0.0, True), ("scan1", pytest.approx(0.1), True)]
    assert pairer.scans_waiting == 0 and pairer.dropped_scans == 0


def test_a_scan_without_its_own_odometry_waits_then_takes_the_newest_older_pose() -> None:
    pairer: ScanOdomPairer[str] = ScanOdomPairer()
    assert pairer.odometry(100, _pose(100)) == []
    assert pairer.scan(150, "between") == []  # odometry at 150 may still come
    assert pairer.scans_waiting == 1
    (p,) = pairer.odometry(200, _pose(200))
    assert p.payload == "between" and p.stamp_ns == 150 and p.pose == _pose(100) and not p.exact


def test_scans_older_than_every_pose_and_overflowing_scans_are_dropped_and_counted() -> None:
    pairer: ScanOdomPairer[int] = ScanOdomPairer(max_buffer=3)
    for k in range(5):  # no odometry arrives: only the newest 3 scans are kept
        assert pairer.scan(1000 + k, k) == []
    assert pairer.dropped_scans == 2 and pairer.scans_waiting == 3
    for t in range(2000, 2004):  # 4 poses, the buffer keeps the newest 3 (2001..2003)
        pairer.odometry(t, _pose(t))
    assert pairer.dropped_scans == 5  # the 3 waiting scans were older than every pose kept
    (p,) = pairer.scan(2002, 9)
    assert p.exact and p.pose == _pose(2002)
    with pytest.raises(StampError, match="max_buffer"):
        ScanOdomPairer(max_buffer=0)


# ----- every_odometry: the builder's mode (each odometry released, in stamp order) ---------


def _kinds(released: list[Released[str]]) -> list[tuple[str, int]]:
    """(kind, stamp) of each released item: 'o' odometry, 's' scan, stream name for a stream."""
    out = []
    for r in released:
        if isinstance(r, OdometrySample):
            out.append(("o", r.stamp_ns))
        elif isinstance(r, StreamSample):
            out.append((r.stream, r.stamp_ns))
        else:
            out.append(("s", r.stamp_ns))
    return out


@pytest.mark.parametrize("order", INTERLEAVINGS)
def test_every_odometry_is_released_in_stamp_order_before_the_scans_it_precedes(
    order: tuple[str, ...],
) -> None:
    pairer: ScanOdomPairer[str] = ScanOdomPairer(every_odometry=True)
    out: list[Released[str]] = []
    for item in order:
        k = int(item[1]) * 100_000_000
        if item[0] == "o":
            out += pairer.odometry(k, _pose(k), np.eye(3))
        else:
            out += pairer.scan(k, f"scan{item[1]}")
    # o2 stays buffered: no scan needs it yet.
    assert _kinds(out) == [("o", 0), ("s", 0), ("o", 100_000_000), ("s", 100_000_000)]
    assert paired_only(out)[1].exact and paired_only(out)[1].pose == _pose(100_000_000)


def test_every_odometry_ignores_odometry_it_already_passed_and_drops_scans_it_passed() -> None:
    pairer: ScanOdomPairer[str] = ScanOdomPairer(max_buffer=2, every_odometry=True)
    assert pairer.odometry(10, _pose(10)) == []
    assert _kinds(pairer.scan(10, "a")) == [("o", 10), ("s", 10)]
    assert pairer.odometry(10, _pose(10)) == [] and pairer.odometry(5, _pose(5)) == []
    assert pairer.stale_odometry == 2  # at or before the odometry released: out of order
    for t in (20, 30):
        assert pairer.odometry(t, _pose(t)) == []
    # A third odometry overflows the buffer with no scan waiting: the oldest is released.
    assert _kinds(pairer.odometry(40, _pose(40))) == [("o", 20)]
    assert pairer.scan(15, "late") == [] and pairer.dropped_scans == 1  # odometry passed it
    (o30, s35) = pairer.scan(35, "b")
    assert isinstance(s35, Paired) and s35.pose == _pose(30) and not s35.exact
    assert isinstance(o30, OdometrySample) and o30.stamp_ns == 30 and o30.cov is None


def test_streams_release_their_newest_sample_at_or_before_each_scan() -> None:
    pairer: ScanOdomPairer[str] = ScanOdomPairer(max_buffer=3, streams=("truth",))
    for t in (1, 2, 3):
        assert pairer.stream("truth", t, _pose(t)) == []
    pairer.odometry(2, _pose(2))
    assert _kinds(pairer.scan(2, "a")) == [("truth", 2), ("s", 2)]  # 1 passed over, 3 waits
    for t in (4, 5, 6):  # the buffer holds 3: the oldest (3) is released at once
        out = pairer.stream("truth", t, _pose(t))
    assert _kinds(out) == [("truth", 3)]
    with pytest.raises(StampError, match="unknown stream 'gps'"):
        pairer.stream("gps", 7, _pose(7))
    with pytest.raises(StampError, match="covariance"):
        pairer.odometry(8, _pose(8), np.ones((2, 3)))


def test_stamp_join_pairs_equal_stamps_and_drops_what_cannot_match() -> None:
    from island_msgs_py.stamps import StampJoin

    join: StampJoin[str, int] = StampJoin(max_buffer=2)
    assert join.left(10, "a") == []
    assert join.right(10, 1) == [(10, "a", 1)]
    assert join.left(20, "b") == []  # its verdict never comes: the next one is for 30
    assert join.left(30, "c") == []
    assert join.right(30, 3) == [(30, "c", 3)]
    assert join.unmatched_left == 1 and join.unmatched_right == 0
    assert join.right(40, 4) == [] and join.left(50, "e") == []  # 40 has no scan
    assert join.unmatched_right == 1
    assert join.right(60, 6) == [] and join.unmatched_left == 2  # scan 50's verdict passed
    join.right(70, 7)
    join.right(80, 8)  # three verdicts waiting for scans, two kept: the oldest is dropped
    assert join.overflow_right == 1 and join.overflow_left == 0
    assert join.left(70, "g") == [(70, "g", 7)]
    with pytest.raises(ValueError, match="max_buffer"):
        StampJoin(0)
