"""Through a doorway no lane shows: find its wall and jambs in a look, stand before it, pass.

A 0.74 m doorway leaves a 0.5 m robot 0.12 m a side, and the ring's 25 deg cones close it for
a lane (`exits.free_lanes`): a cone reports the nearest echo anywhere in it, so from a metre or
two a reading passes the doorway only when the whole cone does. Driven along the exit's heading
the robot meets a jamb or the wall beside the door (a heading a few degrees off misses 0.12 m).

So (`pass_doorway`): the robot turns `sweep_deg` either way of the exit keeping every reading
as the nearest range per bearing bin (a `Profile`; where that shows no doorway, again after
driving along the exit until an echo within 30 deg of its heading is `approach_m` near: a
doorway straight ahead is seen through until its jambs are beside the robot, so the sides
stop the approach too), and fits the wall the exit meets first (`fit_wall`: a flat
wall at distance p and normal n gives a specular ring p / cos(phi), phi the least incidence of
a cone's rays, and no echo beyond `echo_deg`). Bearings where that wall must echo but the
sonar sees `see_through_m` beyond it are a doorway (`find_doorway`); a run's edge beside an
echo of the wall is a jamb (half a cone outside the first reading that passes), and the middle
is between both jambs (or `half_width_m` from the one seen). The robot then stands
`standoff_m` before the middle on the wall's normal, looks again (the doorway is wide in the
cones there) until the middle settles, and drives through it and `through_m` on. With no wall
or doorway found it stays where the look left it. Odometry frame throughout [m, rad].
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np
from island_msgs_py.geometry import wrap_angles
from island_msgs_py.types import FloatArray, Pose2D, wrap_angle

from island_mapping.core.explore.config import DoorwayConfig
from island_mapping.core.explore.exits import _linear_runs
from island_mapping.core.route import Command, Drive, go_to, rotate_to, step

_FRONT_RAD = math.radians(30.0)  # echoes within this of the heading stop the approach [rad]
# ... and within this, at _BESIDE_FRACTION of approach_m (a doorway straight ahead is seen
# through by the front cone until its jambs are beside the robot) [rad, -]
_BESIDE_RAD, _BESIDE_FRACTION = math.radians(70.0), 0.6
_BEAM_RAD = math.radians(60.0)  # transducers within this of the heading fill the profile [rad]
_BIN_RAD = math.radians(2.0)  # profile bin [rad]
_APPROACH_MPS = 0.3
_SWEEP_RADPS = 0.4
_SWEEP_GAIN_PER_S = 2.0
_SWEEP_TOL_RAD = math.radians(1.0)
_FIT_STEP_RAD = math.radians(1.0)  # normals tried [rad]
_FIT_SPAN_DEG = 60.0  # first look: normals within this of the heading [deg]
_FIT_FAR_M = (0.3, 3.0)  # first look, where the departure starts: walls this near [m]
_FIT_NEAR_M = (0.3, 1.6)  # ... and after an approach [m]
_REFINE_SPAN_DEG = 15.0  # looks at the stand-off: the normal within this of the last [deg]
_REFINE_BAND_M = 0.3  # ... and the wall within this of standoff_m [m]
_REFINE_SWEEP = 0.5  # ... turning this share of sweep_deg (plus 2.5 deg) either way [-]
_REFINE_WITHIN_DEG = 30.0  # ... the middle within this of the normal [deg]
_RELOOK_BACK_M = 1.0  # a wall with no doorway seen is looked at again from this far [m]
_MIN_USED = 8  # bins a wall's normal must be seen in [-]
_LOCAL_MAX_BINS = 5  # a wall is a local maximum of inliers over this many normals each side
_RELOOK_RAD = math.radians(45.0)  # a wall looked at again faces the exit this near [rad]
_MIN_COS = 0.26  # a wall met at more than ~75 deg from its normal is not met [-]
_WIDTH_M = (0.5, 2.0)  # a doorway between two jambs seen is this wide [m]
_CLEAR_AHEAD_M = 0.45  # past the doorway, an echo this near ahead ends the drive [m]
_PAST_M = 0.3  # ... once this far beyond the doorway [m]


@dataclass(frozen=True)
class Profile:
    """A look: per bearing bin (relative to ref_rad), the nearest range read [m] (NaN: no
    reading in the bin; inf: no echo), and the pose `at` where the look ended (odometry)."""

    ref_rad: float
    bearings_rad: FloatArray
    ranges_m: FloatArray
    at: Pose2D


@dataclass(frozen=True)
class Wall:
    """A wall line in a profile: its normal toward it (relative to the profile's ref_rad),
    its distance from the look's pose, and the bins it explains."""

    normal_rad: float
    distance_m: float
    inliers: int


@dataclass(frozen=True)
class Doorway:
    """A doorway's middle and its wall's normal (pointing through it), odometry frame."""

    x_m: float
    y_m: float
    normal_rad: float


def _front_m(d: Drive, half_rad: float = _FRONT_RAD) -> float:
    """The nearest echo within half_rad of the heading [m] (inf: none)."""
    r = np.asarray(d.sense.ranges_m, dtype=np.float64)
    near = np.abs(wrap_angles(d.sense.angles_rad)) <= half_rad
    return float(np.min(r[near])) if np.any(near) else math.inf


def approach(d: Drive, cfg: DoorwayConfig, max_m: float) -> Generator[Command, None, bool]:
    """Straight on until an echo in the front cone is approach_m near (True) or max_m [m] was
    driven (False); a contact also ends it (True)."""
    start = d.sense.odom
    while math.hypot(d.sense.odom.x - start.x, d.sense.odom.y - start.y) < max_m:
        near = _front_m(d) <= cfg.approach_m or (
            _front_m(d, _BESIDE_RAD) <= _BESIDE_FRACTION * cfg.approach_m)
        if near or (yield from step(d, _APPROACH_MPS, 0.0)):
            return True
    return False


def sweep(d: Drive, heading_rad: float, half_deg: float) -> Generator[Command, None, Profile]:
    """Turn to heading -half_deg, then to +half_deg, binning every reading of the transducers
    within 60 deg of the robot's heading by its bearing relative to heading_rad."""
    bearings: list[float] = []
    ranges: list[float] = []

    def keep() -> None:
        a = np.asarray(d.sense.angles_rad, dtype=np.float64)
        front = np.abs(wrap_angles(a)) <= _BEAM_RAD
        bearings.extend(wrap_angles(d.sense.odom.theta + a[front] - heading_rad).tolist())
        ranges.extend(np.asarray(d.sense.ranges_m, dtype=np.float64)[front].tolist())

    keep()
    half = math.radians(half_deg)
    for target in (heading_rad - half, heading_rad + half):
        while abs(err := wrap_angle(target - d.sense.odom.theta)) > _SWEEP_TOL_RAD:
            w = float(np.clip(_SWEEP_GAIN_PER_S * err, -_SWEEP_RADPS, _SWEEP_RADPS))
            yield from step(d, 0.0, w)
            keep()
    span = half + _BEAM_RAD
    nb = max(1, round(2.0 * span / _BIN_RAD))
    edges = np.linspace(-span, span, nb + 1)
    k = np.clip(np.digitize(np.asarray(bearings), edges) - 1, 0, nb - 1)
    mins = np.full(nb, np.nan)
    np.fmin.at(mins, k, np.asarray(ranges))
    return Profile(heading_rad, 0.5 * (edges[:-1] + edges[1:]), mins, d.sense.odom)


def _incidence(p: Profile, normal_rad: float, cfg: DoorwayConfig) -> FloatArray:
    """Per bin, the least angle between a ray of its cone and the wall normal [rad]."""
    rays = np.radians(np.linspace(-cfg.cone_half_deg, cfg.cone_half_deg, cfg.cone_rays))
    return np.asarray(np.min(np.abs(p.bearings_rad[:, None] + rays[None, :] - normal_rad),
                             axis=1))


def _wall_at(p: Profile, n: float, near_m: tuple[float, float], cfg: DoorwayConfig
             ) -> tuple[int, float]:
    """(inliers, distance) of the wall with normal n [rad] best explaining the profile."""
    phi = _incidence(p, n, cfg)
    use = np.isfinite(p.ranges_m) & (phi <= math.radians(cfg.echo_deg))
    if np.count_nonzero(use) < _MIN_USED:
        return 0, 0.0
    dist = float(np.percentile((p.ranges_m * np.cos(phi))[use], 25))
    if not near_m[0] <= dist <= near_m[1]:
        return 0, 0.0
    pred = dist / np.cos(phi[use])
    return int(np.count_nonzero(np.abs(p.ranges_m[use] - pred) < 0.03 + 0.03 * pred)), dist


def fit_wall(p: Profile, around_rad: float, span_deg: float, near_m: tuple[float, float],
             cfg: DoorwayConfig) -> Wall | None:
    """Of the walls the profile shows (local maxima of inliers over normals within span_deg of
    around_rad, at least min_inliers, at a distance within near_m), the one the ray along
    around_rad meets first; None if none."""
    span = math.radians(span_deg)
    normals = np.arange(around_rad - span, around_rad + span + 1e-9, _FIT_STEP_RAD)
    fits = [_wall_at(p, float(n), near_m, cfg) for n in normals]
    scores = np.array([f[0] for f in fits])
    best: tuple[float, Wall] | None = None
    for i, (score, dist) in enumerate(fits):
        lo, hi = max(0, i - _LOCAL_MAX_BINS), i + _LOCAL_MAX_BINS + 1
        if score < cfg.min_inliers or score < scores[lo:hi].max():
            continue
        c = math.cos(normals[i] - around_rad)
        meet = dist / c if c > _MIN_COS else math.inf
        if best is None or meet < best[0]:
            best = (meet, Wall(float(normals[i]), dist, score))
    return None if best is None else best[1]


def find_doorway(p: Profile, wall: Wall, within_rad: float, cfg: DoorwayConfig
                 ) -> Doorway | None:
    """The doorway in `wall` whose middle lies nearest the profile's heading (within
    within_rad of it): module docstring; None if none."""
    n = wall.normal_rad
    phi = _incidence(p, n, cfg)
    pred = wall.distance_m / np.cos(np.minimum(phi, 0.5 * math.pi - 1e-3))
    must = (phi <= math.radians(cfg.echo_deg)) & ~np.isnan(p.ranges_m)
    through = must & (p.ranges_m > pred + cfg.see_through_m)
    echo = must & ~through
    o = p.at
    along = np.array([-math.sin(p.ref_rad + n), math.cos(p.ref_rad + n)])
    edge = 0.5 * _BIN_RAD + math.radians(cfg.cone_half_deg)

    def on_wall(b: float) -> FloatArray:
        r = wall.distance_m / max(math.cos(b - n), _MIN_COS)
        return np.array([o.x + r * math.cos(p.ref_rad + b), o.y + r * math.sin(p.ref_rad + b)])

    best: tuple[float, FloatArray] | None = None
    for lo, length in _linear_runs(through):
        hi = lo + length - 1
        left = on_wall(p.bearings_rad[lo] - edge) if lo > 0 and echo[lo - 1] else None
        right = (on_wall(p.bearings_rad[hi] + edge) if hi + 1 < len(echo) and echo[hi + 1]
                 else None)
        if left is not None and right is not None:
            if not _WIDTH_M[0] <= float(np.hypot(*(right - left))) <= _WIDTH_M[1]:
                continue
            mid = 0.5 * (left + right)
        elif left is not None:
            mid = left + cfg.half_width_m * along
        elif right is not None:
            mid = right - cfg.half_width_m * along
        else:
            continue
        off = abs(wrap_angle(math.atan2(mid[1] - o.y, mid[0] - o.x) - p.ref_rad))
        if off <= within_rad and (best is None or off < best[0]):
            best = (off, mid)
    if best is None:
        return None
    return Doorway(float(best[1][0]), float(best[1][1]), wrap_angle(p.ref_rad + n))


def _look(p: Profile, span_deg: float, near_m: tuple[float, float], within_deg: float,
          cfg: DoorwayConfig) -> tuple[Wall | None, Doorway | None]:
    wall = fit_wall(p, 0.0, span_deg, near_m, cfg)
    if wall is None:
        return None, None
    return wall, find_doorway(p, wall, math.radians(within_deg), cfg)


def _first_look(d: Drive, heading_rad: float, cfg: DoorwayConfig, near_m: tuple[float, float]
                ) -> Generator[Command, None, Doorway | None]:
    """The doorway the exit leads to, in a wall within near_m: a look from here; a wall with
    none seen, facing the exit (within 45 deg) and met by it within near_m, is looked at
    again from a metre before where the exit meets it, facing it."""
    p = yield from sweep(d, heading_rad, cfg.sweep_deg)
    wall, door = _look(p, _FIT_SPAN_DEG, near_m, cfg.sweep_deg, cfg)
    if door is not None or wall is None or abs(wall.normal_rad) > _RELOOK_RAD:
        return door
    meet = wall.distance_m / math.cos(wall.normal_rad)  # along the heading [m]
    if meet > near_m[1]:
        return None
    nw = wrap_angle(heading_rad + wall.normal_rad)
    back = _RELOOK_BACK_M
    x = p.at.x + meet * math.cos(heading_rad) - back * math.cos(nw)
    y = p.at.y + meet * math.sin(heading_rad) - back * math.sin(nw)
    yield from go_to(d, Pose2D(x, y, nw))
    p = yield from sweep(d, nw, cfg.sweep_deg)
    return _look(p, _REFINE_SPAN_DEG, (back - _REFINE_BAND_M, back + 2 * _REFINE_BAND_M),
                 cfg.sweep_deg, cfg)[1]


def _through(d: Drive, door: Doorway, beyond_m: float) -> Generator[Command, None, None]:
    """From where the robot stands, straight through the doorway's middle and beyond_m on;
    past it, an echo close ahead ends the drive."""
    o = d.sense.odom
    aim = math.atan2(door.y_m - o.y, door.x_m - o.x)
    to_door = math.hypot(door.x_m - o.x, door.y_m - o.y)
    yield from rotate_to(d, aim)
    dist = to_door + beyond_m
    target = Pose2D(o.x + dist * math.cos(aim), o.y + dist * math.sin(aim), aim)
    for cmd in go_to(d, target):
        gone = math.hypot(d.sense.odom.x - o.x, d.sense.odom.y - o.y)
        if cmd[0] > 0.0 and gone > to_door + _PAST_M and _front_m(d, 0.5 * _FRONT_RAD) < (
                _CLEAR_AHEAD_M):
            break
        yield cmd
    yield (0.0, 0.0)


def pass_doorway(d: Drive, heading_rad: float, cfg: DoorwayConfig, approach_max_m: float,
                 through_m: float) -> Generator[Command, None, bool]:
    """Pass the doorway an exit along odometric heading_rad leads to (module docstring): True
    when one was found and driven through, False when the approach met no wall within
    approach_max_m [m] or no doorway was seen (the robot stays where that left it)."""
    yield from rotate_to(d, heading_rad)
    door = yield from _first_look(d, heading_rad, cfg, _FIT_FAR_M)
    if door is None:
        if not (yield from approach(d, cfg, approach_max_m)):
            return False
        door = yield from _first_look(d, heading_rad, cfg, _FIT_NEAR_M)
    if door is None:
        return False
    seen = [door]  # the middle is the mean of every look's
    for _ in range(cfg.refines):
        stand = Pose2D(door.x_m - cfg.standoff_m * math.cos(door.normal_rad),
                       door.y_m - cfg.standoff_m * math.sin(door.normal_rad), door.normal_rad)
        yield from go_to(d, stand)
        p = yield from sweep(d, door.normal_rad, _REFINE_SWEEP * cfg.sweep_deg + 2.5)
        band = (cfg.standoff_m - _REFINE_BAND_M, cfg.standoff_m + _REFINE_BAND_M)
        again = _look(p, _REFINE_SPAN_DEG, band, _REFINE_WITHIN_DEG, cfg)[1]
        if again is None:
            break
        moved = math.hypot(again.x_m - door.x_m, again.y_m - door.y_m)
        seen.append(again)
        door = Doorway(float(np.mean([s.x_m for s in seen])),
                       float(np.mean([s.y_m for s in seen])), again.normal_rad)
        if moved < cfg.settle_m:
            break
    yield from _through(d, door, through_m)
    return True
