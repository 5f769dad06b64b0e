"""Places at side openings (issue 16): a doorway or a side hallway the hall follower passes.

The measure R cannot tell a junction seen from the corridor beside it from the corridor: from
there, the walls that would fix the position along the corridor (a side hallway's walls, a
doorway's jambs) are seen only far off their normals, which a specular sonar misses. A step into
the opening sees them square on. So, with `OpeningConfig.enabled`, an opening the follower
passes in a hallway is a place to attempt an island at (still only when eq. 3's epsilon > E_min
says the robot needs one): the builder takes the robot back to the opening's middle, turns into
it and drives in (through a doorway's passage, `past_m` beyond its narrowest point; into a side
hallway `branch_m`), and the star starts there. A dismissed attempt drives back out to where the
follower stopped, so the follower's record goes on as if nothing had happened.

- `OpeningRun`: which side opened in a hallway and where along the path its middle was.
- `Entry`: the drive from where the follower stopped into the opening (centre, turn, in) as a
  small state machine fed once per scan, the strategy steps it drove (the edge's strategy goes
  on with them), and the way back out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

from island_msgs_py.hall_perception import HallPerceptionConfig, Perception, perceive
from island_msgs_py.types import (
    ControlStrategy,
    FloatArray,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
    wrap_angle,
)

from island_mapping.core.builder.config import StarConfig
from island_mapping.core.builder.motion import (
    Twist,
    along_line,
    drive_line,
    drive_onto_origin,
    return_to_centre,
    rot,
    turn_to,
)
from island_mapping.core.builder.opening_config import OpeningConfig
from island_mapping.core.graph import reverse_strategy

_TURNED_RAD = math.radians(30.0)
"""The follower turned off the hallway: heading changed by more than this [rad]."""
_PAST_WALL_M = 0.3
"""A side open this far past the hallway's wall line (half its width in): a room behind a
doorway in a thin wall; nearer, the robot may still stand in a junction's open middle [m]."""
_DECIDE_MARGIN_M = 0.1
"""The drive in goes at least this far past where a room would show, before it stops [m]."""
_WIDTH_GAIN = 0.1
"""Weight of one scan's hallway width in the smoothed width [-]."""


@dataclass
class OpeningRun:
    """A side (left or right) open while following, by path [m]: the run from start_m; once
    it closes after min_m (or has stayed open over long_m), `centre_m` is where along the path
    its middle was (for a long one, long_m / 2 in) and `side` which side (1 left, -1 right),
    until `take`n. A run starts only in a hallway: both sides walls over hall_m of path before
    it (in a room the sides come and go)."""

    start_m: float | None = None
    centre_m: float | None = None
    taken: bool = False
    walled_m: float | None = None  # path when both sides last became walls
    last_walled_m: float | None = None  # path when both sides were last seen walls
    first_m: float | None = None  # path at the run's first scan [m]
    left: int = 0  # scans of the run with the left side open
    right: int = 0
    side: int = 0
    theta_rad: float | None = None  # the hallway's heading (odometry) [rad]

    def update(self, path_m: float, left_open: bool, right_open: bool, theta_rad: float,
               cfg: OpeningConfig) -> None:
        """One scan at path_m [m], heading theta_rad (odometry): which sides are open. A turn
        of the follower ends the hallway (and a run in it)."""
        if self.first_m is None:
            self.first_m = path_m
        if self.theta_rad is None or abs(wrap_angle(theta_rad - self.theta_rad)) > _TURNED_RAD:
            self.theta_rad, self.start_m, self.walled_m = theta_rad, None, None
        if left_open or right_open:
            in_hall = self.walled_m is not None and path_m - self.walled_m >= cfg.hall_m
            self.walled_m = None
            if self.start_m is None and (self.taken or not in_hall):
                return
            if self.start_m is None:
                self.start_m, self.left, self.right = path_m, 0, 0
            self.left += left_open
            self.right += right_open
            if path_m - self.start_m >= cfg.long_m:
                self._offer(self.start_m + 0.5 * cfg.long_m)
            return
        if self.start_m is not None and path_m - self.start_m >= cfg.min_m:
            self._offer(0.5 * (self.start_m + path_m))
        self.start_m, self.taken = None, False
        self.last_walled_m = path_m
        if self.walled_m is None:
            self.walled_m = path_m

    def _offer(self, centre_m: float) -> None:
        self.centre_m = centre_m
        self.side = 1 if self.left >= self.right else -1
        self.taken = self.start_m is not None  # still open: no second run of this opening
        self.start_m = None

    def take(self) -> tuple[float, int] | None:
        """(the opening's middle [m of path], its side) if one is pending; not offered again."""
        if self.centre_m is None:
            return None
        out, self.centre_m = (self.centre_m, self.side), None
        return out


@dataclass(frozen=True)
class OpeningExit:
    """What an island built inside an opening tells its exit finder (island frame, theta 0
    into the opening): side 1 the opening was on the follower's left, -1 right; `back` the way
    from the origin back out to the hallway's middle (facing into the opening there, as the
    robot stood before it drove in); the hallway's width_m [m]; narrow:
    the robot came through a doorway (a passage, or a gap in a thin wall with open space
    behind): it stands in a room."""

    side: int
    back: ControlStrategy
    width_m: float
    narrow: bool


class EntryPhase(StrEnum):
    CENTRE = "centre"  # back (or on) to the opening's middle, facing the way driven
    TURN = "turn"  # a quarter turn into the opening
    IN = "in"  # straight into the opening
    DONE = "done"


@dataclass
class Entry:
    """The drive into an opening (odometry poses): `centre` is its middle on the path, facing
    the way the follower drove; `record_end` where the follower stopped; side 1 left, -1
    right. `travelled_m` into the opening so far, and where the narrow part (a doorway's
    passage) ended along it [m]."""

    centre: Pose2D
    record_end: Pose2D
    side: int
    phase: EntryPhase = EntryPhase.CENTRE
    travelled_m: float = 0.0
    narrow_end_m: float | None = None
    opened: bool = False  # a side opened out once in: behind a doorway in a thin wall
    out: list[Pose2D] = field(default_factory=list)  # the way back out, still to drive
    hall_width_m: float = 2.0  # of the hallway the follower drove [m]

    @property
    def room(self) -> bool:
        """Did the robot cross a doorway into a room (a passage, or open space behind)?"""
        return self.narrow_end_m is not None or self.opened

    @property
    def heading(self) -> Pose2D:
        """The pose at the opening's middle facing into it (odometry)."""
        return self.centre.compose(Pose2D(0.0, 0.0, self.side * 0.5 * math.pi))

    def step(self, odom: Pose2D, seen: Perception, cfg: OpeningConfig, sc: StarConfig,
             stalled: bool) -> Twist | None:
        """The twist that goes on entering, or None once inside (phase DONE)."""
        if self.phase is EntryPhase.CENTRE:
            cmd = return_to_centre(odom.relative_to(self.centre), sc)
            if cmd is not None and not stalled:
                return cmd
            self.phase = EntryPhase.TURN
        if self.phase is EntryPhase.TURN:
            cmd = turn_to(odom.relative_to(self.heading), 0.0, sc)
            if cmd is not None and not stalled:
                return cmd
            self.phase = EntryPhase.IN
        if self.phase is EntryPhase.IN:
            rel = odom.relative_to(self.heading)
            self.travelled_m, lateral = along_line(rel, 0.0)
            if seen.left_dist_m < cfg.narrow_m and seen.right_dist_m < cfg.narrow_m:
                self.narrow_end_m = self.travelled_m  # in a passage: centre between its sides
                lateral = 0.5 * (seen.right_dist_m - seen.left_dist_m)
            elif self.travelled_m > 0.5 * self.hall_width_m + _PAST_WALL_M and (
                    seen.left_open or seen.right_open):
                self.opened = True  # past the hallway's wall line: a room opens out
            decide_m = 0.5 * self.hall_width_m + _PAST_WALL_M + _DECIDE_MARGIN_M
            goal = max(cfg.branch_m, decide_m) if not self.room else min(
                max(cfg.room_in_m, (self.narrow_end_m or 0.0) + cfg.past_m), cfg.max_in_m)
            # Only the echo straight ahead stops it: the oblique transducers hear a doorway's
            # wall beside the opening, on their axes, as if in the way.
            if (self.travelled_m < goal - sc.position_tol_m
                    and seen.front_free_m > cfg.clearance_m and not stalled):
                return drive_line(rel, 0.0, lateral, sc.speed_mps, sc)
            self.phase = EntryPhase.DONE
        return None

    def steps(self) -> tuple[StrategyPrimitive, ...]:
        """The strategy steps driven from where the follower stopped to where the star
        starts (what an edge's strategy goes on with): back to the middle (`Rot 180, Go d,
        Rot 180`), the quarter turn, `Go` in."""
        back = self.record_end.relative_to(self.centre)
        out: list[StrategyPrimitive] = []
        d = math.hypot(back.x, back.y)
        if round(100 * d) > 0:
            out += [rot(math.pi), StrategyPrimitive(PrimitiveKind.GO, round(100 * d)),
                    rot(math.pi)] if back.x > 0 else [StrategyPrimitive(
                        PrimitiveKind.GO, round(100 * d))]
        out.append(rot(wrap_angle(self.side * 0.5 * math.pi)))
        if round(100 * self.travelled_m) > 0:
            out.append(StrategyPrimitive(PrimitiveKind.GO, round(100 * self.travelled_m)))
        return tuple(out)

    def exit_info(self, shift: Pose2D) -> OpeningExit:
        """What the island built with its origin at `shift` (star anchor frame) tells its exit
        finder."""
        into = [StrategyPrimitive(PrimitiveKind.GO, round(100 * self.travelled_m))]
        if shift.x != 0.0 or shift.y != 0.0:  # the origin moved off the anchor: then onto it
            into += drive_onto_origin(Pose2D(-shift.x, -shift.y, 0.0), 0.0)
        back = reverse_strategy(ControlStrategy(tuple(s for s in into if s.value != 0)))
        return OpeningExit(self.side, back, self.hall_width_m, self.room)

    def leave(self) -> None:
        """Start the way back out: to the opening's middle, then where the follower stopped."""
        self.out = [self.centre, self.record_end]

    def leave_step(self, odom: Pose2D, sc: StarConfig, stalled: bool) -> Twist | None:
        """The twist that goes on leaving, or None once back where the follower stopped."""
        while self.out:
            cmd = return_to_centre(odom.relative_to(self.out[0]), sc)
            if cmd is not None and not stalled:
                return cmd
            self.out.pop(0)
            stalled = False
        return None


class Openings:
    """What the builder knows of side openings: the run of the hallway it follows (`run`),
    the opening entered for the attempt under way (`entry`) and the hallway's smoothed width.
    Feed `observe` once per scan while following."""

    def __init__(self, cfg: OpeningConfig, perception: HallPerceptionConfig | None = None
                 ) -> None:
        self.cfg = cfg
        self.perception = perception if perception is not None else HallPerceptionConfig()
        self.run = OpeningRun()
        self.entry: Entry | None = None
        self.hall_width_m = 2.0  # [m]

    def reset(self) -> None:
        """Openings count from a hallway driven after now (a handover, a hand back)."""
        self.run = OpeningRun()

    def observe(self, ranges_m: FloatArray, angles_rad: FloatArray, path_m: float,
                theta_rad: float) -> None:
        """One scan while following, at path_m [m] and odometric heading theta_rad [rad]."""
        seen = perceive(ranges_m, angles_rad, self.perception)
        self.run.update(path_m, seen.left_open, seen.right_open, theta_rad, self.cfg)
        width = seen.left_dist_m + seen.right_dist_m
        if not (seen.left_open or seen.right_open) and math.isfinite(width):
            self.hall_width_m += _WIDTH_GAIN * (width - self.hall_width_m)

    def in_hallway(self, path_m: float) -> bool:
        """Were both sides walls within the last hallway_recent_m of path (or is the opening
        logic off: then everywhere counts)? In a room or a hall the follower runs along one
        wall, and its corners are not places of their own (the room's island stands at its
        door)."""
        last = self.run.last_walled_m
        return not self.cfg.enabled or (
            last is not None and path_m - last <= self.cfg.hallway_recent_m)

    @property
    def behind_walls(self) -> bool:
        """Does the last island's vicinity end behind a wall of its model (openings on and
        behind_walls)?"""
        return self.cfg.enabled and self.cfg.behind_walls

    def in_room(self, path_m: float) -> bool:
        """Has the follower run along a room's (or a hall's) walls, never both sides walls,
        over room_after_m of path (since the last hallway, or the handover)? Then the room is
        a place of its own: a house of rooms has no hallway to stand its islands in."""
        run = self.run
        since = run.last_walled_m if run.last_walled_m is not None else run.first_m
        return (self.cfg.enabled and self.cfg.room_after_m > 0.0 and since is not None
                and path_m - since >= self.cfg.room_after_m)

    def pending(self, path_m: float) -> bool:
        """An opening passed in a hallway waits to be entered (the robot at path_m [m]); one
        passed more than stale_m ago is dropped (the robot was near the last island then)."""
        c = self.run.centre_m
        if c is not None and path_m - c > self.cfg.stale_m:
            self.run.centre_m = c = None
        return self.cfg.enabled and c is not None

    def enter(self, odom: Pose2D, path_m: float) -> bool:
        """Begin the drive into the pending opening (the robot at odom, path_m [m]); False when
        none is pending."""
        opening = self.run.take()
        if opening is None:
            return False
        back = path_m - opening[0]
        self.entry = Entry(odom.compose(Pose2D(-back, 0.0, 0.0)), odom, opening[1],
                           hall_width_m=self.hall_width_m)
        return True

    def step(self, odom: Pose2D, scan: tuple[FloatArray, FloatArray], sc: StarConfig,
             stalled: bool) -> Twist | None:
        """The drive into the opening (`Entry.step`); None once inside."""
        assert self.entry is not None
        return self.entry.step(odom, perceive(*scan, self.perception), self.cfg, sc, stalled)

    def steps(self) -> tuple[StrategyPrimitive, ...]:
        """The strategy steps of the entry done (none while no entry is done)."""
        e = self.entry
        return e.steps() if e is not None and e.phase is EntryPhase.DONE else ()

    def exit_info(self, shift: Pose2D) -> OpeningExit | None:
        """What an island accepted with its origin at `shift` (anchor frame) tells its exit
        finder, when it stands in an entered opening."""
        return None if self.entry is None else self.entry.exit_info(shift)
