"""How the builder drives when it has the robot: turns in place, straight drives along a line,
onto an origin, and full-circle looks. Each helper turns a pose (the robot in the frame it drives
in) into a twist (v [m/s], w [rad/s]), or None when there is nothing left to do. No decisions:
which leg, which origin and when to stop looking are the machine's.

Also the strategy steps (`Rot a, Go d, Rot b`) that record a drive onto an origin on an edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from island_msgs_py.types import (
    FloatArray,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
    wrap_angle,
)

from island_mapping.core.builder.config import StarConfig

Twist = tuple[float, float]
"""(v [m/s], w [rad/s])."""

STOP: Twist = (0.0, 0.0)

# Leg bearings in the origin frame: ahead, left, behind, right [rad].
LEG_BEARINGS_RAD = (0.0, 0.5 * math.pi, math.pi, -0.5 * math.pi)
# The same legs turning right: ahead, right, behind, left.
LEG_BEARINGS_RIGHT_RAD = (0.0, -0.5 * math.pi, math.pi, 0.5 * math.pi)

# Turn in place first when the way to a target is this far off the heading [rad].
_AIM_TOL_RAD = math.radians(10.0)
# A target this near [m] and behind the robot is reached by reversing onto it.
_REVERSE_ONTO_M = 0.3
# Steering gain onto a leg's line per metre of lateral offset [rad/m].
_LATERAL_GAIN_RAD_PER_M = 1.5
# Speed per metre left to go near a target (slows down onto it) [1/s].
_APPROACH_GAIN_PER_S = 2.0
# Docking stops short of an echo nearer than this, even with a smaller star clearance [m].
_DOCK_CLEARANCE_M = 0.5


class LegPhase(StrEnum):
    TURN = "turn"  # rotate to the leg's bearing
    OUT = "out"  # drive forward to the corner
    BACK = "back"  # reverse to the centre


class LookPhase(StrEnum):
    GO = "go"  # drive to the (estimated) origin
    ALIGN = "align"  # turn to the origin's heading
    LOOK = "look"  # turn a full circle collecting scans, then localize


@dataclass
class Look:
    """Go onto an origin, align with it, turn a full circle collecting scans (dock, probe)."""

    phase: LookPhase = field(default=LookPhase.GO, kw_only=True)
    turned_rad: float = field(default=0.0, kw_only=True)
    prev_theta: float = field(default=0.0, kw_only=True)
    points: list[FloatArray] = field(default_factory=list, kw_only=True)  # odometry frame [m]
    turn_sign: float = field(default=1.0, kw_only=True)  # +1 the circle turns left, -1 right


class StallWatch:
    """Has a drive made no progress (odometry within stall_m and stall_rad) for after_s? Feed
    `update` once per scan; it answers True once per stall (and starts over)."""

    def __init__(self, after_s: float, stall_m: float = 0.02,
                 stall_rad: float = math.radians(2.0)) -> None:
        self.after_s, self.stall_m, self.stall_rad = after_s, stall_m, stall_rad
        self._since: tuple[float, Pose2D] | None = None

    def update(self, t_s: float, odom: Pose2D, driving: bool) -> bool:
        """The robot at odom at t_s [s]; driving: a drive that should progress is under way."""
        if not driving or self.after_s <= 0:
            self._since = None
            return False
        s = self._since
        if s is None or math.hypot(odom.x - s[1].x, odom.y - s[1].y) > self.stall_m or abs(
            wrap_angle(odom.theta - s[1].theta)
        ) > self.stall_rad:
            self._since = (t_s, odom)
            return False
        if t_s - s[0] >= self.after_s:
            self._since = None
            return True
        return False


def turn_rate(err_rad: float, sc: StarConfig) -> float:
    """The turn rate [rad/s] that closes a heading error [rad] (proportional, clipped)."""
    return float(
        np.clip(sc.heading_gain_per_s * err_rad, -sc.turn_rate_radps, sc.turn_rate_radps)
    )


def turn_to(pose: Pose2D, heading_rad: float, sc: StarConfig) -> Twist | None:
    """(0, w) toward the heading (in pose's frame), or None when already there."""
    err = wrap_angle(heading_rad - pose.theta)
    if abs(err) <= math.radians(sc.heading_tol_deg):
        return None
    w = float(np.clip(sc.heading_gain_per_s * err, -sc.turn_rate_radps, sc.turn_rate_radps))
    return 0.0, w


def drive_line(pose: Pose2D, bearing: float, lateral_m: float, v: float,
               sc: StarConfig) -> Twist:
    """Drive along the line through the frame's origin at `bearing` (forward, v > 0, or
    reversing), holding heading, `lateral_m` left of the line now."""
    heading_err = wrap_angle(bearing - pose.theta)
    if abs(heading_err) > math.radians(sc.drive_heading_err_deg):
        return 0.0, turn_rate(heading_err, sc)
    # Steer back onto the line: a lateral offset to the left calls for a right turn going
    # forward and a left turn reversing.
    steer = heading_err - math.copysign(1.0, v) * _LATERAL_GAIN_RAD_PER_M * lateral_m
    w = float(np.clip(sc.heading_gain_per_s * steer, -sc.turn_rate_radps, sc.turn_rate_radps))
    return v, w


def along_line(pose: Pose2D, bearing: float) -> tuple[float, float]:
    """(how far along, how far left of) the line through the origin at `bearing` [m]."""
    u = np.array([math.cos(bearing), math.sin(bearing)])
    along = float(u @ np.array([pose.x, pose.y]))
    lateral = float(np.array([-u[1], u[0]]) @ np.array([pose.x, pose.y]))
    return along, lateral


def return_to_centre(pose: Pose2D, sc: StarConfig, turn_only: bool = False) -> Twist | None:
    """Back to the frame's origin along the current heading's line (forward or reversing),
    then face heading 0; None when there. turn_only: only face heading 0 where it stands."""
    dist = math.hypot(pose.x, pose.y)
    if dist > sc.position_tol_m and not turn_only:
        to_c = math.atan2(-pose.y, -pose.x)
        err = wrap_angle(to_c - pose.theta)
        speed = min(sc.speed_mps, _APPROACH_GAIN_PER_S * dist)
        if abs(err) < 0.5 * math.pi:
            if abs(err) > _AIM_TOL_RAD:
                return turn_to(pose, to_c, sc) or STOP
            return drive_line(pose, to_c, 0.0, speed, sc)
        back = wrap_angle(to_c + math.pi)
        if abs(wrap_angle(back - pose.theta)) > _AIM_TOL_RAD:
            return turn_to(pose, back, sc) or STOP
        return drive_line(pose, back, 0.0, -speed, sc)
    return turn_to(pose, 0.0, sc)


def drive_to_origin(rel: Pose2D, ahead_free_m: float, sc: StarConfig) -> Twist | None:
    """(v, w) toward the origin of the frame `rel` is given in (forward, or reversing when it
    is just behind), or None when there (or when the way ahead is blocked: nearest echo
    ahead_free_m [m])."""
    dist = math.hypot(rel.x, rel.y)
    if dist <= sc.position_tol_m:
        return None
    to_c = math.atan2(-rel.y, -rel.x)
    err = wrap_angle(to_c - rel.theta)
    if abs(err) > 0.5 * math.pi and dist < _REVERSE_ONTO_M:  # overshot a little: reverse
        err_b = wrap_angle(to_c + math.pi - rel.theta)
        return -min(sc.speed_mps, _APPROACH_GAIN_PER_S * dist), turn_rate(err_b, sc)
    if abs(err) > _AIM_TOL_RAD:
        return 0.0, turn_rate(err, sc)
    if ahead_free_m < min(sc.clearance_m, _DOCK_CLEARANCE_M):
        return None  # something in the way: dock where it stands
    return min(sc.speed_mps, _APPROACH_GAIN_PER_S * dist), turn_rate(err, sc)


def go_align(look: Look, rel: Pose2D, tol_rad: float, ahead_free_m: float,
             sc: StarConfig) -> Twist | None:
    """GO onto the origin (`rel`: the robot in its frame), then ALIGN with its heading
    within tol_rad: the twist, or None once aligned (phase ALIGN) or looking (LOOK)."""
    if look.phase is LookPhase.GO:
        cmd = drive_to_origin(rel, ahead_free_m, sc)
        if cmd is not None:
            return cmd
        look.phase = LookPhase.ALIGN
    if look.phase is LookPhase.ALIGN:
        err = wrap_angle(-rel.theta)
        if abs(err) > tol_rad:
            return 0.0, turn_rate(err, sc)
    return None


def start_look(look: Look, theta_rad: float) -> None:
    """Begin a full circle from heading theta_rad (odometry) with no points yet."""
    look.phase, look.turned_rad, look.prev_theta, look.points = (
        LookPhase.LOOK, 0.0, theta_rad, [])


def look_step(look: Look, theta_rad: float, sc: StarConfig) -> Twist | None:
    """LOOK: turn a full circle in place (scans collect in look.points); None once done."""
    look.turned_rad += abs(wrap_angle(theta_rad - look.prev_theta))
    look.prev_theta = theta_rad
    if look.turned_rad < 2.0 * math.pi:
        return 0.0, look.turn_sign * sc.turn_rate_radps
    return None


def look_around(look: Look, rel: Pose2D, tol_rad: float, theta_rad: float, ahead_free_m: float,
                sc: StarConfig) -> Twist | None:
    """Go onto the origin (`rel`: the robot in its frame), align with it within tol_rad, turn a
    full circle (theta_rad: odometry's heading now): the twist, or None once the circle is
    done."""
    cmd = go_align(look, rel, tol_rad, ahead_free_m, sc)
    if cmd is not None:
        return cmd
    if look.phase is LookPhase.ALIGN:
        start_look(look, theta_rad)
    return look_step(look, theta_rad, sc)


def ahead_free_m(ranges_m: FloatArray, angles_rad: FloatArray, sc: StarConfig) -> float:
    """Nearest echo within the ahead cone of a scan (from the robot centre) [m]."""
    half = math.radians(sc.ahead_halfwidth_deg)
    wrapped = np.arctan2(np.sin(angles_rad), np.cos(angles_rad))
    sel = np.abs(wrapped) <= half
    vals = ranges_m[sel & np.isfinite(ranges_m)]
    return float(vals.min()) if vals.size else math.inf


def drive_onto_origin(p: Pose2D, min_go_m: float) -> tuple[StrategyPrimitive, ...]:
    """The steps from pose `p` in an island's frame onto its origin, facing theta 0, as the hall
    follower would record them: turn to the origin, go, turn; only the final turn when the origin
    is `min_go_m` [m] or nearer."""
    dist = math.hypot(p.x, p.y)
    steps: tuple[StrategyPrimitive, ...]
    if dist > min_go_m:
        to_c = wrap_angle(math.atan2(-p.y, -p.x) - p.theta)
        steps = (rot(to_c), StrategyPrimitive(PrimitiveKind.GO, round(100 * dist)),
                 rot(-(p.theta + to_c)))
    else:
        steps = (rot(-p.theta),)
    return tuple(s for s in steps if s.value != 0)


def rot(angle_rad: float) -> StrategyPrimitive:
    """A Rot step of the strategy (degrees CCW in [0, 360))."""
    return StrategyPrimitive(PrimitiveKind.ROT, round(math.degrees(angle_rad)) % 360)
