"""The builder fed through the project's one stamp pairer, as island_builder_node feeds it
(island_msgs_py.stamps.ScanOdomPairer with every_odometry and a ground-truth stream, then
island_mapping.core.builder.feed)."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
import pytest
from island_mapping.core.builder import (
    GROUND_TRUTH,
    BuilderCommand,
    BuilderConfig,
    BuilderError,
    IslandBuilder,
    checked_cov,
    checked_scan,
    feed,
)
from island_msgs_py.stamps import ScanOdomPairer
from island_msgs_py.types import FloatArray, Pose2D


class _Sync:
    """What the node does per message: check, hand to the pairer, feed what it released."""

    def __init__(self, builder: IslandBuilder, max_buffer: int) -> None:
        self.builder = builder
        self.pairer: ScanOdomPairer[tuple[FloatArray, FloatArray]] = ScanOdomPairer(
            max_buffer, every_odometry=True, streams=(GROUND_TRUTH,))

    def odometry(self, t_ns: int, pose: Pose2D, cov: npt.ArrayLike
                 ) -> list[tuple[int, BuilderCommand]]:
        return feed(self.builder, self.pairer.odometry(t_ns, pose, checked_cov(t_ns * 1e-9, cov)))

    def ground_truth(self, t_ns: int, pose: Pose2D) -> list[tuple[int, BuilderCommand]]:
        return feed(self.builder, self.pairer.stream(GROUND_TRUTH, t_ns, pose))

    def scan(self, t_ns: int, r: npt.ArrayLike, a: npt.ArrayLike
             ) -> list[tuple[int, BuilderCommand]]:
        return feed(self.builder, self.pairer.scan(t_ns, checked_scan(t_ns * 1e-9, r, a)))


class _Recorder(IslandBuilder):
    """Records the odometry stamp and truth the builder holds when each scan is processed."""

    def __init__(self) -> None:
        super().__init__(BuilderConfig(build_first_island=False))
        self.seen: list[tuple[float, float, float | None]] = []
        self.odom_t = math.nan
        self.truth_x: float | None = None

    def on_odometry(self, t_s: float, odom_pose: Pose2D, cov3x3: npt.ArrayLike) -> None:
        super().on_odometry(t_s, odom_pose, cov3x3)
        self.odom_t = t_s

    def on_ground_truth(self, pose: Pose2D) -> None:
        super().on_ground_truth(pose)
        self.truth_x = pose.x

    def on_scan(self, t_s: float, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike) -> None:
        self.seen.append((t_s, self.odom_t, self.truth_x))
        super().on_scan(t_s, ranges_m, angles_rad)


def _feed(order: str) -> _Recorder:
    """Scans every 100 ms, odometry and truth every 20 ms (x = stamp in s), in one of two
    arrival orders: each sensor period's messages in stamp order, or the odometry and truth of
    the next period arriving before this period's scan (as DDS may deliver them)."""
    rec = _Recorder()
    sync = _Sync(rec, max_buffer=50)
    cov = np.diag([1e-4, 1e-4, 1e-6])
    ms = 1_000_000
    r, a = np.full(4, 2.0), np.linspace(-1.0, 1.0, 4)
    def odometry(t: int) -> None:
        sync.odometry(t, Pose2D(t * 1e-9, 0.0, 0.0), cov)
        sync.ground_truth(t, Pose2D(t * 1e-9, 0.0, 0.0))

    odometry(0)
    for k in range(10):
        scan_ns = 100 * k * ms
        if order == "stamp":  # the scan, then the odometry until the next scan
            sync.scan(scan_ns, r, a)
        for j in range(1, 6):
            odometry(scan_ns + 20 * j * ms)
        if order != "stamp":  # the scan after the next period's odometry
            sync.scan(scan_ns, r, a)
    assert sync.pairer.scans_waiting == 0 and sync.pairer.dropped_scans == 0
    return rec


def test_stamp_sync_pairs_each_scan_with_its_own_odometry_whatever_the_arrival_order() -> None:
    by_stamp, early_odom = _feed("stamp"), _feed("early")
    assert len(by_stamp.seen) == len(early_odom.seen) == 10
    for seen in (by_stamp.seen, early_odom.seen):
        for t_scan, t_odom, truth_x in seen:
            assert t_odom == pytest.approx(t_scan)  # not the newer odometry that had arrived
            assert truth_x == pytest.approx(t_scan)
    assert by_stamp.seen == early_odom.seen
    assert by_stamp.path_m == pytest.approx(early_odom.path_m)


def test_stamp_sync_holds_a_scan_until_its_odometry_and_bounds_its_buffers() -> None:
    rec = _Recorder()
    sync = _Sync(rec, max_buffer=3)
    cov = np.zeros((3, 3))
    r, a = np.full(2, 1.0), np.zeros(2)
    assert sync.odometry(3, Pose2D(0.3, 0.0, 0.0), cov) == []
    assert sync.scan(5, r, a) == []  # no odometry of its stamp yet: held back, nothing blocks
    assert sync.pairer.scans_waiting == 1
    out = sync.odometry(7, Pose2D(1.0, 0.0, 0.0), cov)  # newer odometry releases it
    # ... paired with the newest older odometry (3), not with the one that released it (7).
    assert [t for t, _ in out] == [5] and rec.seen[0][1] == pytest.approx(3e-9)
    assert sync.odometry(2, Pose2D(0.5, 0.0, 0.0), cov) == [] and sync.pairer.stale_odometry == 1
    for k in range(5):  # no odometry arriving: the oldest scans are dropped and counted
        sync.scan(100 + k, r, a)
    assert sync.pairer.scans_waiting == 3 and sync.pairer.dropped_scans == 2
    with pytest.raises(BuilderError, match="3 ranges but 2 angles"):
        sync.scan(200, np.ones(3), np.zeros(2))
    with pytest.raises(BuilderError, match="covariance"):
        sync.odometry(300, Pose2D(0.0, 0.0, 0.0), np.ones((2, 2)))
