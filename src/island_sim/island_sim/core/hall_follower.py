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
- A *stall* (driving forward while odometry shows no progress: a wall the sonar missed, a
  doorway's jamb under the body's edge) backs the robot straight away by `backoff_m` (BACK_OFF;
  less where the ring sees a wall behind), then decides as at a wall ahead. Backing is along
  the Go it interrupts and is taken off that Go's travel.
- What it executed is kept as the paper's control-strategy primitives (Table 1, see
  `strategy_record`): Go [cm] of odometric travel, Rot [deg CCW, 0-360) of odometric rotation;
  `reset_strategy()` restarts the record at the current pose; `set_enabled(False)` outputs zero
  twist (motion while paused is not recorded) and re-enabling resumes from FOLLOW at the
  current pose.

The configuration (`HallFollowerConfig`, `TurnPolicy`, `TurnChoice`, `parse_script`,
`HallFollowerError`) lives in `hall_follower_config` and is importable from here too.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import wrap_angles
from island_msgs_py.hall_perception import Perception, PerceptionError, perceive
from island_msgs_py.types import ControlStrategy, Pose2D, wrap_angle

from island_sim.core.hall_follower_config import (
    HallFollowerConfig,
    HallFollowerError,
    TurnChoice,
    TurnPolicy,
    parse_script,
)
from island_sim.core.strategy_record import StrategyRecorder

__all__ = [
    "Decision",
    "FollowerState",
    "HallFollower",
    "HallFollowerConfig",
    "HallFollowerError",
    "TurnChoice",
    "TurnPolicy",
    "parse_script",
]

# Weight of a new wall-based hallway direction in the smoothed direction estimate [-].
_AXIS_SMOOTHING = 0.3
# A robot that moved less than this in one control period has stopped [m].
_SETTLED_STEP_M = 0.002
# Stall detection: below this commanded speed nothing is expected to move [m/s]; progress in a
# control period under this fraction of (commanded speed x period) counts as no progress [-].
_STALL_MIN_SPEED_MPS = 0.1
_STALL_PROGRESS_FRACTION = 0.2
# Half-width of the sector behind the robot whose echoes limit backing off [rad]; backing that
# has not covered backoff_m in this many times the time it needs has stalled too [-].
_REAR_HALF_RAD = math.radians(35.0)
_BACKOFF_TIME_FACTOR = 3.0
# Largest disagreement [rad] between the wall-based and the held hallway direction still trusted.
_AXIS_TRUST_RAD = math.radians(25.0)
# The twist of a step that only changes state (stop, settle, decide) [m/s, rad/s].
_STOP = (0.0, 0.0)


class FollowerState(StrEnum):
    FOLLOW = "follow"
    ADVANCE = "advance"  # driving on to the middle of the chosen side hallway
    TURN = "turn"  # rotating in place to a target odometric heading
    ENTER = "enter"  # driving into the new hallway before following it
    BACK_OFF = "back_off"  # backing straight away from where it stalled
    PAUSED = "paused"


_TURN_ANGLE_RAD = {
    TurnChoice.LEFT: math.pi / 2.0,
    TurnChoice.RIGHT: -math.pi / 2.0,
    TurnChoice.BACK: math.pi,
    TurnChoice.STRAIGHT: 0.0,
}
_LEFT_ORDER = (TurnChoice.LEFT, TurnChoice.STRAIGHT, TurnChoice.RIGHT, TurnChoice.BACK)
_RIGHT_ORDER = (TurnChoice.RIGHT, TurnChoice.STRAIGHT, TurnChoice.LEFT, TurnChoice.BACK)


def _rear_m(ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike) -> float:
    """The nearest echo behind the robot (within _REAR_HALF_RAD of its back) [m]."""
    r = np.asarray(ranges_m, dtype=np.float64)
    behind = np.abs(wrap_angles(np.asarray(angles_rad, dtype=np.float64) - math.pi))
    rear = r[(behind <= _REAR_HALF_RAD) & np.isfinite(r)]
    return float(rear.min()) if rear.size else math.inf


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
        self._backoff_from_m = 0.0  # travel when backing off started [m]
        self._backoff_since_s = 0.0
        self._blocked_next = False  # after backing off: decide as at a wall ahead
        self._record = StrategyRecorder()

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
            self._stall_since = None  # the pause is not time spent stuck
            self._blocked_next = False
            self._last_t = None
            self._last_v = 0.0
            for side in self._armed:
                self._armed[side] = False
                self._closed_since[side] = math.nan
                self._open_since[side] = math.nan
        if not enabled and self._enabled:
            self._record.close_rotation(self._heading)
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
        self._record.reset(self._heading)

    def strategy(self) -> ControlStrategy:
        """What was executed since the start or the last reset, e.g. `Go 125, Rot 270, Go 652`."""
        return self._record.strategy(self._heading)

    @property
    def _heading(self) -> float | None:
        """The last odometric heading [rad]; None before the first pose (since resuming)."""
        return self._last_pose.theta if self._last_pose is not None else None

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
        if self._state is FollowerState.BACK_OFF:
            self._last_t = t_s
            return self._step_back_off(ranges_m, angles_rad, t_s)
        stalled = self._stalled(t_s)
        self._last_t = t_s
        if stalled:
            self.stalls += 1
            self._stall_since = None
            if self.config.backoff_m > 0.0 and self.config.backoff_speed_mps > 0.0:
                self._start_back_off(t_s)
                return _STOP
            self._blocked_next = True
        if self._blocked_next:
            self._blocked_next = False
            p = dataclasses.replace(p, front_m=0.0)  # blocked by something the sonar missed
        v, w = self._control(p, odom_pose, t_s)
        self._last_v = v
        return v, w

    def _start_back_off(self, t_s: float) -> None:
        """Stalled: back straight away (what the stalled state had planned is dropped)."""
        self._state = FollowerState.BACK_OFF
        self._pending = None
        self._backoff_from_m = self._travel_m
        self._backoff_since_s = t_s

    def _step_back_off(self, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike, t_s: float
                       ) -> tuple[float, float]:
        """BACK_OFF: reverse until backoff_m is covered, a wall is near behind, or backing
        makes no progress; then FOLLOW, deciding as at a wall ahead."""
        c = self.config
        backed = self._travel_m - self._backoff_from_m
        overdue = c.backoff_speed_mps <= 0.0 or t_s - self._backoff_since_s > (  # set live
            _BACKOFF_TIME_FACTOR * (c.backoff_m / c.backoff_speed_mps + c.stall_time_s))
        if backed >= c.backoff_m or _rear_m(ranges_m, angles_rad) <= c.stop_distance_m or overdue:
            self._state = FollowerState.FOLLOW
            self._blocked_next = True
            self._last_v = 0.0
            return _STOP
        self._last_v = -c.backoff_speed_mps
        return -c.backoff_speed_mps, 0.0

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
        """One step of the state machine. TURN rotates (and ends in ENTER); ADVANCE turns at the
        side hallway's middle or cancels (back to FOLLOW, which may decide at once); ENTER ends
        in FOLLOW; FOLLOW may decide. A step that started a turn stops; the others drive."""
        if not self._started:
            self._started = True
            self._axis = odom_pose.theta
        self._track_hallway(p, odom_pose)
        self._track_sides(p)
        if self._state is FollowerState.TURN:
            return self._step_turn(odom_pose)
        if self._state is FollowerState.ADVANCE and self._step_advance(p, odom_pose):
            return _STOP
        if self._state is FollowerState.ENTER:
            self._step_enter(p)
        if self._state is FollowerState.FOLLOW and self._step_follow(p, odom_pose, t_s):
            return _STOP
        return self._drive(p, odom_pose)

    def _track_hallway(self, p: Perception, odom_pose: Pose2D) -> None:
        """Between two closed sides while following: update the hallway's direction (odometry
        frame, smoothed, only from walls that agree with it) and its width."""
        in_hall = (
            self._state is FollowerState.FOLLOW and not p.left_open and not p.right_open
        )
        if not in_hall:
            return
        if p.wall_angle_rad is not None:
            axis = wrap_angle(odom_pose.theta + p.wall_angle_rad)
            if abs(wrap_angle(axis - self._axis)) < _AXIS_TRUST_RAD:
                step = _AXIS_SMOOTHING * wrap_angle(axis - self._axis)
                self._axis = wrap_angle(self._axis + step)
        if math.isfinite(p.left_dist_m) and math.isfinite(p.right_dist_m):
            self._hall_width_m = p.left_dist_m + p.right_dist_m

    def _step_turn(self, odom_pose: Pose2D) -> tuple[float, float]:
        """TURN: wait until the robot stands still (that roll is part of the Go), then rotate
        in place to the target heading; there, ENTER the new hallway along it."""
        c = self.config
        if self._settling:
            if self._last_step_m > _SETTLED_STEP_M:
                return _STOP  # still rolling to a stop: that travel belongs to the Go
            self._settling = False
            self._record.close_go()
            self._record.start_rotation(odom_pose.theta)
        err = wrap_angle(self._turn_target - odom_pose.theta)
        if abs(err) <= math.radians(c.turn_tolerance_deg):
            self._record.close_rotation(self._heading)
            self._state = FollowerState.ENTER
            self._axis = self._turn_target
            self._enter_until_m = self._travel_m + c.enter_distance_m
            return _STOP
        w = c.k_heading * err
        w = math.copysign(min(max(abs(w), c.min_turn_rate_radps), c.max_turn_rate_radps), err)
        return 0.0, w

    def _step_advance(self, p: Perception, odom_pose: Pose2D) -> bool:
        """ADVANCE: cancel if the chosen side closed again; start the turn at the side hallway's
        middle (or before a wall ahead). True when the turn started."""
        c = self.config
        side = self._pending
        assert side is not None
        still_open = p.left_open if side is TurnChoice.LEFT else p.right_open
        if not still_open:
            self._cancel_advance()
            return False
        at_turn = self._travel_m >= self._advance_until_m or p.front_m <= max(
            c.stop_distance_m, 0.5 * self._hall_width_m
        )
        if at_turn:
            self._start_turn(side, odom_pose)
        return at_turn

    def _cancel_advance(self) -> None:
        """The opening closed before its middle: a door, not a hallway. Follow on (a scripted
        turn is kept for the next opening)."""
        self.cancelled_turns += 1
        if self._script_active and self.decisions:
            self._script.insert(0, self.decisions[-1].choice)
        self._state = FollowerState.FOLLOW
        self._pending = None

    def _step_enter(self, p: Perception) -> None:
        """ENTER: follow again after `enter_distance_m` into the new hallway (or at a wall)."""
        if self._travel_m >= self._enter_until_m or p.front_m <= self.config.stop_distance_m:
            self._state = FollowerState.FOLLOW

    def _step_follow(self, p: Perception, odom_pose: Pose2D, t_s: float) -> bool:
        """FOLLOW: at an opening or a wall ahead, decide. A side turn with room ahead first
        ADVANCEs to the side hallway's middle; back (or a side turn at a wall) turns at once.
        True when the turn started."""
        choice = self._maybe_decide(p, odom_pose, t_s)
        if choice is None or choice is TurnChoice.STRAIGHT:
            return False
        side_turn = choice in (TurnChoice.LEFT, TurnChoice.RIGHT)
        if side_turn and p.front_m > self.config.stop_distance_m:
            self._start_advance(choice)
            return False
        self._start_turn(choice, odom_pose)
        return True

    def _start_advance(self, side: TurnChoice) -> None:
        """Drive on to the estimated middle of the side hallway that opened on `side`."""
        c = self.config
        self._pending = side
        self._state = FollowerState.ADVANCE
        opened_at = self._open_since[side]
        if math.isnan(opened_at):
            opened_at = self._travel_m
        advance = max(c.min_advance_m, 0.5 * self._hall_width_m - c.side_lag_m)
        self._advance_until_m = opened_at + advance

    @property
    def _script_active(self) -> bool:
        return self.config.policy is TurnPolicy.SCRIPTED

    def _track_motion(self, pose: Pose2D) -> None:
        self._last_step_m = 0.0
        if self._last_pose is not None:
            d = math.hypot(pose.x - self._last_pose.x, pose.y - self._last_pose.y)
            self._last_step_m = d
            self._travel_m += d
            if self._state is FollowerState.BACK_OFF:
                self._record.add_travel(-d)  # backing along the Go undoes part of it
            elif self._state is not FollowerState.TURN or self._settling:
                self._record.add_travel(d)
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
