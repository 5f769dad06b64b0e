"""Motion primitives of route following, as generators of velocity commands (no ROS, no simulator).

Every primitive is a generator that yields one command `(v [m/s], w [rad/s])` per sensor period
and reads the robot's newest sensing from a shared `Sense`, which whoever runs the generator
updates in place before resuming it: the simulated evaluation after stepping its robot, the
explorer node when the next scan arrives. The same code therefore drives the simulator and the
live robot, and a primitive's logic reads top to bottom:

    blocked = yield from step(drive, v, w)   # one sensor period under (v, w)

`Go d` follows the hallway for d metres of odometric travel, centred by the same wall fits the
hall follower uses (`island_msgs_py.hall_perception`); `Rot a` turns in place by a of odometric
heading; `look_around` turns a full circle collecting echoes.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Generator
from dataclasses import dataclass, field

import numpy as np
from island_msgs_py.geometry import ranges_to_points, to_frame, unwind_sign
from island_msgs_py.hall_perception import HallPerceptionConfig, Perception, perceive
from island_msgs_py.types import ControlStrategy, FloatArray, Pose2D, PrimitiveKind, wrap_angle

from island_mapping.core.route.config import NavigateConfig

Command = tuple[float, float]
"""(v [m/s], w [rad/s]) for one sensor period."""

Motion = Generator[Command, None, None]

# Rotations end within this of their target heading [rad]; the robot counts as not turning
# below this turn rate [rad/s].
_HEADING_TOL_RAD = math.radians(0.5)
_STILL_RADPS = 0.05
# A drive ends within this of its target [m]; beyond this distance it steers toward it [m].
_ARRIVE_M = 0.01
_GO_TO_MIN_M = 0.02
_STEER_FROM_M = 0.1
# Speed profile near the end of a drive: v = min(cruise, gain * remaining + floor) [1/s, m/s].
_APPROACH_GAIN_PER_S = 1.5
_GO_TO_FLOOR_MPS = 0.02
_GO_FLOOR_MPS = 0.03
# A Go ends this close to its distance [m]; the slowest turn of rotate_by [rad/s].
_GO_DONE_M = 0.005
_BACK_OFF_MPS = 0.15
_QUARTER_TOL_DEG = 15.0  # a turn this near 90 deg is a quarter turn
_BACK_OFF_PERIODS = 40  # a back-off that moves nothing (held on both sides) gives up
_MIN_ROT_RATE_RADPS = 0.1
# The hallway direction is taken from the walls when they are within this of the heading [rad].
_WALL_TRUST_RAD = math.radians(25.0)
# A gap ahead narrower than this is no doorway: the robot (0.5 m) would not pass [m].
_DOORWAY_MIN_WIDTH_M = 0.6
# Half the width the robot sweeps, with a margin: an echo nearer its centre line is in the way.
_PATH_HALF_WIDTH_M = 0.35
# How far past a jamb the unheard side is not taken for an open hallway [m].
_JAMB_CLEAR_M = 1.0
# Approach angle per metre off a jamb's lane [rad/m].
_JAMB_GAIN_RAD_PER_M = 4.0
# After a contact the lane moves this far away from the side touched [m]: a wall the ring did
# not hear is within the robot's radius of its centre, nearer than the sonar's shortest range.
_CONTACT_SHIFT_M = 0.15
# Turned more than this off the hallway's direction at a contact, the robot touched on the side
# it was turned to [rad]; nearer straight on, the side touched is the one without a wall heard.
_CONTACT_TURN_RAD = math.radians(2.0)
# Scans whose echoes a Drive remembers (a specular ring hears a jamb's corner on one bearing
# only, now and then; 10 Hz scans) [-].
_RECENT_SCANS = 50


class RouteTimeoutError(Exception):
    """The time limit of the current leg of a route ran out."""


class RouteDeviationError(RouteTimeoutError):
    """A strategy's Go step ended well short of its length (a wall where the recorded way went
    on): the robot is not where the strategy leads, whatever a localization there says."""


# A forward command at least this fast [m/s] ...
STALL_CMD_MPS = 0.02
# ... that left the measured forward speed (odometry's twist) below this: a wall stopped the
# robot, as a bumper's contact would say [m/s].
STALL_SPEED_MPS = 1e-3


def stalled(commanded_v_mps: float, measured_v_mps: float) -> bool:
    """Was the robot stopped by an obstacle over the last period? A robot without a bumper
    (the explorer node hears only odometry) infers it: it was commanded forward at least
    STALL_CMD_MPS [m/s] and odometry measured under STALL_SPEED_MPS [m/s] (either sign)."""
    return commanded_v_mps >= STALL_CMD_MPS and abs(measured_v_mps) < STALL_SPEED_MPS


@dataclass
class Sense:
    """The robot's newest sensing, updated in place before a motion generator is resumed.

    ranges_m / angles_rad: the latest scan in the robot frame (inf = no echo) [m, rad];
    w_radps: the measured turn rate (odometry's twist) [rad/s]; blocked: the last period's motion
    was stopped by an obstacle (a bumper, or the simulator's contact).
    """

    t_s: float
    odom: Pose2D
    ranges_m: FloatArray
    angles_rad: FloatArray
    w_radps: float = 0.0
    blocked: bool = False

    def points_odom(self) -> FloatArray:
        """Echoes of the latest scan in the odometry frame, (N, 2) [m]."""
        return ranges_to_points(self.ranges_m, self.angles_rad, self.odom)


@dataclass
class Drive:
    """What the motion primitives share: the sensing, the configurations and the time limit."""

    sense: Sense
    cfg: NavigateConfig = field(default_factory=NavigateConfig)
    perception: HallPerceptionConfig = field(default_factory=HallPerceptionConfig)
    hall_width_m: float = 2.0  # assumed hallway width until both walls are seen [m]
    deadline_s: float = math.inf  # RouteTimeoutError past this time [s]
    # The echoes of the last _RECENT_SCANS scans, odometry frame, (K, 2) each [m].
    recent: deque[FloatArray] = field(default_factory=lambda: deque(maxlen=_RECENT_SCANS))
    turned_rad: float = 0.0  # signed odometric turn during the steps driven so far [rad]
    # Odometric turn either way since the pose was last known (a trusted fix; for the
    # explorer also the builder's hand back at an island's origin), whoever drove (the
    # explorer counts it, `spin`) [rad].
    spun_rad: float = 0.0

    def spin(self, sense: Sense) -> None:
        """The newest sensing, whoever drove since the last: its turn counts in spun_rad."""
        self.spun_rad += abs(wrap_angle(sense.odom.theta - self.sense.odom.theta))
        self.sense = sense

    def recent_points(self) -> FloatArray:
        """The remembered echoes in the robot's frame now, (K, 2) [m]."""
        if not self.recent:
            return np.zeros((0, 2))
        return to_frame(np.concatenate(tuple(self.recent), axis=0), self.sense.odom)


def step(d: Drive, v_mps: float, w_radps: float) -> Generator[Command, None, bool]:
    """One sensor period under (v, w); returns whether an obstacle stopped the motion."""
    if d.sense.t_s > d.deadline_s:
        raise RouteTimeoutError()
    before = d.sense.odom.theta
    yield (v_mps, w_radps)
    d.turned_rad += wrap_angle(d.sense.odom.theta - before)
    d.recent.append(d.sense.points_odom())
    return d.sense.blocked


def _turn_rate(d: Drive, err_rad: float) -> float:
    c = d.cfg
    return float(np.clip(c.k_heading_per_s * err_rad, -c.turn_rate_radps, c.turn_rate_radps))


def rotate_to(d: Drive, heading_odom_rad: float) -> Motion:
    """Turn in place to an odometric heading and wait until the turn has stopped."""
    while True:
        err = wrap_angle(heading_odom_rad - d.sense.odom.theta)
        if abs(err) <= _HEADING_TOL_RAD and abs(d.sense.w_radps) < _STILL_RADPS:
            return
        yield from step(d, 0.0, _turn_rate(d, err))


def rotate_by(d: Drive, angle_rad: float) -> Motion:
    """Turn in place by angle_rad of odometric heading (any size, e.g. a full turn)."""
    c = d.cfg
    done, last = 0.0, d.sense.odom.theta
    sign = 1.0 if angle_rad >= 0 else -1.0
    while abs(angle_rad) - abs(done) > _HEADING_TOL_RAD:
        remaining = abs(angle_rad) - abs(done)
        w = sign * min(c.turn_rate_radps, max(_MIN_ROT_RATE_RADPS, c.k_heading_per_s * remaining))
        yield from step(d, 0.0, w)
        th = d.sense.odom.theta
        done += wrap_angle(th - last)
        last = th
    yield from step(d, 0.0, 0.0)


def go_to(d: Drive, target_odom: Pose2D) -> Motion:
    """Drive by odometry to a pose: turn to face it, drive (stopping at a wall), turn to it."""
    c = d.cfg
    o = d.sense.odom
    if math.hypot(target_odom.x - o.x, target_odom.y - o.y) > _GO_TO_MIN_M:
        yield from rotate_to(d, math.atan2(target_odom.y - o.y, target_odom.x - o.x))
        while True:
            o = d.sense.odom
            dx, dy = target_odom.x - o.x, target_odom.y - o.y
            dist = math.hypot(dx, dy)
            along = dx * math.cos(o.theta) + dy * math.sin(o.theta)
            if along <= _ARRIVE_M or dist <= _ARRIVE_M:
                break
            err = wrap_angle(math.atan2(dy, dx) - o.theta) if dist > _STEER_FROM_M else 0.0
            v = min(c.go_speed_mps, _APPROACH_GAIN_PER_S * along + _GO_TO_FLOOR_MPS)
            if (yield from step(d, v, _turn_rate(d, err))):
                break  # a wall is in the way: stop here
    yield from rotate_to(d, target_odom.theta)
    yield from step(d, 0.0, 0.0)


def go_along_hall(d: Drive, distance_m: float, *, remember: bool = False
                  ) -> Generator[Command, None, float]:
    """Drive distance_m of odometric travel forward, centred in the hallway by the sonar;
    stop early at a wall ahead (an echo in the robot's path within 30 deg of the heading: a
    doorway's jamb heard on an oblique transducer is beside the path; in a doorway's
    passage, both sides nearer than passage_side_m, only the echo straight ahead, since the
    jambs' corners echo on every oblique axis; before a doorway, `doorway_offset`, none) or
    when the motion is blocked. With `remember`, the jamb check also reads the echoes of the
    last scans (`Drive.recent`) and the lane past a jamb is steered to proportionally; without,
    a jamb heard turns the robot away at the full approach angle."""
    c = d.cfg
    travelled = 0.0
    last = d.sense.odom
    hold = last.theta  # hallway direction in the odometry frame [rad]
    half_width = 0.5 * d.hall_width_m
    max_app = math.radians(c.max_approach_deg)
    backoffs = 0
    jamb_until_m, lane = 0.0, 0.0  # travel [m] up to which a jamb's lane [m] is kept
    touched_until_m = 0.0  # travel [m] up to which a contact's lane is kept, jambs or not
    start = last
    while travelled < distance_m - _GO_DONE_M:
        p = perceive(d.sense.ranges_m, d.sense.angles_rad, d.perception)
        o = d.sense.odom
        in_passage = p.left_dist_m < c.passage_side_m and p.right_dist_m < c.passage_side_m
        pts = ranges_to_points(d.sense.ranges_m, d.sense.angles_rad)  # robot frame
        gap = doorway_offset(pts, c)
        jamb = None if gap is not None else jamb_offset(
            np.concatenate((pts, d.recent_points()), axis=0) if remember else pts, c)
        # Before a doorway its jambs are what the front transducers hear: nothing lies in the
        # gap (`doorway_offset`), so the robot aims at its middle and only a contact stops it;
        # one jamb in the path with the way straight ahead free, the robot steers past it.
        passing = gap is not None or (jamb is not None and p.front_free_m >= c.stop_distance_m)
        if not passing and (p.front_free_m if in_passage else p.front_cone_m) < (
                c.stop_distance_m):
            break
        if not in_passage and p.wall_angle_rad is not None and abs(
                p.wall_angle_rad) < _WALL_TRUST_RAD:  # a doorway's jambs are too short
            hold = wrap_angle(o.theta + p.wall_angle_rad)
        side = o.relative_to(start).y  # across the way the Go started [m]
        if jamb is not None and travelled >= touched_until_m:  # the lane that clears it,
            # kept after the sonar loses the jamb
            want = side + jamb
            if travelled < jamb_until_m and (want - lane) * jamb < 0.0:
                want = lane  # a lane further away is kept
            jamb_until_m, lane = travelled + _JAMB_CLEAR_M, want
        offset, half_width = _lateral_offset(p, half_width, gap, travelled >= jamb_until_m, c)
        gain = c.k_lateral_rad_per_m
        if gap is None and travelled < jamb_until_m:  # the lane, firmly: a jamb is cm off
            offset, gain = lane - side, _JAMB_GAIN_RAD_PER_M
        approach = float(np.clip(gain * offset, -max_app, max_app))
        if jamb is not None and not remember and travelled >= touched_until_m:  # past it,
            # turned away as far as allowed
            approach = math.copysign(max_app, jamb)
        err = wrap_angle(hold + approach - o.theta)
        remaining = distance_m - travelled
        v = min(c.go_speed_mps, _APPROACH_GAIN_PER_S * remaining + _GO_FLOOR_MPS)
        if (yield from step(d, v, _turn_rate(d, err))):
            # a wall the sonar missed is in the way (a door jamb beside): back off and aim
            # again at the gap's middle, a few times, then stop here
            if backoffs >= c.contact_retries:
                break
            backoffs += 1
            away = _contact_away(p, wrap_angle(o.theta - hold))
            yield from _back_off(d, c.contact_backoff_m)
            if away != 0.0:  # the same lane would touch again
                touched_until_m = jamb_until_m = travelled + _JAMB_CLEAR_M
                lane = side + away * _CONTACT_SHIFT_M
        now = d.sense.odom
        travelled += math.hypot(now.x - last.x, now.y - last.y)
        last = now
    yield from step(d, 0.0, 0.0)
    return travelled


def _contact_away(p: Perception, turned_rad: float) -> float:
    """Which way (1 left, -1 right, 0 unknown) to move off a wall touched while driving
    forward: away from the side the robot was turned to (`turned_rad`, its heading off the
    hallway's, left positive), or, driving straight on, away from the side no wall was heard
    on (a wall nearer than the sonar's shortest range is silent)."""
    if abs(turned_rad) > _CONTACT_TURN_RAD:
        return -math.copysign(1.0, turned_rad)
    left, right = math.isfinite(p.left_dist_m), math.isfinite(p.right_dist_m)
    if left == right:
        return 0.0
    return -1.0 if not left else 1.0


def _lateral_offset(p: Perception, half_width: float, gap: float | None, one_wall: bool,
                    c: NavigateConfig) -> tuple[float, float]:
    """(where to aim across the heading [m, left positive], the hallway's half width [m]):
    the middle between both walls; with one wall seen (and `one_wall`), half a hallway's
    width from it when that near already; a doorway ahead's middle (`gap`) unless both walls
    are seen. Just past a jamb `one_wall` is False: the side unheard may be the other jamb,
    nearer than the sonar's shortest range."""
    use_left = math.isfinite(p.left_dist_m) and not p.left_open
    use_right = math.isfinite(p.right_dist_m) and not p.right_open
    offset = 0.0
    if use_left and use_right:
        return 0.5 * (p.left_dist_m - p.right_dist_m), 0.5 * (p.left_dist_m + p.right_dist_m)
    if one_wall and use_left and abs(p.left_dist_m - half_width) < c.one_wall_band_m:
        offset = p.left_dist_m - half_width
    elif one_wall and use_right and abs(p.right_dist_m - half_width) < c.one_wall_band_m:
        offset = half_width - p.right_dist_m
    return (offset if gap is None else gap), half_width


def _back_off(d: Drive, metres: float) -> Motion:
    """Reverse straight by `metres` of odometric travel (off a wall the robot touched)."""
    start = d.sense.odom
    for _ in range(_BACK_OFF_PERIODS):
        if math.hypot(d.sense.odom.x - start.x, d.sense.odom.y - start.y) >= metres or (
                yield from step(d, -_BACK_OFF_MPS, 0.0)):
            break
    yield from step(d, 0.0, 0.0)


def doorway_offset(pts: FloatArray, c: NavigateConfig) -> float | None:
    """Where the middle of a narrow gap ahead lies across the heading (left positive) [m]: the
    nearest echoes (`pts`, robot frame, (K, 2) [m]) on either side of the path within
    doorway_ahead_m ahead bound the gap; None unless both sides bound one narrower than
    doorway_max_width_m (a hallway is wider; its walls centre the robot) and wide enough for
    the robot (no echo lies inside the gap)."""
    x, y = pts[:, 0], pts[:, 1]
    ahead = (x > 0.1) & (x < c.doorway_ahead_m) & (np.abs(y) < c.doorway_max_width_m)
    left, right = y[ahead & (y > 0.0)], y[ahead & (y < 0.0)]
    if left.size == 0 or right.size == 0:
        return None
    lo, hi = float(right.max()), float(left.min())
    if not _DOORWAY_MIN_WIDTH_M <= hi - lo < c.doorway_max_width_m:
        return None
    return 0.5 * (hi + lo)


def jamb_offset(pts: FloatArray, c: NavigateConfig) -> float | None:
    """Where to aim across the heading (left positive) [m] to pass an echo (`pts`, robot
    frame) in the robot's path (within _PATH_HALF_WIDTH_M of its centre line, doorway_ahead_m
    ahead) on one side only: a doorway's jamb, the other one unheard (a specular sonar hears a
    corner on one oblique axis); None when no echo, or echoes on both sides, lie in the path."""
    x, y = pts[:, 0], pts[:, 1]
    near = (x > 0.1) & (x < c.doorway_ahead_m) & (np.abs(y) < _PATH_HALF_WIDTH_M)
    left, right = y[near & (y >= 0.0)], y[near & (y < 0.0)]
    if (left.size > 0 and right.size > 0) or left.size == right.size == 0:
        return None
    if left.size > 0:
        return float(left.min()) - _PATH_HALF_WIDTH_M
    return float(right.max()) + _PATH_HALF_WIDTH_M


def execute_strategy(d: Drive, strategy: ControlStrategy) -> Motion:
    """Run the primitives: Go d [cm] along the hallway, Rot a [deg CCW] in place (odometry).
    A quarter turn between a Go and a short Go (into a doorway, `doorway_go_m`) first finds
    the doorway beside the robot and stops at its middle (`center_on_doorway`): odometry
    along a hallway is a few decimetres off after ten metres, a doorway's margin less. A Go
    that ends short by more than go_short_m and go_short_fraction of its length raises
    `RouteDeviationError`: the recorded way went on where this one met a wall."""
    steps = strategy.steps
    for k, s in enumerate(steps):
        if s.kind is PrimitiveKind.GO:
            got = yield from go_along_hall(d, s.metres, remember=True)
            if got < s.metres - max(d.cfg.go_short_m, d.cfg.go_short_fraction * s.metres):
                raise RouteDeviationError(f"Go {s.value} ended after {got:.2f} m")
            continue
        turn = s.value if s.value <= 180 else s.value - 360
        nxt = steps[k + 1] if k + 1 < len(steps) else None
        if (k > 0 and steps[k - 1].kind is PrimitiveKind.GO and nxt is not None
                and nxt.kind is PrimitiveKind.GO and nxt.metres <= d.cfg.doorway_go_m
                and abs(abs(turn) - 90) <= _QUARTER_TOL_DEG):
            yield from center_on_doorway(d, 1 if turn > 0 else -1)
        yield from rotate_by(d, math.radians(turn))


def center_on_doorway(d: Drive, side: int) -> Motion:
    """Back up doorway_search_m, then drive on twice that, noting where the side (1 left,
    -1 right) is open; stop at the middle of the open run nearest the start if it is a
    doorway (narrower than doorway_max_width_m), else back where it started."""
    c = d.cfg
    start = d.sense.odom
    yield from _back_off(d, c.doorway_search_m)
    base = d.sense.odom
    runs: list[list[float]] = []
    was_open = False
    for cmd in go_along_hall(d, 2.0 * c.doorway_search_m):
        p = perceive(d.sense.ranges_m, d.sense.angles_rad, d.perception)
        s = math.hypot(d.sense.odom.x - base.x, d.sense.odom.y - base.y)
        is_open = p.left_open if side > 0 else p.right_open
        if is_open and not was_open:
            runs.append([s, s])
        if is_open:
            runs[-1][1] = s
        was_open = is_open
        yield cmd
    back = math.hypot(start.x - base.x, start.y - base.y)
    doors = [r for r in runs if r[1] - r[0] < c.doorway_max_width_m]
    goal = min((0.5 * (r[0] + r[1]) for r in doors), key=lambda m: abs(m - back),
               default=back)
    yield from go_to(d, base.compose(Pose2D(goal, 0.0, 0.0)))


Scan = tuple[Pose2D, FloatArray, FloatArray]
"""One scan of a look: the odometric pose, the ranges [m] (inf: no echo), their angles [rad]."""


def look_scans(d: Drive) -> Generator[Command, None, list[Scan]]:
    """Turn once in place keeping every scan whole (the beams that heard nothing too); the
    way that undoes the net turning of the looks and drives so far (`Drive.turned_rad`),
    with cfg.unwind_turns, else left."""
    scans = [_scan(d.sense)]
    done, last = 0.0, d.sense.odom.theta
    sign = unwind_sign(d.turned_rad, d.cfg.unwind_turns)
    while done < 2.0 * math.pi:
        yield from step(d, 0.0, sign * d.cfg.turn_rate_radps)
        th = d.sense.odom.theta
        done += sign * wrap_angle(th - last)
        last = th
        scans.append(_scan(d.sense))
    yield from step(d, 0.0, 0.0)
    return scans


def _scan(sense: Sense) -> Scan:
    return sense.odom, np.asarray(sense.ranges_m, dtype=np.float64), np.asarray(
        sense.angles_rad, dtype=np.float64)


def look_around(d: Drive) -> Generator[Command, None, FloatArray]:
    """Turn once in place collecting echoes; returns them in the final robot frame, (N, 2) [m]."""
    scans = yield from look_scans(d)
    pts = [ranges_to_points(r, a, o) for o, r, a in scans]
    return to_frame(np.concatenate(pts, axis=0), d.sense.odom)

