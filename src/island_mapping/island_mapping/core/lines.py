"""Line models from range points (paper section 6): cluster, split, fit, merge.

`fit_lines(points_xy, config)` turns (N, 2) points [m] in one frame (a 180-beam laser scan, or
sonar echoes accumulated over a few poses) into a `LineModel`:

1. drop rows with NaN/inf;
2. spatial clustering: connected components of the graph joining points closer than
   `cluster_dist_m` (scipy cKDTree + csgraph);
3. split: a cluster whose total-least-squares line leaves a point farther than `split_dist_m`
   is cut in two by iterative end-point fit along the cluster's principal direction, each part is
   re-clustered by connectivity and treated the same way (split-and-merge);
4. a total least squares line per cluster (principal axis of the centred points); clusters with
   fewer than `min_points` points, an RMS distance above `max_fit_rms_m` or a length below
   `min_length_m` are dropped; endpoints are the extreme projections of the points on the line;
5. merge: two segments whose directions differ by at most `merge_angle_deg`, whose lines pass
   within `merge_offset_m` of each other's midpoints and whose extents along the common direction
   leave a gap of at most `merge_gap_m` are refit as one (repeated until nothing merges).

Degenerate input (empty, 1-2 points, non-finite rows) gives an empty or small model, never an
exception.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import point_segment_distance
from island_msgs_py.types import FloatArray, LineModel
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

IntArray = npt.NDArray[np.int64]

# k-lines refinement rounds (reassign points to the nearest segment, refit) before merging.
_REASSIGN_ROUNDS = 2
# Recursion guard for the split step (a cluster is split at most this deep).
_MAX_SPLIT_DEPTH = 32


class LineFitError(InputError):
    """A LineFitConfig value is invalid (the message names the field)."""


@dataclass(frozen=True)
class LineFitConfig:
    """Parameters of the line fit (single source of defaults).

    The defaults suit sparse sonar echoes (a 16-beam ring, a 25 deg cone: points lie up to ~0.2 m
    off the wall and ~1 m apart); for a 1-deg laser scan `LASER_LINE_FIT` is tighter.
    """

    cluster_dist_m: float = field(
        default=1.0, metadata={"help": "points closer than this are neighbours in a cluster [m]"}
    )
    min_points: int = field(
        default=3, metadata={"help": "fewest points that make a line segment [-]"}
    )
    split_dist_m: float = field(
        default=0.2,
        metadata={"help": "a cluster is split when a point is farther than this from its fitted "
                  "line [m]"},
    )
    max_fit_rms_m: float = field(
        default=0.1, metadata={"help": "largest RMS point-to-line distance of a kept segment [m]"}
    )
    min_length_m: float = field(
        default=0.2, metadata={"help": "shortest kept segment [m]"}
    )
    merge_angle_deg: float = field(
        default=8.0, metadata={"help": "largest direction difference of merged segments [deg]"}
    )
    merge_offset_m: float = field(
        default=0.25,
        metadata={"help": "largest distance of the shorter segment's endpoints from the longer "
                  "one's line when merging [m]"},
    )
    merge_gap_m: float = field(
        default=1.0,
        metadata={"help": "largest gap between the extents of merged collinear segments [m]"},
    )

    def __post_init__(self) -> None:
        for name in ("cluster_dist_m", "split_dist_m", "max_fit_rms_m", "min_length_m",
                     "merge_angle_deg", "merge_offset_m", "merge_gap_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise LineFitError(f"LineFitConfig.{name}: expected a finite number, got {v!r}")
            if v < 0:
                raise LineFitError(f"LineFitConfig.{name}: must be >= 0, got {v}")
        if self.cluster_dist_m <= 0 or self.split_dist_m <= 0:
            raise LineFitError("LineFitConfig: cluster_dist_m and split_dist_m must be > 0")
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int | np.integer):
            raise LineFitError(
                f"LineFitConfig.min_points: expected an int, got {self.min_points!r}"
            )
        if self.min_points < 2:
            raise LineFitError(f"LineFitConfig.min_points: must be >= 2, got {self.min_points}")


@dataclass(frozen=True)
class _Fit:
    centroid: FloatArray  # (2,) [m]
    direction: FloatArray  # (2,) unit
    rms_m: float
    max_dev_m: float


def tls_fit(points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Total least squares line of (n >= 2, 2) points: (centroid, unit direction, signed
    perpendicular distances (n,) [m])."""
    centroid = points.mean(axis=0)
    centred = points - centroid
    cov = centred.T @ centred
    _evals, evecs = np.linalg.eigh(cov)
    direction = evecs[:, 1]  # largest eigenvalue: the principal axis
    normal = np.array([-direction[1], direction[0]])
    return centroid, direction, centred @ normal


def _fit(points: FloatArray) -> _Fit:
    c, d, dev = tls_fit(points)
    return _Fit(c, d, float(np.sqrt(np.mean(dev**2))), float(np.max(np.abs(dev))))


def _components(points: FloatArray, dist_m: float) -> list[IntArray]:
    """Index arrays of the connected components of the `dist_m` neighbour graph."""
    n = points.shape[0]
    if n == 0:
        return []
    pairs = cKDTree(points).query_pairs(dist_m, output_type="ndarray")
    graph = coo_matrix(
        (np.ones(pairs.shape[0]), (pairs[:, 0], pairs[:, 1])), shape=(n, n)
    ) if pairs.size else coo_matrix((n, n))
    _, labels = connected_components(graph, directed=False)
    order = np.argsort(labels, kind="stable")
    cuts = np.flatnonzero(np.diff(labels[order])) + 1
    return [np.asarray(g, dtype=np.int64) for g in np.split(order, cuts)]


def _split_index(ordered: FloatArray) -> int:
    """Iterative end-point fit: index of the point farthest from the chord first -> last."""
    a, b = ordered[0], ordered[-1]
    chord = b - a
    length = float(np.hypot(chord[0], chord[1]))
    rel = ordered - a
    if length < 1e-9:
        dist = np.hypot(rel[:, 0], rel[:, 1])
    else:
        dist = np.abs(rel[:, 0] * chord[1] - rel[:, 1] * chord[0]) / length
    return int(np.argmax(dist))


def _split(points: FloatArray, idx: IntArray, cfg: LineFitConfig, depth: int) -> list[IntArray]:
    """Split a cluster (indices into points) into line-like parts."""
    if idx.shape[0] < cfg.min_points:
        return []
    fit = _fit(points[idx])
    if fit.max_dev_m <= cfg.split_dist_m or depth >= _MAX_SPLIT_DEPTH:
        return [idx]
    order = idx[np.argsort((points[idx] - fit.centroid) @ fit.direction, kind="stable")]
    k = _split_index(points[order])
    if k <= 0 or k >= order.shape[0] - 1:
        k = order.shape[0] // 2
    parts: list[IntArray] = []
    # The split point belongs to both sides (a corner is on both walls).
    for half in (order[: k + 1], order[k:]):
        for comp in _components(points[half], cfg.cluster_dist_m):
            parts.extend(_split(points, half[comp], cfg, depth + 1))
    return parts


def _segment_from(points: FloatArray) -> tuple[FloatArray, _Fit]:
    fit = _fit(points)
    t = (points - fit.centroid) @ fit.direction
    p1 = fit.centroid + t.min() * fit.direction
    p2 = fit.centroid + t.max() * fit.direction
    return np.concatenate([p1, p2]), fit


def thin_evenly(points: FloatArray, max_points: int) -> FloatArray:
    """At most `max_points` of the (K, 2) `points`, taken evenly along the array (scans arrive in
    order, so this keeps every direction and place represented)."""
    if points.shape[0] <= max_points:
        return points
    keep = np.linspace(0, points.shape[0] - 1, max_points).round().astype(int)
    return points[keep]


def _reassign(
    pts: FloatArray, items: list[tuple[FloatArray, IntArray]], cfg: LineFitConfig
) -> list[tuple[FloatArray, IntArray]]:
    """Give every point to its nearest segment (within split_dist_m) and refit (k-lines step):
    repairs corner points that the split put on the wrong wall."""
    if not items:
        return items
    segs = np.stack([s for s, _ in items])
    dist = point_segment_distance(pts, segs)
    best = np.argmin(dist, axis=1)
    ok = dist[np.arange(pts.shape[0]), best] <= cfg.split_dist_m
    out: list[tuple[FloatArray, IntArray]] = []
    for i, (seg, g) in enumerate(items):
        g_new = np.flatnonzero(ok & (best == i)).astype(np.int64)
        if g_new.shape[0] < cfg.min_points:
            continue
        seg_new, fit = _segment_from(pts[g_new])
        if fit.rms_m <= cfg.max_fit_rms_m:
            out.append((seg_new, g_new))
        else:
            out.append((seg, g))
    return out


def _extend(
    pts: FloatArray, seg: FloatArray, support: IntArray, cfg: LineFitConfig
) -> tuple[FloatArray, IntArray]:
    """Stretch a segment over the points near its line that continue it (corner points the split
    gave to the other wall): within split_dist_m of the line and cluster_dist_m of the extent."""
    d = seg[2:4] - seg[0:2]
    length = float(np.hypot(d[0], d[1]))
    if length < 1e-9:
        return seg, support
    u = d / length
    n = np.array([-u[1], u[0]])
    rel = pts - seg[0:2]
    t = rel @ u
    near = np.abs(rel @ n) <= cfg.split_dist_m
    near &= (t >= -cfg.cluster_dist_m) & (t <= length + cfg.cluster_dist_m)
    t_near = t[near]
    lo = min(0.0, float(t_near.min())) if t_near.size else 0.0
    hi = max(length, float(t_near.max())) if t_near.size else length
    # Grow only over contiguous points: stop at the first gap wider than cluster_dist_m.
    ts = np.sort(np.concatenate([t_near, [0.0, length]]))
    inside = (ts >= lo) & (ts <= hi)
    ts = ts[inside]
    gaps = np.diff(ts)
    start = int(np.searchsorted(ts, 0.0))
    end = int(np.searchsorted(ts, length, side="right")) - 1
    while start > 0 and gaps[start - 1] <= cfg.cluster_dist_m:
        start -= 1
    while end < ts.shape[0] - 1 and gaps[end] <= cfg.cluster_dist_m:
        end += 1
    new = np.concatenate([seg[0:2] + ts[start] * u, seg[0:2] + ts[end] * u])
    return new, support


def _mergeable(a: FloatArray, b: FloatArray, cfg: LineFitConfig) -> bool:
    da, db = a[2:4] - a[0:2], b[2:4] - b[0:2]
    la, lb = float(np.hypot(*da)), float(np.hypot(*db))
    if la < 1e-9 or lb < 1e-9:
        return False
    ua, ub = da / la, db / lb
    if abs(float(ua @ ub)) < math.cos(math.radians(cfg.merge_angle_deg)):
        return False
    # Both endpoints of the shorter segment must lie near the longer one's line.
    long_, short = (a, b) if la >= lb else (b, a)
    u_long = ua if la >= lb else ub
    n_long = np.array([-u_long[1], u_long[0]])
    for end in (short[0:2], short[2:4]):
        if abs(float((end - long_[0:2]) @ n_long)) > cfg.merge_offset_m:
            return False
    ta = sorted([0.0, la])
    tb = sorted([float((b[0:2] - a[0:2]) @ ua), float((b[2:4] - a[0:2]) @ ua)])
    gap = max(tb[0] - ta[1], ta[0] - tb[1])
    return gap <= cfg.merge_gap_m


def _overlap_m(a: FloatArray, b: FloatArray) -> float:
    """Length [m] of the overlap of b's projection on a's direction with a (<= 0: none)."""
    da = a[2:4] - a[0:2]
    la = float(np.hypot(da[0], da[1]))
    if la < 1e-9:
        return 0.0
    u = da / la
    tb = sorted([float((b[0:2] - a[0:2]) @ u), float((b[2:4] - a[0:2]) @ u)])
    return min(la, tb[1]) - max(0.0, tb[0])


def fit_lines(points_xy: npt.ArrayLike, config: LineFitConfig | None = None) -> LineModel:
    """A line model (K, 4) [m] of the (N, 2) points [m]; see the module docstring."""
    cfg = config if config is not None else LineFitConfig()
    segs, _ = fit_lines_with_support(points_xy, cfg)
    return LineModel(segs)


def fit_lines_with_support(
    points_xy: npt.ArrayLike, config: LineFitConfig | None = None
) -> tuple[FloatArray, list[IntArray]]:
    """Like `fit_lines`, also returning for each segment the indices of the input rows it fits."""
    cfg = config if config is not None else LineFitConfig()
    finite = _finite_points(points_xy, cfg)
    if finite is None:
        return np.zeros((0, 4)), []
    pts, finite_rows = finite
    # Fit, then merge collinear neighbours until nothing changes.
    items = _fitted_groups(pts, cfg)
    for _ in range(_REASSIGN_ROUNDS):
        items = _reassign(pts, items, cfg)
    items = [_extend(pts, seg, g, cfg) for seg, g in items]
    while len(items) > 1 and _merge_one_pair(pts, items, cfg):
        pass
    kept = [(s, g) for s, g in items if float(np.hypot(*(s[2:4] - s[0:2]))) >= cfg.min_length_m]
    if not kept:
        return np.zeros((0, 4)), []
    kept.sort(key=lambda sg: (float(sg[0][0]), float(sg[0][1])))
    # (the extension keeps each segment's TLS line; it only moves the endpoints along it)
    segs = np.stack([s for s, _ in kept])
    return segs, [finite_rows[g] for _, g in kept]


def _finite_points(
    points_xy: npt.ArrayLike, cfg: LineFitConfig
) -> tuple[FloatArray, IntArray] | None:
    """The finite (M, 2) rows [m] of the input and their row indices; None when the input is
    not (N, 2) numbers or has fewer than `min_points` finite rows."""
    try:
        arr = np.asarray(points_xy, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] != 2:
        return None
    finite_rows = np.flatnonzero(np.all(np.isfinite(arr), axis=1))
    pts = arr[finite_rows]
    if pts.shape[0] < cfg.min_points:
        return None
    return pts, finite_rows


def _fitted_groups(pts: FloatArray, cfg: LineFitConfig) -> list[tuple[FloatArray, IntArray]]:
    """(segment, point indices) of every split cluster that fits a line well enough."""
    groups: list[IntArray] = []
    for comp in _components(pts, cfg.cluster_dist_m):
        groups.extend(_split(pts, comp, cfg, 0))
    items: list[tuple[FloatArray, IntArray]] = []
    for g in groups:
        g = np.unique(g)
        if g.shape[0] < cfg.min_points:
            continue
        seg, fit = _segment_from(pts[g])
        if fit.rms_m <= cfg.max_fit_rms_m:
            items.append((seg, g))
    return items


def _merge_one_pair(
    pts: FloatArray, items: list[tuple[FloatArray, IntArray]], cfg: LineFitConfig
) -> bool:
    """Merge (or de-duplicate) the first mergeable pair of `items` in place; False if none."""
    for i in range(len(items)):
        for j in range(i + 1, len(items)):
            if not _mergeable(items[i][0], items[j][0], cfg):
                continue
            g = np.union1d(items[i][1], items[j][1])
            seg, fit = _segment_from(pts[g])
            if fit.rms_m <= cfg.max_fit_rms_m:
                items[i] = _extend(pts, seg, g, cfg)
                del items[j]
            elif _overlap_m(items[i][0], items[j][0]) > 0:
                # Two overlapping near-duplicates that do not fit as one: keep the one
                # with more support (the other is usually a corner's stray points).
                worse = j if items[i][1].shape[0] >= items[j][1].shape[0] else i
                del items[worse]
            else:
                continue
            return True
    return False


# Tighter settings for a 1-deg laser scan (points ~0.1 m apart, ~1 cm noise).
LASER_LINE_FIT = LineFitConfig(
    cluster_dist_m=0.5, split_dist_m=0.08, max_fit_rms_m=0.04, merge_offset_m=0.1, merge_gap_m=0.5
)
