"""The walls near a moving robot, for the questions the simulator asks every step (numpy only).

`island_msgs_py.geometry.clearance_m` measures a point against every wall with a dozen numpy
calls; the simulated robot asks it for its centre at every physics step, where those calls cost
far more than the arithmetic. `WallClearance` keeps the few walls that can be the nearest to
any point within `reach_m` of where it last gathered them, and measures a point against those
in plain float arithmetic: the same operations in the same order as `clearance_m`, so the answer
is the same bit for bit.

The same idea for a sonar ring: `island_msgs_py.raycast.NearbyRayCaster`.
"""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.geometry import point_segment_distance
from island_msgs_py.types import FloatArray

REACH_M = 0.5
"""Walls gathered at a centre serve every point within this of it [m] (50 physics steps of a
robot at 0.5 m/s and 50 Hz)."""

# Slack on the gathering radius, far above the round-off of the distances it compares [m].
_SLACK_M = 1e-6


class WallClearance:
    """Centre-to-wall distance [m] of points (x, y) [m] against (N, 4) wall segments [m].

    A wall can be the nearest to a point q within r of a centre c only if its distance from c is
    at most d(c) + 2 r (d(c) the clearance at c): d(q) <= d(c) + r, and a wall's distance changes
    by at most r between c and q. Those walls are gathered at c, in their original order.
    """

    def __init__(self, segments: FloatArray, reach_m: float = REACH_M) -> None:
        self._segments = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
        self._reach_m = float(reach_m)
        self._centre: tuple[float, float] | None = None
        # (start x, start y, direction x, direction y, squared length) of the gathered walls.
        self._near: list[tuple[float, float, float, float, float]] = []

    def at(self, x: float, y: float) -> float:
        """Distance [m] from (x, y) to the nearest wall (inf without walls)."""
        c = self._centre
        if c is None or math.hypot(x - c[0], y - c[1]) > self._reach_m:
            self._gather(x, y)
        best = math.inf
        for px, py, dx, dy, dd in self._near:
            wx, wy = x - px, y - py
            t = (wx * dx + wy * dy) / dd if dd > 0 else 0.0
            t = min(max(t, 0.0), 1.0)
            ex, ey = wx - t * dx, wy - t * dy
            best = min(best, ex * ex + ey * ey)
        return math.sqrt(best)

    def _gather(self, x: float, y: float) -> None:
        self._centre = (x, y)
        if self._segments.shape[0] == 0:
            self._near = []
            return
        dist = point_segment_distance(np.array([[x, y]]), self._segments)[0]
        keep = dist <= float(dist.min()) + 2.0 * self._reach_m + _SLACK_M
        self._near = [
            (float(x1), float(y1), float(x2 - x1), float(y2 - y1),
             float((x2 - x1) * (x2 - x1) + (y2 - y1) * (y2 - y1)))
            for x1, y1, x2, y2 in self._segments[keep].tolist()
        ]

