"""The walls near a moving robot, for the questions the simulator asks every step (numpy only).

`island_msgs_py.geometry.clearance_m` measures a point against every wall with a dozen numpy
calls; the simulated robot asks it for its centre at every physics step, where those calls cost
far more than the arithmetic. `WallClearance` keeps the few walls that can be the nearest to
any point within `reach_m` of where it last gathered them, and measures a point against those
in plain float arithmetic: the same operations in the same order as `clearance_m`, so the answer
is the same bit for bit.

`NearbyRayCaster` does the same for a sonar ring: it keeps the walls a ray of at most the
sonar's range can reach from anywhere within `reach_m` of where it gathered them, and casts
against those only, with the brute-force caster (which the world's index equals bit for bit).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import point_segment_distance
from island_msgs_py.raycast import RayCaster, RayHits, raycast
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


RAY_REACH_M = 1.0
"""Walls gathered for ray casting serve ray origins within this of where they were gathered
[m] (about 20 sensor periods of driving)."""


class NearbyRayCaster:
    """A `RayCaster` over `caster`'s walls for rays of at most `max_range_m` [m] from origins
    near each other (a sonar ring on a moving robot).

    A wall hit at most max_range_m from an origin within r of the centre c lies within
    max_range_m + r of c: those walls are gathered at c, in their original order, and the hits
    found among them are the world's own (ties still go to the lowest index). Rays that may go
    farther, or origins beyond r of c (after gathering anew), are handled exactly too.
    """

    def __init__(self, caster: RayCaster, max_range_m: float, reach_m: float = RAY_REACH_M
                 ) -> None:
        self._caster = caster
        self._max_range_m = float(max_range_m)
        self._reach_m = float(reach_m)
        self._centre: FloatArray | None = None
        self._index: npt.NDArray[np.int64] = np.zeros(0, dtype=np.int64)
        self._near: FloatArray = np.zeros((0, 4))

    @property
    def segments(self) -> FloatArray:
        return self._caster.segments

    def raycast(self, origins: npt.ArrayLike, angles_rad: npt.ArrayLike,
                max_range_m: float = np.inf) -> RayHits:
        """First hits of rays from `origins` (M, 2) [m] along `angles_rad` (M,); see `raycast`."""
        o = np.atleast_2d(np.asarray(origins, dtype=np.float64))
        if not max_range_m <= self._max_range_m or o.shape[1:] != (2,) or o.shape[0] == 0:
            return self._caster.raycast(origins, angles_rad, max_range_m)
        if not self._covers(o):
            self._gather(o.mean(axis=0))
            if not self._covers(o):  # origins spread wider than the reach
                return self._caster.raycast(origins, angles_rad, max_range_m)
        hits = raycast(self._near, o, angles_rad, max_range_m)
        seg = hits.segment.copy()
        hit = seg >= 0
        seg[hit] = self._index[seg[hit]]
        return RayHits(hits.distance_m, seg, hits.cos_incidence, hits.normal_angle)

    def _covers(self, o: FloatArray) -> bool:
        c = self._centre
        if c is None:
            return False
        return bool(np.all(np.hypot(o[:, 0] - c[0], o[:, 1] - c[1]) <= self._reach_m))

    def _gather(self, centre: FloatArray) -> None:
        self._centre = centre
        segs = self._caster.segments
        if segs.shape[0] == 0:
            self._index, self._near = np.zeros(0, dtype=np.int64), np.zeros((0, 4))
            return
        dist = point_segment_distance(centre[None, :], segs)[0]
        self._index = np.flatnonzero(dist <= self._max_range_m + self._reach_m + _SLACK_M)
        self._near = np.ascontiguousarray(segs[self._index])
