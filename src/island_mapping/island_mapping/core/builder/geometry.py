"""Points between frames, scans to points, and whether a straight drive keeps clear of walls."""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.geometry import from_frame, to_frame
from island_msgs_py.geometry import ranges_to_points as _ranges_to_points
from island_msgs_py.types import FloatArray, Pose2D

from island_mapping.core.lines import point_segment_distance

# Spacing of the points a straight drive is checked at [m].
_DRIVE_CHECK_STEP_M = 0.05


def drive_clear(segs: FloatArray, a: FloatArray, b: FloatArray, clearance_m: float) -> bool:
    """Does the straight drive a -> b [m] keep clearance_m [m] from the walls `segs` (N, 4)?"""
    k = max(2, math.ceil(float(np.hypot(*(b - a))) / _DRIVE_CHECK_STEP_M) + 1)
    line = np.stack([np.linspace(a[0], b[0], k), np.linspace(a[1], b[1], k)], axis=1)
    return bool(point_segment_distance(line, segs).min() >= clearance_m)


def concat(points: list[FloatArray]) -> FloatArray:
    """The point lists stacked into one (N, 2) array (empty: (0, 2))."""
    return np.concatenate(points, axis=0) if points else np.zeros((0, 2))


def scan_points(r: FloatArray, a: FloatArray, pose: Pose2D) -> FloatArray:
    """(K, 2) points [m] of the finite ranges `r` at robot-frame angles `a`, in the pose's
    parent frame (island_msgs_py.geometry.ranges_to_points)."""
    return _ranges_to_points(r, a, pose)


__all__ = ["concat", "drive_clear", "from_frame", "scan_points", "to_frame"]
