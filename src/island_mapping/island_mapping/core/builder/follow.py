"""When an attempt may start while the hall follower drives: after the retry distance, once the
follower has settled after a turn, and, while the quick check's measure still rises, deferred
(up to defer_max_m, or defer_timeout_s once the robot stopped)."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

from island_msgs_py.types import ControlStrategy, FloatArray, PrimitiveKind

from island_mapping.core.builder.config import BuilderConfig
from island_mapping.core.builder.epsilon import eq3_bound


def follower_turning(strategy: ControlStrategy) -> bool:
    """Is the hall follower's latest primitive a turn (it records turns as they go on)?"""
    steps = strategy.steps
    return bool(steps) and steps[-1].kind is PrimitiveKind.ROT


def follower_settled(strategy: ControlStrategy, settled_go_m: float) -> bool:
    """True unless the hall follower is turning or has not yet gone `settled_go_m` [m]
    straight since its last turn (from the strategy it reports; an empty record counts as
    settled; settled_go_m 0 = always settled)."""
    steps = strategy.steps
    if not steps or settled_go_m <= 0:
        return True
    if follower_turning(strategy):
        return False
    last = steps[-1]
    turned_before = any(s.kind is PrimitiveKind.ROT for s in steps[:-1])
    return not turned_before or last.metres >= settled_go_m


def straight_behind_m(strategy: ControlStrategy) -> float:
    """The straight path the follower reported driving last (its record ends in a Go) [m]."""
    steps = strategy.steps
    if steps and steps[-1].kind is PrimitiveKind.GO:
        return steps[-1].metres
    return 0.0


@dataclass
class FollowGate:
    """Where the next quick check may happen and the deferral under way.

    retry_at_path_m: no quick check before the follower's path reaches this [m];
    defer_prev: the quick measure at the last deferral (None: not deferring); defer_m: path
    deferred so far [m]; defer_t_s: time of the last deferral [s].
    """

    retry_at_path_m: float = 0.0
    defer_prev: float | None = None
    defer_m: float = 0.0
    defer_t_s: float = 0.0

    def stalled(self, t_s: float, cfg: BuilderConfig) -> bool:
        """Deferring, but the next check has not come for defer_timeout_s (the robot
        stopped)?"""
        return self.defer_prev is not None and t_s - self.defer_t_s > cfg.defer_timeout_s

    def end_deferral(self) -> None:
        self.defer_prev, self.defer_m = None, 0.0

    def retry_after(self, path_m: float, distance_m: float) -> None:
        """No quick check before distance_m more path [m]."""
        self.retry_at_path_m = path_m + distance_m

    def defer(self, quick: float, t_s: float, path_m: float, cfg: BuilderConfig) -> bool:
        """Keep following (True) while the quick measure still rises and the deferral has not
        gone defer_max_m: the place is getting better as the robot goes on."""
        rising = self.defer_prev is None or quick > self.defer_prev * (
            1.0 + cfg.defer_rise_fraction
        )
        if not (cfg.defer_while_rising and rising and self.defer_m < cfg.defer_max_m):
            return False
        self.defer_prev = quick
        self.defer_t_s = t_s
        self.defer_m += cfg.defer_step_m
        self.retry_at_path_m = path_m + cfg.defer_step_m
        return True


@dataclass
class ScanHistory:
    """Scan points (odometry frame) seen over the last stretch of path while following: the
    quick check's (`quick`, quick_history_m) and recognition's (`revisit`, revisit.history_m:
    near echoes only, kept while following)."""

    quick: deque[tuple[float, FloatArray]] = field(default_factory=deque)
    revisit: deque[tuple[float, FloatArray]] = field(default_factory=deque)

    def add(self, path_m: float, points: FloatArray, near: FloatArray, following: bool,
            cfg: BuilderConfig) -> None:
        """A scan's points and near echoes seen at path length path_m [m]."""
        _keep(self.quick, path_m, points, cfg.quick_history_m)
        if following:
            _keep(self.revisit, path_m, near, cfg.revisit.history_m)

    def quick_points(self) -> list[FloatArray]:
        return [p for _, p in self.quick]

    def revisit_points(self) -> list[FloatArray]:
        return [p for _, p in self.revisit]


def _keep(history: deque[tuple[float, FloatArray]], path_m: float, points: FloatArray,
          length_m: float) -> None:
    """Append `points` seen at path_m and drop what lies more than length_m of path behind."""
    history.append((path_m, points))
    while history and history[0][0] < path_m - length_m:
        history.popleft()


class FollowStep(StrEnum):
    """What the builder does while the follower drives."""

    FOLLOW = "follow"  # keep following (nothing to do, deferred, or docking onto a revisit)
    FAIL_AT_ONCE = "fail_at_once"  # the quick check is out of reach: a dot in Fig. 4a
    ATTEMPT = "attempt"  # start a star here


@dataclass(frozen=True)
class Following:
    """The robot while the follower drives: epsilon_m [m], time t_s [s], path_m followed [m],
    the follower's record, whether it is within vicinity_m of the last island."""

    epsilon_m: float
    t_s: float
    path_m: float
    strategy: ControlStrategy
    near_last_island: bool
    at_opening: bool = False
    in_hallway: bool = True  # the quick check may start an attempt here
    in_room: bool = False  # long enough along a room's walls: here too


def follow_step(
    gate: FollowGate, cfg: BuilderConfig, now: Following, quick: Callable[[], float],
    try_revisit: Callable[[], bool],
) -> tuple[FollowStep, float]:
    """Whether to attempt an island (eq. 3: epsilon > E_min), and the quick check's measure.

    Not before retry_distance_m after the last attempt, nor before the follower has settled
    after a turn, nor near the last island. Then `quick()` (the best normalized measure of the
    last quick_history_m of points at the robot): below quick_reject_fraction of the bound the
    attempt fails at once; otherwise `try_revisit()` (a known island here: the robot docks) and,
    while the measure still rises, defer. A deferral that stalls (the robot stopped) attempts
    there once the follower is not turning."""
    if now.epsilon_m <= cfg.e_min_m:
        return FollowStep.FOLLOW, 0.0
    stalled = gate.stalled(now.t_s, cfg)
    if stalled and follower_turning(now.strategy):
        return FollowStep.FOLLOW, 0.0  # anchored mid-turn, theta 0 would lie across a hallway
    if stalled:  # deferring, but the robot stopped moving on: attempt here
        gate.end_deferral()
        return (FollowStep.FOLLOW if try_revisit() else FollowStep.ATTEMPT), 0.0
    if now.path_m < gate.retry_at_path_m or not follower_settled(
        now.strategy, cfg.settled_go_m
    ) or now.near_last_island:
        return FollowStep.FOLLOW, 0.0
    if now.at_opening:  # the place's good point is in the opening, not at the robot
        gate.end_deferral()
        return (FollowStep.FOLLOW if try_revisit() else FollowStep.ATTEMPT), 0.0
    if not (now.in_hallway or now.in_room):
        return FollowStep.FOLLOW, 0.0
    q = quick()
    if q < cfg.quick_reject_fraction * eq3_bound(cfg, now.epsilon_m):
        gate.end_deferral()
        gate.retry_after(now.path_m, cfg.retry_distance_m)
        return FollowStep.FAIL_AT_ONCE, q
    if try_revisit():  # a place worth an island: is it one the robot already has?
        gate.end_deferral()
        return FollowStep.FOLLOW, q
    if gate.defer(q, now.t_s, now.path_m, cfg):
        return FollowStep.FOLLOW, q  # the place is getting better as the robot goes on
    gate.end_deferral()
    return FollowStep.ATTEMPT, q
