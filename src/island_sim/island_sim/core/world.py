"""Line-segment worlds and ray casting (numpy only).

A world is a set of wall segments (N, 4) rows (x1, y1, x2, y2) [m] in the world frame.
`raycast` is the single ray caster of the project: the sonar model, the distinctiveness
measure and the localization-confidence simulation all use it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from island_msgs_py.types import FloatArray, Pose2D

# Rays closer than this to a segment's supporting line count as parallel (no hit) [m].
_PARALLEL_EPS = 1e-12


class WorldError(ValueError):
    """A world file or world description is malformed; the message names the file and problem."""


@dataclass(frozen=True, eq=False)
class World:
    """Wall segments (N, 4) [m] in the world frame, a name and a default start pose."""

    segments: FloatArray
    name: str = "world"
    start_pose: Pose2D = field(default_factory=lambda: Pose2D(0.0, 0.0, 0.0))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) [m] of all segment endpoints."""
        pts = self.segments.reshape(-1, 2)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    def raycast(
        self, origins: npt.ArrayLike, angles_rad: npt.ArrayLike, max_range_m: float = np.inf
    ) -> RayHits:
        """First hits of rays from `origins` (M, 2) [m] along `angles_rad` (M,); see `raycast`."""
        return raycast(self.segments, origins, angles_rad, max_range_m)


@dataclass(frozen=True)
class RayHits:
    """First hits of M rays.

    distance_m: (M,) distance to the first hit [m], `inf` where nothing within max range;
    segment: (M,) index of the hit segment, -1 for no hit;
    cos_incidence: (M,) |N . u| of the hit (1 = head-on), 0 for no hit;
    normal_angle: (M,) angle [rad] of the hit segment's normal facing the ray origin, 0 for no hit.
    """

    distance_m: FloatArray
    segment: npt.NDArray[np.int64]
    cos_incidence: FloatArray
    normal_angle: FloatArray


def raycast(
    segments: FloatArray,
    origins: npt.ArrayLike,
    angles_rad: npt.ArrayLike,
    max_range_m: float = np.inf,
    chunk: int = 4096,
) -> RayHits:
    """Cast M rays from `origins` (M, 2) [m] along `angles_rad` (M,) against `segments` (N, 4).

    Brute force over all segments, vectorized in chunks of rays. Returns the first hit per ray.
    """
    o = np.atleast_2d(np.asarray(origins, dtype=np.float64))
    a = np.atleast_1d(np.asarray(angles_rad, dtype=np.float64))
    if o.shape[0] == 1 and a.shape[0] > 1:
        o = np.broadcast_to(o, (a.shape[0], 2))
    m = a.shape[0]
    dist = np.full(m, np.inf)
    seg = np.full(m, -1, dtype=np.int64)
    if segments.shape[0] == 0 or m == 0:
        return RayHits(dist, seg, np.zeros(m), np.zeros(m))
    p = segments[:, 0:2]
    e = segments[:, 2:4] - p  # (N, 2) segment direction
    for s in range(0, m, chunk):
        oo = o[s : s + chunk]
        u = np.stack([np.cos(a[s : s + chunk]), np.sin(a[s : s + chunk])], axis=1)
        # Solve oo + t u = p + v e  ->  t = cross(p - oo, e) / cross(u, e), v = cross(p - oo, u) / cross(u, e)
        denom = u[:, None, 0] * e[None, :, 1] - u[:, None, 1] * e[None, :, 0]
        w0 = p[None, :, 0] - oo[:, None, 0]
        w1 = p[None, :, 1] - oo[:, None, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (w0 * e[None, :, 1] - w1 * e[None, :, 0]) / denom
            v = (w0 * u[:, None, 1] - w1 * u[:, None, 0]) / denom
        ok = (np.abs(denom) > _PARALLEL_EPS) & (t > 0.0) & (v >= 0.0) & (v <= 1.0)
        t = np.where(ok, t, np.inf)
        j = np.argmin(t, axis=1)
        tj = t[np.arange(t.shape[0]), j]
        hit = np.isfinite(tj) & (tj <= max_range_m)
        dist[s : s + chunk] = np.where(hit, tj, np.inf)
        seg[s : s + chunk] = np.where(hit, j, -1)
    return _finish_hits(segments, a, dist, seg)


def _finish_hits(
    segments: FloatArray, angles: FloatArray, dist: FloatArray, seg: npt.NDArray[np.int64]
) -> RayHits:
    """Fill incidence cosines and facing normal angles for hit rays."""
    hit = seg >= 0
    cos_inc = np.zeros_like(dist)
    normal = np.zeros_like(dist)
    if np.any(hit):
        sg = segments[seg[hit]]
        d = sg[:, 2:4] - sg[:, 0:2]
        n = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.linalg.norm(d, axis=1)[:, None]
        u = np.stack([np.cos(angles[hit]), np.sin(angles[hit])], axis=1)
        dot = np.sum(n * u, axis=1)
        n = np.where(dot[:, None] > 0, -n, n)  # the normal that faces back toward the ray origin
        cos_inc[hit] = np.abs(dot)
        normal[hit] = np.arctan2(n[:, 1], n[:, 0])
    return RayHits(dist, seg, cos_inc, normal)
