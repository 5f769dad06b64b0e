"""Points between frames (from island_msgs_py.geometry), and whether a straight drive keeps
clear of walls."""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.geometry import from_frame, to_frame
from island_msgs_py.types import FloatArray

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


__all__ = ["concat", "drive_clear", "from_frame", "to_frame"]
