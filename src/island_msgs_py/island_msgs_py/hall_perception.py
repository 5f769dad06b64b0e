"""What one range scan says about the hallway around the robot (numpy only, no ROS).

Shared by the hall follower (island_sim) and route following by the map (island_mapping): both
keep to the middle of a hallway from the same wall fits, so "Go d" means the same thing to the
robot that recorded a strategy and to the robot that follows it.

`perceive(ranges_m, angles_rad, config)` gives the free range ahead, whether each side is open,
the perpendicular distance to each side's wall and, when both side walls fit as parallel
lines, the hallway's direction in the robot frame.

The robot's path is its width plus `path_margin_m` either side, narrowed where a side's wall
stands closer than that (a hallway or doorway barely wider than the robot): echoes of that wall
itself are then beside the path, not in it, down to `narrow_margin_m` of clearance.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from island_msgs_py.errors import InputError
from island_msgs_py.types import FloatArray

# A wall fit needs points spread at least this far along the robot's x axis [m].
MIN_FIT_SPAN_M = 0.2
# Echoes within this bearing of the heading count for `front_cone_m` [rad].
FRONT_CONE_RAD = math.radians(30.0)
# Largest angle [rad] between the left and right wall fits of one hallway.
PARALLEL_RAD = math.radians(8.0)


class PerceptionError(InputError):
    """A scan that cannot be perceived (the message names what is wrong)."""


@dataclass(frozen=True)
class HallPerceptionConfig:
    """The geometry of hallway perception (distances from the robot centre).

    Not a parameter set of its own: the hall follower's configuration carries these fields
    (`HallFollowerConfig.perception`), so the follower and route following agree.
    """

    robot_radius_m: float = 0.25  # radius of the robot's body [m]
    path_margin_m: float = 0.2  # echoes within radius + this of the path are in the way [m]
    side_half_angle_deg: float = 35.0  # echoes this near a side's perpendicular are its wall [deg]
    fit_tolerance_m: float = 0.08  # largest residual of one straight side wall [m]
    open_side_m: float = 2.5  # a side whose perpendicular range exceeds this is open [m]
    narrow_margin_m: float = 0.03  # least path margin beside a side wall closer than that [m]


def path_half_width_m(c: HallPerceptionConfig, side_m: float) -> float:
    """Half the width of the robot's path [m] when the nearer side wall is `side_m` from the
    robot centre: radius + path_margin_m, narrowed to keep that wall's echoes (within the fit
    tolerance) out of it, but never below radius + narrow_margin_m."""
    room = side_m - c.robot_radius_m - c.fit_tolerance_m
    return c.robot_radius_m + min(c.path_margin_m, max(c.narrow_margin_m, room))


@dataclass(frozen=True)
class Perception:
    """What one scan says about the surroundings (robot frame)."""

    front_m: float  # nearest obstacle in the robot's path or the front sector [m]
    front_free_m: float  # range straight ahead [m] (inf = nothing within range)
    left_open: bool
    right_open: bool
    left_dist_m: float  # perpendicular distance to the left wall fit [m], inf if none
    right_dist_m: float
    wall_angle_rad: float | None  # hallway direction in the robot frame from the wall fits
    # nearest obstacle in the robot's path heard within FRONT_CONE_RAD of the heading [m]: a
    # doorway's jamb beside the path, heard on an oblique transducer's axis, is not in it
    front_cone_m: float = math.inf


def fit_wall(pts: FloatArray, perp_m: float, tol_m: float) -> tuple[float, float | None]:
    """(distance [m], direction [rad] or None) of a side wall from points (K, 2) on that side.

    `perp_m` is the perpendicular transducer's distance (inf if it has no echo). A straight-line
    fit is used only when all points lie within `tol_m` of it (one wall, not a corner).
    """
    if pts.shape[0] >= 2 and float(np.ptp(pts[:, 0])) >= MIN_FIT_SPAN_M:
        # least-squares line y = a + b x (closed form: a handful of points per side)
        xm, ym = float(pts[:, 0].mean()), float(pts[:, 1].mean())
        dx, dy = pts[:, 0] - xm, pts[:, 1] - ym
        b = float(dx @ dy) / float(dx @ dx)
        a = ym - b * xm
        resid = np.abs(pts[:, 1] - (a + b * pts[:, 0])) / math.sqrt(1.0 + b * b)
        if float(np.max(resid)) <= tol_m:
            return float(abs(a) / math.sqrt(1.0 + b * b)), float(math.atan(b))
    if math.isfinite(perp_m):
        return perp_m, None
    if pts.shape[0] == 0:
        return math.inf, None
    return float(np.min(np.abs(pts[:, 1]))), None


@dataclass(frozen=True)
class _Bearings:
    """What a scan's perception needs of its bearings alone (computed once per ring).

    a: bearings wrapped to [-pi, pi] [rad]; cos_a, sin_a: their cosines and sines; ahead: the
    transducer nearest straight ahead; per side (left, right): the transducer nearest its
    perpendicular, |sin| of its bearing, and which transducers lie within the side's sector.
    """

    a: FloatArray
    cos_a: FloatArray
    sin_a: FloatArray
    ahead: int
    perp: tuple[int, int]
    perp_sin: tuple[float, float]
    in_sector: tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_]]


@functools.lru_cache(maxsize=8)
def _bearings(raw: bytes, side_half_angle_deg: float) -> _Bearings:
    """`_Bearings` of the float64 bearings [rad] whose bytes are `raw` (checked finite)."""
    a = np.frombuffer(raw, dtype=np.float64)
    a = np.arctan2(np.sin(a), np.cos(a))
    perp, perp_sin, in_sector = [], [], []
    for sign in (1.0, -1.0):
        d = a - sign * math.pi / 2.0
        off = np.abs(np.arctan2(np.sin(d), np.cos(d)))
        k = int(np.argmin(off))
        perp.append(k)
        perp_sin.append(abs(math.sin(a[k])))
        in_sector.append(off <= math.radians(side_half_angle_deg))
    cos_a, sin_a = np.cos(a), np.sin(a)
    for arr in (a, cos_a, sin_a, *in_sector):
        arr.setflags(write=False)  # shared by every later scan of the ring
    return _Bearings(a, cos_a, sin_a, int(np.argmin(np.abs(a))), (perp[0], perp[1]),
                     (perp_sin[0], perp_sin[1]), (in_sector[0], in_sector[1]))


def perceive(
    ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike, config: HallPerceptionConfig
) -> Perception:
    """Summarize one scan (ranges from the robot centre [m], bearings [rad], robot frame)."""
    c = config
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    raw = np.ascontiguousarray(angles_rad, dtype=np.float64).reshape(-1)
    if r.shape != raw.shape or r.size == 0:
        raise PerceptionError(
            f"update: ranges ({r.size}) and angles ({raw.size}) must be non-empty and match"
        )
    if not np.all(np.isfinite(raw)):
        raise PerceptionError("update: angles_rad contains a NaN or infinite bearing")
    b = _bearings(raw.tobytes(), float(c.side_half_angle_deg))
    r = np.where(np.isnan(r) | (r <= 0), np.inf, r)
    ok = np.isfinite(r)
    rr = np.where(ok, r, 0.0)
    # Echo points; 0 (not NaN) where there is no echo, and every use below is masked by `ok`.
    x = rr * b.cos_a
    y = rr * b.sin_a

    def side(k: int) -> tuple[bool, float, float | None]:
        perp_m = float(r[b.perp[k]] * b.perp_sin[k])
        is_open = not perp_m <= c.open_side_m
        sel = ok & b.in_sector[k]
        sel &= np.abs(y) <= c.open_side_m
        pts = np.stack([x[sel], y[sel]], axis=1)
        dist, ang = fit_wall(pts, math.inf if is_open else perp_m, c.fit_tolerance_m)
        return is_open, dist, ang

    l_open, l_dist, l_ang = side(0)
    r_open, r_dist, r_ang = side(1)
    front_free = float(r[b.ahead])
    front = cone = front_free
    in_path = ok & (x > 0)
    in_path &= np.abs(y) <= path_half_width_m(c, min(l_dist, r_dist))
    if np.any(in_path):
        front = min(front, float(np.min(x[in_path])))
        ahead = in_path & (np.abs(b.a) <= FRONT_CONE_RAD)
        if np.any(ahead):
            cone = min(cone, float(np.min(x[ahead])))
    wall_angle = None  # only two parallel walls are trusted as a hallway's direction
    if l_ang is not None and r_ang is not None and abs(l_ang - r_ang) <= PARALLEL_RAD:
        wall_angle = 0.5 * (l_ang + r_ang)
    return Perception(front, front_free, l_open, r_open, l_dist, r_dist, wall_angle, cone)
