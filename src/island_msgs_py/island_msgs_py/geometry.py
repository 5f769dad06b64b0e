"""Planar geometry on numpy arrays (numpy only): the one copy the whole project uses.

Conventions (those of `island_msgs_py.types`): poses are rows (x [m], y [m], theta [rad]);
segments are rows (x1, y1, x2, y2) [m]; points are rows (x, y) [m]. A pose given "in the frame
of" another is composed with it: a (+) b is b's pose, given in a's frame, in a's parent frame.

- angles: `wrap_angles` (element-wise; `types.wrap_angle` is the scalar one);
- pose algebra on (N, 3) arrays: `compose_poses`, `relative_poses`, `inverse_poses`;
- points and frames: `from_frame`, `to_frame`, `ranges_to_points` (a range scan -> points);
- points and segments: `point_segment_distance`, `closest_on_segments`,
  `closest_on_segment_rows`, `clearance_m`;
- polylines: `douglas_peucker` (traced walls of imported worlds, the way an edge drove).

Each formula is written once here; the order of the floating-point operations is part of the
contract (the offline exploration is reproduced bit for bit), so change none without measuring.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from island_msgs_py.errors import InputError
from island_msgs_py.types import FloatArray, Pose2D

IntArray = npt.NDArray[np.int64]

# Point x segment pairs evaluated at once by `clearance_m` (bounds its temporaries).
_CLEARANCE_PAIRS = 1 << 20


class GeometryError(InputError):
    """An array of the wrong shape (the message names the argument and the shape)."""


# ----------------------------------------------------------------------------- angles


def wrap_angles(theta_rad: npt.ArrayLike) -> FloatArray:
    """Angles [rad] wrapped element-wise to [-pi, pi] as atan2(sin, cos).

    Unlike the scalar `types.wrap_angle`, an angle that lands on -pi exactly stays -pi.
    """
    a = np.asarray(theta_rad, dtype=np.float64)
    return np.asarray(np.arctan2(np.sin(a), np.cos(a)), dtype=np.float64)


def unwind_sign(net_turn_rad: float, enabled: bool = True) -> float:
    """+1 (turn left) or -1 (right): the way a full turn in place undoes the net turn so far
    [rad] (always +1 when not enabled). A wheelbase error scales every odometric rotation by
    the same fraction, so turns that cancel keep its heading error from growing."""
    return -1.0 if enabled and net_turn_rad > 0.0 else 1.0


# ----------------------------------------------------------------------------- poses


def _as_poses(a: npt.ArrayLike, name: str) -> FloatArray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise GeometryError(f"{name}: expected (N, 3) poses (x, y, theta), got {arr.shape}")
    return arr


def compose_poses(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """a (+) b row by row: b given in the frame of a, returned in a's parent frame; (N, 3).

    Rows broadcast (one pose against many); a single (3,) pose counts as one row.
    """
    pa, pb = _as_poses(a, "a"), _as_poses(b, "b")
    c, s = np.cos(pa[:, 2]), np.sin(pa[:, 2])
    return np.stack(
        [
            pa[:, 0] + c * pb[:, 0] - s * pb[:, 1],
            pa[:, 1] + s * pb[:, 0] + c * pb[:, 1],
            wrap_angles(pa[:, 2] + pb[:, 2]),
        ],
        axis=1,
    )


def relative_poses(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """Poses b expressed in the frames of poses a (a^-1 (+) b), row by row; (N, 3)."""
    pa, pb = _as_poses(a, "a"), _as_poses(b, "b")
    c, s = np.cos(pa[:, 2]), np.sin(pa[:, 2])
    dx, dy = pb[:, 0] - pa[:, 0], pb[:, 1] - pa[:, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angles(pb[:, 2] - pa[:, 2])], axis=1)


def inverse_poses(a: npt.ArrayLike) -> FloatArray:
    """a^-1 row by row: the parent frame's origin seen from each pose; (N, 3)."""
    pa = _as_poses(a, "a")
    c, s = np.cos(pa[:, 2]), np.sin(pa[:, 2])
    x, y = pa[:, 0], pa[:, 1]
    return np.stack([-c * x - s * y, s * x - c * y, wrap_angles(-pa[:, 2])], axis=1)


# ----------------------------------------------------------------------------- points and frames


def _frame(frame: Pose2D | npt.ArrayLike) -> tuple[float, float, float]:
    if isinstance(frame, Pose2D):
        return frame.x, frame.y, frame.theta
    f = np.asarray(frame, dtype=np.float64).reshape(-1)
    if f.shape != (3,):
        raise GeometryError(f"frame: expected a pose (x, y, theta), got {f.shape[0]} values")
    return float(f[0]), float(f[1]), float(f[2])


def _as_points(points: npt.ArrayLike) -> FloatArray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 2:
        p = p.reshape(-1, 2)
    return p


def from_frame(points: npt.ArrayLike, frame: Pose2D | npt.ArrayLike) -> FloatArray:
    """(K, 2) points [m] given in `frame` (a Pose2D or (x, y, theta)), returned in its parent."""
    p = _as_points(points)
    x, y, th = _frame(frame)
    c, s = math.cos(th), math.sin(th)
    return np.stack([p[:, 0] * c - p[:, 1] * s + x, p[:, 0] * s + p[:, 1] * c + y], axis=1)


def to_frame(points: npt.ArrayLike, frame: Pose2D | npt.ArrayLike) -> FloatArray:
    """(K, 2) points [m] of the parent frame expressed in `frame` (the inverse of from_frame)."""
    p = _as_points(points)
    x, y, th = _frame(frame)
    c, s = math.cos(th), math.sin(th)
    d = p - np.array([x, y])
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)


def ranges_to_points(
    ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike, pose: Pose2D | None = None
) -> FloatArray:
    """(K, 2) points [m] of the finite ranges (from the sensor centre) along `angles_rad`.

    Drops inf/NaN readings. Without `pose` the points are in the sensor (robot) frame; with it,
    the bearings turn by pose.theta and the points are in the pose's parent frame (odometry,
    world).
    """
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if r.shape != a.shape:
        raise GeometryError(f"ranges_to_points: {r.shape[0]} ranges but {a.shape[0]} angles")
    ok = np.isfinite(r) & np.isfinite(a)
    r, a = r[ok], a[ok]
    if pose is not None:
        a = a + pose.theta
        return np.stack([pose.x + r * np.cos(a), pose.y + r * np.sin(a)], axis=1)
    return np.stack([r * np.cos(a), r * np.sin(a)], axis=1)


# ----------------------------------------------------------------------------- points and segments


def point_segment_distance(points: FloatArray, segments: FloatArray) -> FloatArray:
    """(N, K) Euclidean distances [m] from (N, 2) points to (K, 4) segments."""
    a = segments[None, :, 0:2]
    d = segments[None, :, 2:4] - a
    rel = points[:, None, :] - a
    dd = np.sum(d * d, axis=2)
    t = np.clip(np.sum(rel * d, axis=2) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    diff = rel - t[:, :, None] * d
    return np.asarray(np.hypot(diff[:, :, 0], diff[:, :, 1]))


def closest_on_segments(
    points: FloatArray, segments: FloatArray
) -> tuple[IntArray, FloatArray, FloatArray]:
    """For (N, 2) points: index of the nearest of (K, 4) segments, the closest points (N, 2) on
    them [m] and the distances (N,) [m]. Ties go to the lowest segment index."""
    a = segments[None, :, 0:2]
    d = segments[None, :, 2:4] - a
    rel = points[:, None, :] - a
    dd = np.sum(d * d, axis=2)
    t = np.clip(np.sum(rel * d, axis=2) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    foot = a + t[:, :, None] * d
    diff = points[:, None, :] - foot
    dist2 = np.sum(diff * diff, axis=2)
    best = np.argmin(dist2, axis=1)
    rows = np.arange(points.shape[0])
    return best.astype(np.int64), foot[rows, best], np.sqrt(dist2[rows, best])


def closest_on_segment_rows(
    points: FloatArray, segments: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Row by row: the closest point (N, 2) [m] of segment i (N, 4) to point i (N, 2), and the
    distance (N,) [m]."""
    a, d = segments[:, 0:2], segments[:, 2:4] - segments[:, 0:2]
    rel = points - a
    dd = np.sum(d * d, axis=1)
    t = np.clip(np.sum(rel * d, axis=1) / np.where(dd > 0, dd, 1.0), 0.0, 1.0)
    foot = a + t[:, None] * d
    return foot, np.asarray(np.hypot(points[:, 0] - foot[:, 0], points[:, 1] - foot[:, 1]))


def clearance_m(points: npt.ArrayLike, segments: FloatArray) -> FloatArray:
    """(N,) distance [m] from each of (N, 2) points to the nearest of (K, 4) segments.

    The clearance of a disk centred there is this minus its radius; inf without segments.
    Computed in chunks of points, so any number of points x walls fits in memory.
    """
    pts = _as_points(points)
    out = np.full(pts.shape[0], np.inf)
    if segments.shape[0] == 0:
        return out
    p = segments[:, 0:2]
    d = segments[:, 2:4] - p
    dd = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    step = max(1, _CLEARANCE_PAIRS // segments.shape[0])
    for s in range(0, pts.shape[0], step):
        wx = pts[s : s + step, 0:1] - p[None, :, 0]
        wy = pts[s : s + step, 1:2] - p[None, :, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(dd > 0, (wx * d[:, 0] + wy * d[:, 1]) / dd, 0.0)
        t = np.clip(t, 0.0, 1.0)
        ex, ey = wx - t * d[:, 0], wy - t * d[:, 1]
        out[s : s + step] = np.sqrt(np.min(ex * ex + ey * ey, axis=1))
    return out


def douglas_peucker(pts: FloatArray, tol: float) -> FloatArray:
    """Douglas-Peucker simplification of an open polyline (N, 2): the points that keep every
    point within tol of the simplified line (the same unit), both ends always."""
    n = pts.shape[0]
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        i0, i1 = stack.pop()
        if i1 - i0 < 2:
            continue
        mid = pts[i0 + 1 : i1]
        chord = np.broadcast_to(np.concatenate([pts[i0], pts[i1]]), (mid.shape[0], 4))
        foot, _ = closest_on_segment_rows(mid, chord)
        # Lattice points tie at whole-pixel distances: this rounding (norm of p - foot) decides
        # them as the traced worlds were made (Willow: 3550 walls).
        d = np.linalg.norm(mid - foot, axis=1)
        k = int(np.argmax(d))
        if d[k] > tol:
            km = i0 + 1 + k
            keep[km] = True
            stack.append((i0, km))
            stack.append((km, i1))
    return pts[keep]
