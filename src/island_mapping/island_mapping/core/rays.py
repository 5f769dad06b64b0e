"""The rays of the model measures: what the line measure R and the Fisher score share.

From every point, rays leave every `angular_res_deg` over 360 deg (`ray_angles`). Points are
cast tile by tile (`tiled_chunks`): a tile's rays go to the brute-force `raycast` against the
few segments within range of the tile, or to the model's spatial index when many are. Both
give the same hits as casting against the whole model (`island_msgs_py.raycast`).
Bad points raise `MeasureError` (the measure's exception, shared with `measure`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.raycast import RayCaster, RayHits, SegmentIndex, raycast
from island_msgs_py.types import FloatArray, as_segments

IntArray = npt.NDArray[np.int64]

# Side of the point tiles whose near segments are cast against [m].
_TILE_M = 2.0
# Models with at most this many segments are cast whole (tiling would not pay).
_TILE_MIN_SEGMENTS = 12
# Tiles whose near segments exceed this use the model's spatial index instead of brute force.
_TILE_MAX_SUBSET = 64


MIN_ANGULAR_RES_DEG = 0.01
"""Finest angular resolution of the measures' rays [deg]: 36,000 rays per point."""
MAX_EPS_STEPS = 50
"""Most averaging steps per side of R(p, eps) (eq. 4): (2 x 50 + 1)^2 samples per point."""


class MeasureError(InputError):
    """Bad input to the measure (the message names the argument and the problem)."""


def as_points(points: npt.ArrayLike, name: str = "points") -> FloatArray:
    """Validate (P, 2) finite points [m] (a single (2,) point becomes (1, 2))."""
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 1 and arr.shape[0] == 2:
        arr = arr[None, :]
    if arr.size == 0:
        return np.zeros((0, 2))
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise MeasureError(f"{name}: expected a (P, 2) array of x, y [m], got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise MeasureError(f"{name}: contains a NaN or infinite coordinate")
    return arr


def as_caster(segments: npt.ArrayLike | RayCaster) -> RayCaster:
    """A ray caster over the segments: a given one (a simulator `World`, a `SegmentIndex`) as
    it is, else a `SegmentIndex` over the (K, 4) segments [m] (fast on big models)."""
    if isinstance(segments, RayCaster):
        return segments
    return SegmentIndex(as_segments(segments))


def ray_angles(angular_res_deg: float) -> FloatArray:
    """(n,) ray angles [rad]: j * angular_res_deg for j = 0 .. round(360 / res) - 1."""
    n = max(1, round(360.0 / angular_res_deg))
    return np.arange(n, dtype=np.float64) * math.radians(angular_res_deg)


def _tiles(
    pts: FloatArray, seg: FloatArray, max_range_m: float
) -> list[tuple[IntArray, IntArray | None]]:
    """Points grouped in square tiles with the segments a ray from the tile can hit within range.

    A segment farther than max_range_m from a tile's box cannot give a counted hit, nor occlude
    one (a hit beyond range does not count), so casting against the near segments only gives
    the same counted hits. Small subsets go to the brute-force `raycast` (the same caster as the
    spatial index); large ones (None) to the model's spatial index.
    """
    everything = np.arange(pts.shape[0], dtype=np.int64)
    if not math.isfinite(max_range_m) or seg.shape[0] <= _TILE_MIN_SEGMENTS:
        return [(everything, None)]
    lo_seg = np.minimum(seg[:, 0:2], seg[:, 2:4])
    hi_seg = np.maximum(seg[:, 0:2], seg[:, 2:4])
    key = np.floor((pts - pts.min(axis=0)) / _TILE_M).astype(np.int64)
    tile_id = key[:, 0] * (int(key[:, 1].max()) + 1) + key[:, 1]
    order = np.argsort(tile_id, kind="stable")
    cuts = np.flatnonzero(np.diff(tile_id[order])) + 1
    out: list[tuple[IntArray, IntArray | None]] = []
    for group in np.split(order, cuts):
        box_lo = pts[group].min(axis=0) - max_range_m
        box_hi = pts[group].max(axis=0) + max_range_m
        near = np.all(hi_seg >= box_lo, axis=1) & np.all(lo_seg <= box_hi, axis=1)
        sub = np.flatnonzero(near).astype(np.int64)
        out.append((group.astype(np.int64), sub if sub.size <= _TILE_MAX_SUBSET else None))
    return out


def tiled_chunks(
    pts: FloatArray, seg: FloatArray, max_range_m: float, per_chunk: int
) -> list[tuple[IntArray, IntArray | None]]:
    """(point indices, near-segment indices or None) in chunks of at most `per_chunk` points,
    tile by tile (see `_tiles`)."""
    out = []
    for group, sub in _tiles(pts, seg, max_range_m):
        for s in range(0, group.shape[0], per_chunk):
            out.append((group[s : s + per_chunk], sub))
    return out


def cast_chunk(
    caster: RayCaster,
    pts: FloatArray,
    members: IntArray,
    near: IntArray | None,
    angles_rad: FloatArray,
    max_range_m: float,
) -> tuple[FloatArray, RayHits]:
    """Every ray of `angles_rad` from each point pts[members]: (ray angles (M,) [rad], hits).

    Ray j of member i is row i * len(angles_rad) + j. `near` (from `tiled_chunks`) limits the
    cast to those segments; hit segment indices always index `caster.segments`.
    """
    origins = np.repeat(pts[members], angles_rad.shape[0], axis=0)
    ang = np.tile(angles_rad, members.shape[0])
    if near is None:
        return ang, caster.raycast(origins, ang, max_range_m)
    hits = raycast(caster.segments[near], origins, ang, max_range_m)
    seg = np.where(hits.segment >= 0, near[np.maximum(hits.segment, 0)], -1)
    return ang, replace(hits, segment=seg)
