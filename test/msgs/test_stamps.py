"""Scan/odometry pairing by stamp (island_msgs_py.stamps)."""

from __future__ import annotations

import itertools

import pytest
from island_msgs_py.stamps import ScanOdomPairer, StampError
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
