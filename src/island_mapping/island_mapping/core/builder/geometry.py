"""Points between frames, scans to points, and whether a straight drive keeps clear of walls."""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.types import FloatArray, Pose2D

from island_mapping.core.lines import point_segment_distance

# Spacing of the points a straight drive is checked at [m].
_DRIVE_CHECK_STEP_M = 0.05


def scan_points(r: FloatArray, a: FloatArray, pose: Pose2D) -> FloatArray:
    """(K, 2) points [m] of the finite ranges `r` at robot-frame angles `a`, in the pose's
    parent frame."""
    ok = np.isfinite(r) & np.isfinite(a)
    ang = a[ok] + pose.theta
    return np.stack([pose.x + r[ok] * np.cos(ang), pose.y + r[ok] * np.sin(ang)], axis=1)


def from_frame(points: FloatArray, frame: Pose2D) -> FloatArray:
    """(K, 2) points [m] of `frame` expressed in its parent frame."""
    c, s = math.cos(frame.theta), math.sin(frame.theta)
    x = frame.x + c * points[:, 0] - s * points[:, 1]
    return np.stack([x, frame.y + s * points[:, 0] + c * points[:, 1]], axis=1)


def to_frame(points: FloatArray, frame: Pose2D) -> FloatArray:
    """(K, 2) points [m] of the parent frame expressed in `frame`."""
    c, s = math.cos(frame.theta), math.sin(frame.theta)
    d = points - np.array([frame.x, frame.y])
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)


def drive_clear(segs: FloatArray, a: FloatArray, b: FloatArray, clearance_m: float) -> bool:
    """Does the straight drive a -> b [m] keep clearance_m [m] from the walls `segs` (N, 4)?"""
    k = max(2, math.ceil(float(np.hypot(*(b - a))) / _DRIVE_CHECK_STEP_M) + 1)
    line = np.stack([np.linspace(a[0], b[0], k), np.linspace(a[1], b[1], k)], axis=1)
    return bool(point_segment_distance(line, segs).min() >= clearance_m)


def concat(points: list[FloatArray]) -> FloatArray:
    """The point lists stacked into one (N, 2) array (empty: (0, 2))."""
    return np.concatenate(points, axis=0) if points else np.zeros((0, 2))
