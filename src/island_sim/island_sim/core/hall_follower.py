"""A hall-following controller driven by the sonar ring alone (numpy only).

A pure state machine: `HallFollower.update(ranges_m, angles_rad, odom_pose, t_s) -> (v, w)`.

- FOLLOW keeps to the middle of a hallway: straight-line fits of the wall points on either side
  (robot frame) give the lateral offset and the hallway's direction; with one wall it keeps the
  last hallway half-width from it; with none it holds the last hallway direction by odometry.
- An *opening* is a side whose perpendicular transducer sees nothing within `open_side_m` after
  that side was a wall for `rearm_distance_m` of travel. When an opening (or a wall ahead) appears
  the controller decides by its `TurnPolicy` among the available choices (left, straight, right,
  back). A chosen side turn drives on to the estimated middle of the side hallway (ADVANCE),
  cancelling if the side closes again first (a door, narrower than a hallway), rotates in place
  by odometry (TURN) and drives into the new hallway (ENTER) before following again.
- It stops short of walls ahead: the speed falls to zero at `stop_distance_m`.
- What it executed is kept as the paper's control-strategy primitives (Table 1): Go [cm] of
  odometric travel, Rot [deg CCW, 0-360) of odometric rotation; `reset_strategy()` restarts the
  record at the current pose; `set_enabled(False)` outputs zero twist (motion while paused is not
  recorded) and re-enabling resumes from FOLLOW at the current pose.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.hall_perception import (
    HallPerceptionConfig,
    Perception,
    PerceptionError,
    perceive,
)
from island_msgs_py.types import (
    ControlStrategy,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
    wrap_angle,
)

# Weight of a new wall-based hallway direction in the smoothed direction estimate [-].
_AXIS_SMOOTHING = 0.3
# A robot that moved less than this in one control period has stopped [m].
_SETTLED_STEP_M = 0.002
# Stall detection: below this commanded speed nothing is expected to move [m/s]; progress in a
# control period under this fraction of (commanded speed x period) counts as no progress [-].
_STALL_MIN_SPEED_MPS = 0.1
_STALL_PROGRESS_FRACTION = 0.2
# Largest disagreement [rad] between the wall-based and the held hallway direction still trusted.
_AXIS_TRUST_RAD = math.radians(25.0)
# Parameter range of the config's distances, speeds, gains and times (all must be >= 0).
_NON_NEGATIVE = (0.0, math.inf)


class HallFollowerError(InputError):
    """Bad configuration or bad `update` input; the message names the field."""


class TurnPolicy(StrEnum):
    """How the follower chooses at intersections and dead ends."""

    LEFT_HAND = "left_hand"  # prefer left, then straight, then right, then back
    RIGHT_HAND = "right_hand"  # prefer right, then straight, then left, then back
    SCRIPTED = "scripted"  # the next choice of `script`; left-hand order when unavailable/used up
    RANDOM = "random"  # uniformly among the available choices (seeded Generator)


class TurnChoice(StrEnum):
    LEFT = "left"
    STRAIGHT = "straight"
    RIGHT = "right"
    BACK = "back"


class FollowerState(StrEnum):
    FOLLOW = "follow"
    ADVANCE = "advance"  # driving on to the middle of the chosen side hallway
    TURN = "turn"  # rotating in place to a target odometric heading
    ENTER = "enter"  # driving into the new hallway before following it
    PAUSED = "paused"


_TURN_ANGLE_RAD = {
    TurnChoice.LEFT: math.pi / 2.0,
    TurnChoice.RIGHT: -math.pi / 2.0,
    TurnChoice.BACK: math.pi,
    TurnChoice.STRAIGHT: 0.0,
}
_LEFT_ORDER = (TurnChoice.LEFT, TurnChoice.STRAIGHT, TurnChoice.RIGHT, TurnChoice.BACK)
_RIGHT_ORDER = (TurnChoice.RIGHT, TurnChoice.STRAIGHT, TurnChoice.LEFT, TurnChoice.BACK)


def parse_script(text: str) -> tuple[TurnChoice, ...]:
    """`"left, straight, right, back"` (or l/s/r/b) -> turn choices; empty text -> ()."""
    short = {"l": "left", "s": "straight", "r": "right", "b": "back"}
    out = []
    for part in text.replace(";", ",").split(","):
        p = part.strip().lower()
        if not p:
            continue
        try:
            out.append(TurnChoice(short.get(p, p)))
        except ValueError:
            raise HallFollowerError(
                f"HallFollowerConfig.script: unknown turn {part.strip()!r} "
                "(use left, straight, right, back)"
            ) from None
    return tuple(out)


@dataclass(frozen=True)
class HallFollowerConfig:
    """Parameters of the hall follower (distances from the robot centre)."""

    cruise_speed_mps: float = field(
        default=0.5,
        metadata={"help": "speed along halls [m/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    max_turn_rate_radps: float = field(
        default=1.0,
        metadata={"help": "largest commanded turn rate [rad/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    robot_radius_m: float = field(
        default=0.25,
        metadata={"help": "radius of the robot's body, for clearance checks [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    stop_distance_m: float = field(
        default=0.75,
        metadata={"help": "an obstacle ahead this close (from the robot centre) stops the "
                  "robot and forces a decision [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    slow_distance_m: float = field(
        default=2.0,
        metadata={"help": "the robot slows down linearly below this front range [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    path_margin_m: float = field(
        default=0.2,
        metadata={"help": "echoes ahead within robot_radius_m + this of the robot's path "
                  "count as obstacles in the way [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    side_half_angle_deg: float = field(
        default=35.0,
        metadata={"help": "echoes within this of a side's perpendicular bearing are fitted as "
                  "that side's wall [deg]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    fit_tolerance_m: float = field(
        default=0.08,
        metadata={"help": "largest residual of a side wall fit still taken as one straight "
                  "wall; otherwise only the perpendicular distance is used [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    open_side_m: float = field(
        default=2.5,
        metadata={"help": "a side whose perpendicular range exceeds this is open [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    rearm_distance_m: float = field(
        default=1.0,
        metadata={"help": "travel with a side closed before an opening on it counts again [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    confirm_distance_m: float = field(
        default=0.1,
        metadata={"help": "travel with a side open before the opening counts (debounce) [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    default_hall_width_m: float = field(
        default=2.0,
        metadata={"help": "hallway width assumed before one has been measured [m]",
                  "range": _NON_NEGATIVE},
    )
    side_lag_m: float = field(
        default=0.2,
        metadata={"help": "travel past a corner before the side transducer's cone clears it; "
                  "subtracted from the advance to a side hallway's middle [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    min_advance_m: float = field(
        default=0.4,
        metadata={"help": "shortest drive from an opening to the turn [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    enter_distance_m: float = field(
        default=1.2,
        metadata={"help": "drive after a turn before following again [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    straight_free_m: float = field(
        default=3.0,
        metadata={"help": "at an opening, straight is a choice when the way ahead is free this "
                  "far [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    k_lateral: float = field(
        default=1.2,
        metadata={"help": "approach angle per metre off the hallway middle [rad/m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    max_approach_deg: float = field(
        default=20.0,
        metadata={"help": "largest angle to the hallway when re-centring [deg]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    k_heading: float = field(
        default=2.0,
        metadata={"help": "turn rate per radian of heading error [1/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    turn_tolerance_deg: float = field(
        default=1.5,
        metadata={"help": "a rotation in place ends within this of its target [deg]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    stall_time_s: float = field(
        default=1.0,
        metadata={"help": "driving forward while odometry shows (almost) no progress for this "
                  "long counts as blocked (a wall the sonar cannot see) [s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    min_turn_rate_radps: float = field(
        default=0.15,
        metadata={"help": "smallest turn rate while rotating in place [rad/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    policy: TurnPolicy = field(
        default=TurnPolicy.LEFT_HAND,
        metadata={"help": "turn policy: left_hand, right_hand, scripted, random",
                  "live": True},
    )
    script: str = field(
        default="",
        metadata={"help": "scripted policy: comma-separated turns (left, straight, right, back) "
                  "used one per decision",
                  "live": True},
    )

    def __post_init__(self) -> None:
        for f_name in (
            "cruise_speed_mps", "max_turn_rate_radps", "robot_radius_m", "stop_distance_m",
            "slow_distance_m", "path_margin_m", "side_half_angle_deg", "fit_tolerance_m",
            "open_side_m",
            "rearm_distance_m", "confirm_distance_m", "default_hall_width_m", "side_lag_m",
            "min_advance_m", "enter_distance_m", "straight_free_m", "k_lateral",
            "max_approach_deg", "k_heading", "turn_tolerance_deg", "min_turn_rate_radps",
            "stall_time_s",
        ):
            v = getattr(self, f_name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise HallFollowerError(f"HallFollowerConfig.{f_name}: expected a finite number, "
                                        f"got {v!r}")
            if v < 0:
                raise HallFollowerError(f"HallFollowerConfig.{f_name}: must be >= 0, got {v}")
        if self.stop_distance_m <= self.robot_radius_m:
            raise HallFollowerError(
                f"HallFollowerConfig.stop_distance_m ({self.stop_distance_m}) must exceed "
                f"robot_radius_m ({self.robot_radius_m})"
            )
        if self.slow_distance_m <= self.stop_distance_m:
            raise HallFollowerError(
                f"HallFollowerConfig.slow_distance_m ({self.slow_distance_m}) must exceed "
                f"stop_distance_m ({self.stop_distance_m})"
            )
        if not isinstance(self.policy, TurnPolicy):
            try:
                object.__setattr__(self, "policy", TurnPolicy(self.policy))
            except ValueError:
                raise HallFollowerError(
                    f"HallFollowerConfig.policy: unknown policy {self.policy!r} "
                    f"(use {', '.join(p.value for p in TurnPolicy)})"
                ) from None
        parse_script(self.script)

    @property
    def perception(self) -> HallPerceptionConfig:
        """The hallway perception these fields configure (shared with route following)."""
        return HallPerceptionConfig(self.robot_radius_m, self.path_margin_m,
                                    self.side_half_angle_deg, self.fit_tolerance_m,
                                    self.open_side_m)

    @property
    def script_choices(self) -> tuple[TurnChoice, ...]:
        return parse_script(self.script)


@dataclass(frozen=True)
class Decision:
    """One decision at an intersection or dead end (odometric pose, sim time)."""

    t_s: float
    odom_pose: Pose2D
    options: tuple[TurnChoice, ...]
    choice: TurnChoice
    at_dead_end: bool


class HallFollower:
    """Sonar-only hall following with a turn policy and a control-strategy record."""

    def __init__(
        self, config: HallFollowerConfig | None = None, rng: np.random.Generator | None = None
    ) -> None:
        self.config = config if config is not None else HallFollowerConfig()
        if self.config.policy is TurnPolicy.RANDOM and rng is None:
            raise HallFollowerError("HallFollower: the random policy needs a numpy Generator")
        self._rng = rng
        self._script = list(self.config.script_choices)
        self.decisions: list[Decision] = []
        self.cancelled_turns = 0
        self.stalls = 0  # times odometry showed the robot stuck while driving forward
        self._last_v = 0.0
        self._stall_since: float | None = None
        self._last_t: float | None = None
        self._enabled = True
        self._started = False
        self._state = FollowerState.FOLLOW
        self._last_pose: Pose2D | None = None
        self._travel_m = 0.0  # odometric distance driven since the start [m]
        self._axis = 0.0  # hallway direction in the odometry frame [rad]
        self._hall_width_m = self.config.default_hall_width_m
        self._closed_since = {TurnChoice.LEFT: math.nan, TurnChoice.RIGHT: math.nan}
        self._open_since = {TurnChoice.LEFT: math.nan, TurnChoice.RIGHT: math.nan}
        self._armed = {TurnChoice.LEFT: False, TurnChoice.RIGHT: False}
        self._pending: TurnChoice | None = None
        self._advance_until_m = 0.0
        self._enter_until_m = 0.0
        self._turn_target = 0.0
        self._settling = False
        self._last_step_m = 0.0
        # strategy record
        self._steps: list[StrategyPrimitive] = []
        self._go_m = 0.0
        self._rot_rad = 0.0
        self._rot_start: float | None = None

    # --- public state --------------------------------------------------------------------------
    @property
    def state(self) -> FollowerState:
        return FollowerState.PAUSED if not self._enabled else self._state

    @property
    def enabled(self) -> bool:
        return self._enabled

    @property
    def hall_width_m(self) -> float:
        """Last measured hallway width [m]."""
        return self._hall_width_m

    def set_enabled(self, enabled: bool) -> None:
        """Pause (zero twist, nothing recorded) or resume following from the current pose."""
        if enabled and not self._enabled:
            self._state = FollowerState.FOLLOW
            self._pending = None
            self._last_pose = None  # motion while paused is not part of the strategy
            self._started = False
            for side in self._armed:
                self._armed[side] = False
                self._closed_since[side] = math.nan
                self._open_since[side] = math.nan
        if not enabled and self._enabled:
            self._close_rotation()
        self._enabled = bool(enabled)

    def reconfigure(self, config: HallFollowerConfig) -> None:
        """Follow with `config` from the next update on, keeping the state and the record (a
        changed script starts from its first turn; `default_hall_width_m` only matters before
        the first hallway is measured)."""
        if config.policy is TurnPolicy.RANDOM and self._rng is None:
            raise HallFollowerError("HallFollower: the random policy needs a numpy Generator")
        if config.script != self.config.script:
            self._script = list(config.script_choices)
        self.config = config

    def reset_strategy(self) -> None:
        """Forget the executed strategy; the record restarts at the current pose."""
        self._steps = []
        self._go_m = 0.0
        self._rot_rad = 0.0
        if self._rot_start is not None and self._last_pose is not None:
            self._rot_start = self._last_pose.theta

    def strategy(self) -> ControlStrategy:
        """What was executed since the start or the last reset, e.g. `Go 125, Rot 270, Go 652`."""
        steps = list(self._steps)
        rot = self._rot_rad
        if self._rot_start is not None and self._last_pose is not None:
            rot += wrap_angle(self._last_pose.theta - self._rot_start)
        self._append(steps, PrimitiveKind.ROT, rot)
        self._append(steps, PrimitiveKind.GO, self._go_m)
        return ControlStrategy(tuple(steps))

    # --- strategy bookkeeping ------------------------------------------------------------------
    @staticmethod
    def _append(steps: list[StrategyPrimitive], kind: PrimitiveKind, amount: float) -> None:
        """Append a Go [m] or Rot [rad] amount in Table 1 units, merging with a step of its kind."""
        if kind is PrimitiveKind.GO:
            prev = steps[-1].value if steps and steps[-1].kind is kind else 0
            value = prev + round(amount * 100.0)
            if value <= 0:
                return
        else:
            prev_rad = math.radians(steps[-1].value) if steps and steps[-1].kind is kind else 0.0
            value = round(math.degrees(wrap_angle(prev_rad + amount))) % 360
        if steps and steps[-1].kind is kind:
            steps.pop()
        if value != 0:
            steps.append(StrategyPrimitive(kind, value))

    def _close_go(self) -> None:
        self._append(self._steps, PrimitiveKind.GO, self._go_m)
        self._go_m = 0.0

    def _close_rotation(self) -> None:
        if self._rot_start is not None and self._last_pose is not None:
            self._rot_rad += wrap_angle(self._last_pose.theta - self._rot_start)
        self._rot_start = None
        self._append(self._steps, PrimitiveKind.ROT, self._rot_rad)
        self._rot_rad = 0.0

    # --- perception ----------------------------------------------------------------------------
    def perceive(self, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike) -> Perception:
        """Summarize one scan (ranges from the robot centre [m], bearings [rad], robot frame)."""
        try:
            return perceive(ranges_m, angles_rad, self.config.perception)
        except PerceptionError as exc:
            raise HallFollowerError(str(exc)) from None

    # --- control -------------------------------------------------------------------------------
    def update(
        self, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike, odom_pose: Pose2D, t_s: float
    ) -> tuple[float, float]:
        """One control period: (v [m/s], w [rad/s]) from a scan and the odometric pose."""
        if not isinstance(odom_pose, Pose2D):
            raise HallFollowerError(f"update: odom_pose must be a Pose2D, got {type(odom_pose)}")
        if not math.isfinite(t_s):
            raise HallFollowerError(f"update: t_s must be finite, got {t_s!r}")
        p = self.perceive(ranges_m, angles_rad)
        if not self._enabled:
            return 0.0, 0.0
        self._track_motion(odom_pose)
        stalled = self._stalled(t_s)
        self._last_t = t_s
        if stalled:
            self.stalls += 1
            self._stall_since = None
            p = dataclasses.replace(p, front_m=0.0)  # blocked by something the sonar missed
        v, w = self._control(p, odom_pose, t_s)
        self._last_v = v
        return v, w

    def _stalled(self, t_s: float) -> bool:
        """Commanded forward for `stall_time_s` while odometry advanced < 1/5 of that speed."""
        moving = self._state in (FollowerState.FOLLOW, FollowerState.ADVANCE, FollowerState.ENTER)
        dt_s = t_s - self._last_t if self._last_t is not None else 0.0
        expected_m = self._last_v * dt_s * _STALL_PROGRESS_FRACTION
        if (not moving or self._last_v < _STALL_MIN_SPEED_MPS or dt_s <= 0.0
                or self._last_step_m >= expected_m):
            self._stall_since = None
            return False
        if self._stall_since is None:
            self._stall_since = t_s
        return t_s - self._stall_since >= self.config.stall_time_s

    def _control(self, p: Perception, odom_pose: Pose2D, t_s: float) -> tuple[float, float]:
        if not self._started:
            self._started = True
            self._axis = odom_pose.theta
        c = self.config

        # keep the hallway direction (odometry frame) and width up to date
        in_hall = (
            self._state is FollowerState.FOLLOW and not p.left_open and not p.right_open
        )
        if p.wall_angle_rad is not None and in_hall:
            axis = wrap_angle(odom_pose.theta + p.wall_angle_rad)
            if abs(wrap_angle(axis - self._axis)) < _AXIS_TRUST_RAD:
                step = _AXIS_SMOOTHING * wrap_angle(axis - self._axis)
                self._axis = wrap_angle(self._axis + step)
        if in_hall and math.isfinite(p.left_dist_m) and math.isfinite(p.right_dist_m):
            self._hall_width_m = p.left_dist_m + p.right_dist_m
        self._track_sides(p)

        if self._state is FollowerState.TURN:
            if self._settling:
                if self._last_step_m > _SETTLED_STEP_M:
                    return 0.0, 0.0  # still rolling to a stop: that travel belongs to the Go
                self._settling = False
                self._close_go()
                self._rot_start = odom_pose.theta
            err = wrap_angle(self._turn_target - odom_pose.theta)
            if abs(err) <= math.radians(c.turn_tolerance_deg):
                self._close_rotation()
                self._state = FollowerState.ENTER
                self._axis = self._turn_target
                self._enter_until_m = self._travel_m + c.enter_distance_m
                return 0.0, 0.0
            w = c.k_heading * err
            w = math.copysign(min(max(abs(w), c.min_turn_rate_radps), c.max_turn_rate_radps), err)
            return 0.0, w

        if self._state is FollowerState.ADVANCE:
            side = self._pending
            assert side is not None
            still_open = p.left_open if side is TurnChoice.LEFT else p.right_open
            if not still_open:
                # the opening closed before its middle: a door, not a hallway
                self.cancelled_turns += 1
                if self._script_active and self.decisions:
                    self._script.insert(0, self.decisions[-1].choice)
                self._state = FollowerState.FOLLOW
                self._pending = None
            elif self._travel_m >= self._advance_until_m or p.front_m <= max(
                c.stop_distance_m, 0.5 * self._hall_width_m
            ):
                self._start_turn(side, odom_pose)
                return 0.0, 0.0

        if self._state is FollowerState.ENTER and (
            self._travel_m >= self._enter_until_m or p.front_m <= c.stop_distance_m
        ):
            self._state = FollowerState.FOLLOW

        if self._state is FollowerState.FOLLOW:
            choice = self._maybe_decide(p, odom_pose, t_s)
            if choice is not None:
                if choice in (TurnChoice.LEFT, TurnChoice.RIGHT) and p.front_m > c.stop_distance_m:
                    self._pending = choice
                    self._state = FollowerState.ADVANCE
                    opened_at = self._open_since[choice]
                    if math.isnan(opened_at):
                        opened_at = self._travel_m
                    advance = max(c.min_advance_m, 0.5 * self._hall_width_m - c.side_lag_m)
                    self._advance_until_m = opened_at + advance
                elif choice is not TurnChoice.STRAIGHT:
                    self._start_turn(choice, odom_pose)
                    return 0.0, 0.0

        return self._drive(p, odom_pose)

    @property
    def _script_active(self) -> bool:
        return self.config.policy is TurnPolicy.SCRIPTED

    def _track_motion(self, pose: Pose2D) -> None:
        self._last_step_m = 0.0
        if self._last_pose is not None:
            d = math.hypot(pose.x - self._last_pose.x, pose.y - self._last_pose.y)
            self._last_step_m = d
            self._travel_m += d
            if self._state is not FollowerState.TURN or self._settling:
                self._go_m += d
        self._last_pose = pose

    def _track_sides(self, p: Perception) -> None:
        c = self.config
        for side, is_open in ((TurnChoice.LEFT, p.left_open), (TurnChoice.RIGHT, p.right_open)):
            if is_open:
                self._closed_since[side] = math.nan
                if math.isnan(self._open_since[side]):
                    self._open_since[side] = self._travel_m
            else:
                self._open_since[side] = math.nan
                if math.isnan(self._closed_since[side]):
                    self._closed_since[side] = self._travel_m
                if self._travel_m - self._closed_since[side] >= c.rearm_distance_m:
                    self._armed[side] = True

    def _side_event(self, side: TurnChoice) -> bool:
        opened = self._open_since[side]
        return (
            self._armed[side]
            and not math.isnan(opened)
            and self._travel_m - opened >= self.config.confirm_distance_m
        )

    def _maybe_decide(self, p: Perception, pose: Pose2D, t_s: float) -> TurnChoice | None:
        c = self.config
        blocked = p.front_m <= c.stop_distance_m
        if not blocked and not (self._side_event(TurnChoice.LEFT)
                                or self._side_event(TurnChoice.RIGHT)):
            return None
        options = []
        if p.left_open:
            options.append(TurnChoice.LEFT)
        if not blocked and p.front_free_m >= c.straight_free_m:
            options.append(TurnChoice.STRAIGHT)
        if p.right_open:
            options.append(TurnChoice.RIGHT)
        if blocked or not options:
            options.append(TurnChoice.BACK)
        choice = self._choose(tuple(options))
        for side in (TurnChoice.LEFT, TurnChoice.RIGHT):
            self._armed[side] = False  # both sides must close again before the next event
        self.decisions.append(Decision(t_s, pose, tuple(options), choice, blocked))
        return choice

    def _choose(self, options: tuple[TurnChoice, ...]) -> TurnChoice:
        policy = self.config.policy
        if policy is TurnPolicy.RANDOM:
            assert self._rng is not None
            return options[int(self._rng.integers(len(options)))]
        if policy is TurnPolicy.SCRIPTED and self._script:
            want = self._script[0]
            if want in options:
                self._script.pop(0)
                return want
        order = _RIGHT_ORDER if policy is TurnPolicy.RIGHT_HAND else _LEFT_ORDER
        for choice in order:
            if choice in options:
                return choice
        return TurnChoice.BACK

    def _start_turn(self, choice: TurnChoice, pose: Pose2D) -> None:
        self._state = FollowerState.TURN
        self._settling = True
        self._pending = None
        self._turn_target = wrap_angle(self._axis + _TURN_ANGLE_RAD[choice])
        for side in (TurnChoice.LEFT, TurnChoice.RIGHT):
            self._armed[side] = False
            self._closed_since[side] = math.nan

    def _drive(self, p: Perception, pose: Pose2D) -> tuple[float, float]:
        c = self.config
        half = 0.5 * self._hall_width_m
        use_left = math.isfinite(p.left_dist_m) and not p.left_open
        use_right = math.isfinite(p.right_dist_m) and not p.right_open
        if self._state is FollowerState.ADVANCE:
            use_left = use_left and self._pending is not TurnChoice.LEFT
            use_right = use_right and self._pending is not TurnChoice.RIGHT
        if use_left and use_right:
            offset = 0.5 * (p.left_dist_m - p.right_dist_m)  # > 0: the middle is to the left
        elif use_left:
            offset = p.left_dist_m - half
        elif use_right:
            offset = half - p.right_dist_m
        else:
            offset = 0.0
        # never aim closer to a wall than the body plus a margin
        max_approach = math.radians(c.max_approach_deg)
        approach = max(-max_approach, min(max_approach, c.k_lateral * offset))
        desired = wrap_angle(self._axis + approach)
        err = wrap_angle(desired - pose.theta)
        w = max(-c.max_turn_rate_radps, min(c.max_turn_rate_radps, c.k_heading * err))
        span = c.slow_distance_m - c.stop_distance_m
        speed_scale = min(1.0, max(0.0, (p.front_m - c.stop_distance_m) / span))
        if speed_scale > 0.0:
            speed_scale = max(speed_scale, 0.15)
        # turn first, then go: a large heading error slows the robot down
        speed_scale *= max(0.0, 1.0 - abs(err) / math.radians(45.0))
        return c.cruise_speed_mps * speed_scale, w
