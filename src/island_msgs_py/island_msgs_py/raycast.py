"""Ray casting against line segments (numpy only): the project's single ray caster.

Segments are (N, 4) rows (x1, y1, x2, y2) [m]; rays start at (M, 2) origins [m] along (M,)
angles [rad]. `raycast` is the brute-force caster; `SegmentIndex` answers the same queries bit
for bit with a spatial index (fast in worlds of thousands of walls); `RayCaster` is what both
it and the simulator's `World` offer (segments and a `raycast` method). The simulator's sonar and
worlds, the distinctiveness measure, the Fisher score, localization and place classification
all cast their rays here. `NearbyRayCaster` serves rays of a bounded range from a moving
point (the simulated sonar ring) from the few walls within that range, with the same answers.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from island_msgs_py.errors import InputError
from island_msgs_py.geometry import point_segment_distance
from island_msgs_py.types import FloatArray

# Rays closer than this to a segment's supporting line count as parallel (no hit) [m].
_PARALLEL_EPS = 1e-12


class RaycastError(InputError):
    """Malformed rays (origins and angles that do not match); the message names the shapes."""


@runtime_checkable
class RayCaster(Protocol):
    """Segments (N, 4) [m] that answer `raycast(origins, angles_rad, max_range_m) -> RayHits`."""

    @property
    def segments(self) -> FloatArray: ...

    def raycast(
        self, origins: npt.ArrayLike, angles_rad: npt.ArrayLike, max_range_m: float = ...
    ) -> RayHits: ...


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

    Brute force over all segments, vectorized in chunks of at most `chunk` rays (fewer when
    there are many segments, to bound memory). Returns the first hit per ray.
    """
    o, a = _prepare_rays(origins, angles_rad)
    m = a.shape[0]
    dist = np.full(m, np.inf)
    seg = np.full(m, -1, dtype=np.int64)
    if segments.shape[0] == 0 or m == 0:
        return RayHits(dist, seg, np.zeros(m), np.zeros(m))
    p = segments[:, 0:2]
    e = segments[:, 2:4] - p  # (N, 2) segment direction
    chunk = max(1, min(chunk, _MAX_PAIRS // segments.shape[0]))  # bounded temporaries
    for s in range(0, m, chunk):
        tj, j = _nearest_hits(p, e, o[s : s + chunk], a[s : s + chunk])
        hit = np.isfinite(tj) & (tj <= max_range_m)
        dist[s : s + chunk] = np.where(hit, tj, np.inf)
        seg[s : s + chunk] = np.where(hit, j, -1)
    return _finish_hits(segments, a, dist, seg)


# Below this many segments the index is not worth its bookkeeping: brute force.
_INDEX_MIN_SEGMENTS = 64
# Calls with at most this many rays x segments go to brute force.
_BRUTE_MAX_PAIRS = 1 << 15
# Slack added to query boxes so float round-off in hit distances never drops a candidate [m].
_BOX_MARGIN_M = 1e-6
# Largest rays x candidate-segments product evaluated at once (bounds temporary memory).
_MAX_PAIRS = 1 << 21
# Origin cell indices beyond this are not indexed (such rays go to brute force).
_MAX_CELL = 1 << 26
# Ray directions are split into this many equal sectors, each with its own candidate list.
_SECTORS = 8
# Rays whose candidates exceed 1 / this of all segments test all segments (no gather).
_DENSE_FRACTION_INV = 2
# Calls with at most this many rays skip the per-count bucketing.
_SMALL_CALL_RAYS = 1024
# Search radii whose per-cell candidate lists are kept.
_MAX_CACHED_RADII = 8


class SegmentIndex:
    """Spatial index for ray casting: ray-origin cells x direction sectors, with candidate lists.

    For a search radius r, origins are binned in square cells of size r / 4 and directions in 8
    sectors of 45 deg. The candidates of a (cell, sector) bin are the segments whose bounding
    boxes overlap the region that rays from the cell, in the sector, sweep within distance r
    (a box: the cell grown by the sector's bounding box; computed on first use and cached). A
    hit found at a distance <= r is exact: any nearer hit point lies in that region, so its
    segment was tested. Rays without such a hit are retried with a 3x larger radius until r
    reaches the maximum range or the farthest corner of the world. The answer equals
    brute-force `raycast` bit for bit, including ties (the lowest segment index wins). All rays
    of a pass are evaluated in vectorized chunks.
    """

    def __init__(self, segments: FloatArray) -> None:
        self.segments = np.asarray(segments, dtype=np.float64)
        n = self.segments.shape[0]
        # Row n is a zero-length dummy used to pad candidate lists: it is never hit.
        self._p = np.vstack([self.segments[:, 0:2], np.zeros((1, 2))])
        self._e = np.vstack([self.segments[:, 2:4] - self.segments[:, 0:2], np.zeros((1, 2))])
        self._lo = np.minimum(self.segments[:, 0:2], self.segments[:, 2:4])
        self._hi = np.maximum(self.segments[:, 0:2], self.segments[:, 2:4])
        if n:
            self._world_lo = self._lo.min(axis=0)
            self._world_hi = self._hi.max(axis=0)
            diag = float(np.linalg.norm(self._world_hi - self._world_lo))
        else:
            self._world_lo = self._world_hi = np.zeros(2)
            diag = 0.0
        # First search radius for unlimited rays: a tenth of the world, at least 4 m.
        self.base_radius_m = max(4.0, 0.1 * diag)
        self._cache: dict[float, dict[int, npt.NDArray[np.int64]]] = {}
        self._lock = threading.Lock()  # the cache may be filled from several executor threads

    def __len__(self) -> int:
        return int(self.segments.shape[0])

    def raycast(
        self, origins: npt.ArrayLike, angles_rad: npt.ArrayLike, max_range_m: float = np.inf
    ) -> RayHits:
        """First hits of rays from `origins` (M, 2) [m] along `angles_rad` (M,); see `raycast`."""
        n = len(self)
        if n < _INDEX_MIN_SEGMENTS:
            return raycast(self.segments, origins, angles_rad, max_range_m)
        o, a = _prepare_rays(origins, angles_rad)
        m = a.shape[0]
        if m * n <= _BRUTE_MAX_PAIRS:  # a small job: the bookkeeping would cost more
            return raycast(self.segments, o, a, max_range_m)
        dist = np.full(m, np.inf)
        seg = np.full(m, -1, dtype=np.int64)
        if not max_range_m > 0:
            return _finish_hits(self.segments, a, dist, seg)
        u = np.stack([np.cos(a), np.sin(a)], axis=1)
        sector = np.minimum(
            np.floor(np.mod(a, 2.0 * np.pi) / (2.0 * np.pi / _SECTORS)), _SECTORS - 1
        ).astype(np.int64)
        # Beyond this distance a ray has left the world's bounding box: nothing more to hit [m].
        corners = np.array(
            [
                [self._world_lo[0], self._world_lo[1]],
                [self._world_lo[0], self._world_hi[1]],
                [self._world_hi[0], self._world_lo[1]],
                [self._world_hi[0], self._world_hi[1]],
            ]
        )
        exit_m = np.sqrt(((o[:, None, :] - corners[None, :, :]) ** 2).sum(axis=2)).max(axis=1)
        pending = np.arange(m)
        r = min(float(max_range_m), self.base_radius_m)
        while pending.size:
            cell = r / 4.0
            cij_f = np.floor((o[pending] - self._world_lo) / cell)
            far = np.any(np.abs(cij_f) >= _MAX_CELL, axis=1)
            if np.any(far):  # absurdly distant origins: brute force
                fr = pending[far]
                hits = raycast(self.segments, o[fr], a[fr], max_range_m)
                dist[fr], seg[fr] = hits.distance_m, hits.segment
                pending, cij_f = pending[~far], cij_f[~far]
                if pending.size == 0:
                    break
            cij = cij_f.astype(np.int64) + _MAX_CELL
            keys = (cij[:, 0] * (2 * _MAX_CELL) + cij[:, 1]) * _SECTORS + sector[pending]
            ukeys, inv = np.unique(keys, return_inverse=True)
            lists = self._candidates(r, ukeys)
            counts = np.array([c.size for c in lists], dtype=np.int64)
            ray_counts = counts[inv]
            final = (r >= exit_m[pending]) | (r >= max_range_m)
            t, jg = self._pass_hits(o, a, u, pending, inv, lists, ray_counts)
            ok = np.isfinite(t) & (t <= max_range_m) & (final | (t <= r))
            dist[pending[ok]] = t[ok]
            seg[pending[ok]] = jg[ok]
            pending = pending[~ok & ~final]
            r = min(3.0 * r, float(max_range_m))
        return _finish_hits(self.segments, a, dist, seg)

    def _pass_hits(
        self,
        o: FloatArray,
        a: FloatArray,
        u: FloatArray,
        pending: npt.NDArray[np.int64],
        inv: npt.NDArray[np.int64],
        lists: list[npt.NDArray[np.int64]],
        ray_counts: npt.NDArray[np.int64],
    ) -> tuple[FloatArray, npt.NDArray[np.int64]]:
        """Nearest candidate hit (distance [m], segment) of each pending ray in one pass:
        `inv` maps a ray to its bin, `lists` holds each bin's candidate segments."""
        n = len(self)
        t = np.empty(pending.size)
        jg = np.empty(pending.size, dtype=np.int64)
        # Buckets of rays with similar candidate counts (padding wastes at most 2x); rays
        # with candidates for most of the world test all segments by broadcasting instead.
        if pending.size <= _SMALL_CALL_RAYS:  # one bucket: less bookkeeping per call
            dense = int(ray_counts.max()) * _DENSE_FRACTION_INV >= n
            bucket = np.full(pending.size, -1 if dense else 0, dtype=np.int64)
        else:
            bucket = np.where(
                ray_counts * _DENSE_FRACTION_INV >= n,
                -1,
                np.ceil(np.log2(np.maximum(ray_counts, 1))).astype(np.int64),
            )
        buckets = np.unique(bucket).tolist() if bucket.size > _SMALL_CALL_RAYS else [bucket[0]]
        for b in buckets:
            sel = np.flatnonzero(bucket == b)
            if b < 0:
                for s in range(0, sel.size, max(1, _MAX_PAIRS // n)):
                    ii = sel[s : s + max(1, _MAX_PAIRS // n)]
                    rays = pending[ii]
                    t[ii], jg[ii] = _nearest_hits(self._p[:n], self._e[:n], o[rays], a[rays])
                continue
            kmax = max(1, int(ray_counts[sel].max()))
            # One table row per bin of this bucket (not per bin of the pass: a few big
            # candidate lists times every bin would not fit in memory).
            rows, row_of = np.unique(inv[sel], return_inverse=True)
            table = np.full((rows.size, kmax), n, dtype=np.int64)
            for k, row in enumerate(rows.tolist()):
                c = lists[row]
                table[k, : c.size] = c
            step = max(1, _MAX_PAIRS // kmax)
            for s in range(0, sel.size, step):
                ii = sel[s : s + step]
                rays = pending[ii]
                cand = table[row_of[s : s + step]]  # (R, K) segment indices, padded with n
                ts = _hit_distances(
                    self._p[cand, 0],
                    self._p[cand, 1],
                    self._e[cand, 0],
                    self._e[cand, 1],
                    o[rays, 0:1],
                    o[rays, 1:2],
                    u[rays, 0:1],
                    u[rays, 1:2],
                )
                col = np.argmin(ts, axis=1)
                t[ii] = ts[np.arange(ii.size), col]
                jg[ii] = cand[np.arange(ii.size), col]
        return t, jg

    def _candidates(self, r: float, keys: npt.NDArray[np.int64]) -> list[npt.NDArray[np.int64]]:
        """Sorted candidate segment indices of the origin cells `keys` at search radius r [m]."""
        with self._lock:
            return self._candidates_locked(r, keys)

    def _candidates_locked(
        self, r: float, keys: npt.NDArray[np.int64]
    ) -> list[npt.NDArray[np.int64]]:
        cache = self._cache.get(r)
        if cache is None:
            if len(self._cache) >= _MAX_CACHED_RADII:
                self._cache.pop(next(iter(self._cache)))
            cache = self._cache[r] = {}
        missing = np.array([k for k in keys.tolist() if k not in cache], dtype=np.int64)
        if missing.size:
            cell = r / 4.0
            span = 2 * _MAX_CELL
            sec = missing % _SECTORS
            flat = missing // _SECTORS
            cij = np.stack([flat // span, flat % span], axis=1) - _MAX_CELL
            sec_lo, sec_hi = _sector_boxes(r)
            lo = self._world_lo + cij * cell + sec_lo[sec] - _BOX_MARGIN_M
            hi = self._world_lo + (cij + 1) * cell + sec_hi[sec] + _BOX_MARGIN_M
            n = len(self)
            step = max(1, _MAX_PAIRS // n)
            for s in range(0, missing.size, step):
                qlo, qhi = lo[s : s + step], hi[s : s + step]
                overlap = self._hi[None, :, 0] >= qlo[:, 0:1]
                overlap &= self._hi[None, :, 1] >= qlo[:, 1:2]
                overlap &= self._lo[None, :, 0] <= qhi[:, 0:1]
                overlap &= self._lo[None, :, 1] <= qhi[:, 1:2]
                for k, row in zip(missing[s : s + step].tolist(), overlap, strict=True):
                    cache[k] = np.flatnonzero(row).astype(np.int64)
        return [cache[k] for k in keys.tolist()]


NEARBY_REACH_M = 1.0
"""`NearbyRayCaster`'s walls serve ray origins within this of where they were gathered [m]
(about 20 sensor periods of a driving robot)."""
# Slack on the gathering radius, far above the round-off of the distances it compares [m].
_NEARBY_SLACK_M = 1e-6


class NearbyRayCaster:
    """A `RayCaster` over `caster`'s walls for rays of at most `max_range_m` [m] from origins
    near each other (a sonar ring on a moving robot); the answers are `caster`'s bit for bit.

    A wall hit at most max_range_m from an origin within r of the centre c lies within
    max_range_m + r of c: those walls are gathered at c, in their original order (a tie still
    goes to the lowest index), with their directions and unit normals, and rays are cast against
    them by brute force (which the index equals). Rays that may go farther, or origins beyond r
    of c after gathering anew, go to `caster`.
    """

    def __init__(self, caster: RayCaster, max_range_m: float,
                 reach_m: float = NEARBY_REACH_M) -> None:
        self._caster = caster
        self._max_range_m = float(max_range_m)
        self._reach_m = float(reach_m)
        self._centre: FloatArray | None = None
        self._index: npt.NDArray[np.int64] = np.zeros(0, dtype=np.int64)
        self._p = self._e = self._n = np.zeros((0, 2))

    @property
    def segments(self) -> FloatArray:
        return self._caster.segments

    def raycast(self, origins: npt.ArrayLike, angles_rad: npt.ArrayLike,
                max_range_m: float = np.inf) -> RayHits:
        """First hits of rays from `origins` (M, 2) [m] along `angles_rad` (M,); see `raycast`."""
        o, a = _prepare_rays(origins, angles_rad)
        if not max_range_m <= self._max_range_m or a.shape[0] == 0:
            return self._caster.raycast(o, a, max_range_m)
        if not self._covers(o):
            self._gather(o.mean(axis=0))
            if not self._covers(o):  # origins spread wider than the reach
                return self._caster.raycast(o, a, max_range_m)
        m = a.shape[0]
        dist = np.full(m, np.inf)
        seg = np.full(m, -1, dtype=np.int64)
        cos_inc, normal = np.zeros(m), np.zeros(m)
        if self._index.size == 0:
            return RayHits(dist, seg, cos_inc, normal)
        tj, j = _nearest_hits(self._p, self._e, o, a)
        hit = np.isfinite(tj) & (tj <= max_range_m)
        if np.any(hit):
            # As _finish_hits, from the gathered walls' unit normals.
            jh = j[hit]
            dist[hit], seg[hit] = tj[hit], self._index[jh]
            n = self._n[jh]
            u = np.stack([np.cos(a[hit]), np.sin(a[hit])], axis=1)
            dot = np.sum(n * u, axis=1)
            n = np.where(dot[:, None] > 0, -n, n)
            cos_inc[hit] = np.abs(dot)
            normal[hit] = np.arctan2(n[:, 1], n[:, 0])
        return RayHits(dist, seg, cos_inc, normal)

    def _covers(self, o: FloatArray) -> bool:
        c = self._centre
        if c is None:
            return False
        return bool(np.all(np.hypot(o[:, 0] - c[0], o[:, 1] - c[1]) <= self._reach_m))

    def _gather(self, centre: FloatArray) -> None:
        self._centre = centre
        segs = np.asarray(self._caster.segments, dtype=np.float64)
        if segs.shape[0] == 0:
            self._index = np.zeros(0, dtype=np.int64)
            return
        dist = point_segment_distance(centre[None, :], segs)[0]
        self._index = np.flatnonzero(
            dist <= self._max_range_m + self._reach_m + _NEARBY_SLACK_M).astype(np.int64)
        near = segs[self._index]
        self._p = np.ascontiguousarray(near[:, 0:2])
        self._e = near[:, 2:4] - self._p
        d = near[:, 2:4] - near[:, 0:2]
        self._n = np.stack([-d[:, 1], d[:, 0]], axis=1) / np.linalg.norm(d, axis=1)[:, None]


def _sector_boxes(r: float) -> tuple[FloatArray, FloatArray]:
    """(S, 2) low and high corners [m] of the boxes around the circular sectors of radius r.

    Sector k holds directions [k, k + 1) * 2 pi / S; its box holds the apex, the two arc ends and
    the arc's axis-aligned extreme points inside the sector.
    """
    lo = np.zeros((_SECTORS, 2))
    hi = np.zeros((_SECTORS, 2))
    width = 2.0 * math.pi / _SECTORS
    for k in range(_SECTORS):
        a0, a1 = k * width, (k + 1) * width
        angles = [a0, a1] + [q * math.pi / 2 for q in range(5) if a0 < q * math.pi / 2 < a1]
        pts = np.array([[0.0, 0.0]] + [[r * math.cos(t), r * math.sin(t)] for t in angles])
        lo[k], hi[k] = pts.min(axis=0), pts.max(axis=0)
    return lo, hi


def _hit_distances(
    px: FloatArray,
    py: FloatArray,
    ex: FloatArray,
    ey: FloatArray,
    ox: FloatArray,
    oy: FloatArray,
    ux: FloatArray,
    uy: FloatArray,
) -> FloatArray:
    """Elementwise (broadcast) ray-segment hit distance [m], inf where the ray misses.

    Ray: origin (ox, oy), unit direction (ux, uy). Segment: start (px, py), direction (ex, ey).
    Solves o + t u = p + v e: t = cross(p - o, e) / cross(u, e), v = cross(p - o, u) / cross(u, e).
    The brute-force and the indexed caster both call this, so they agree bit for bit.
    """
    denom = ux * ey - uy * ex
    w0 = px - ox
    w1 = py - oy
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (w0 * ey - w1 * ex) / denom
        v = (w0 * uy - w1 * ux) / denom
    ok = (np.abs(denom) > _PARALLEL_EPS) & (t > 0.0) & (v >= 0.0) & (v <= 1.0)
    return np.where(ok, t, np.inf)


def _prepare_rays(
    origins: npt.ArrayLike, angles_rad: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """(M, 2) origins [m] and (M,) angles [rad]; one origin is shared by all rays."""
    o = np.atleast_2d(np.asarray(origins, dtype=np.float64))
    a = np.atleast_1d(np.asarray(angles_rad, dtype=np.float64)).reshape(-1)
    if o.shape[0] == 1 and a.shape[0] > 1:
        o = np.broadcast_to(o, (a.shape[0], 2))
    if o.ndim != 2 or o.shape[1] != 2 or o.shape[0] != a.shape[0]:
        raise RaycastError(
            f"raycast: origins must be (M, 2) or (1, 2) for M = {a.shape[0]} angles, "
            f"got shape {o.shape}"
        )
    return o, a


def _nearest_hits(
    p: FloatArray, e: FloatArray, oo: FloatArray, aa: FloatArray
) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    """Nearest hit distance (R,) [m] (inf = none) and segment index (R,) of rays vs all segments.

    p: (S, 2) segment starts, e: (S, 2) segment directions; oo: (R, 2) origins, aa: (R,) angles.
    Ties go to the lowest segment index.
    """
    u = np.stack([np.cos(aa), np.sin(aa)], axis=1)
    t = _hit_distances(
        p[None, :, 0],
        p[None, :, 1],
        e[None, :, 0],
        e[None, :, 1],
        oo[:, 0:1],
        oo[:, 1:2],
        u[:, 0:1],
        u[:, 1:2],
    )
    j = np.argmin(t, axis=1)
    return t[np.arange(t.shape[0]), j], j.astype(np.int64)


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
