"""The algebra of control strategies (paper Table 1): normalize, reverse, ideal displacement,
loops cut out."""

from __future__ import annotations

import itertools
import math

from island_msgs_py.types import (
    ControlStrategy,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
    wrap_angle,
)

TURN_AROUND_DEG = 180  # the reverse of a strategy starts and ends with a half turn
FULL_TURN_DEG = 360


def normalize_strategy(strategy: ControlStrategy) -> ControlStrategy:
    """Drop Go 0 and Rot 0, merge consecutive rotations (mod 360) and consecutive Go steps."""
    steps: list[StrategyPrimitive] = []
    for s in strategy.steps:
        if s.value == 0:
            continue
        if steps and steps[-1].kind is s.kind:
            value = steps.pop().value + s.value
            if s.kind is PrimitiveKind.ROT:
                value %= FULL_TURN_DEG
            if value == 0:
                continue
            s = StrategyPrimitive(s.kind, value)
        steps.append(s)
    return ControlStrategy(tuple(steps))


def reverse_strategy(strategy: ControlStrategy) -> ControlStrategy:
    """The strategy that drives back from the target origin (heading 0) to the source origin.

    Turn around (Rot 180), replay the steps in reverse order with Go unchanged and every
    Rot a replaced by Rot (360 - a) % 360, then turn around again (Rot 180) so the robot faces
    the source frame's heading 0. Adjacent rotations are merged (`normalize_strategy`), so
    reversing twice gives back the normalized strategy.
    """
    turn = StrategyPrimitive(PrimitiveKind.ROT, TURN_AROUND_DEG)
    mirrored = [
        StrategyPrimitive(
            s.kind,
            (FULL_TURN_DEG - s.value) % FULL_TURN_DEG if s.kind is PrimitiveKind.ROT else s.value,
        )
        for s in reversed(strategy.steps)
    ]
    return normalize_strategy(ControlStrategy((turn, *mirrored, turn)))


def strategy_displacement(strategy: ControlStrategy) -> Pose2D:
    """Where the strategy ends, in the frame it starts from (ideal execution) [m, rad]."""
    pose = Pose2D(0.0, 0.0, 0.0)
    for s in strategy.steps:
        pose = pose.compose(Pose2D(s.metres, 0.0, s.radians))
    return pose


_SAMPLE_M = 0.25  # spacing of the points a path is compared at (`without_loops`) [m]


def _path_points(strategy: ControlStrategy) -> tuple[list[tuple[float, float]], float]:
    """The ideal execution's points, every _SAMPLE_M along each Go (and each Go's end), from
    (0, 0) heading 0 [m]; and the final heading [rad]."""
    pose = Pose2D(0.0, 0.0, 0.0)
    pts = [(0.0, 0.0)]
    for s in strategy.steps:
        if s.kind is PrimitiveKind.ROT:
            pose = pose.compose(Pose2D(0.0, 0.0, s.radians))
            continue
        n = max(1, math.ceil(s.metres / _SAMPLE_M))
        for k in range(1, n + 1):
            p = pose.compose(Pose2D(s.metres * k / n, 0.0, 0.0))
            pts.append((p.x, p.y))
        pose = pose.compose(Pose2D(s.metres, 0.0, 0.0))
    return pts, pose.theta


def without_loops(strategy: ControlStrategy, within_m: float, min_loop_m: float
                  ) -> ControlStrategy:
    """`strategy` with the loops it drove cut out: wherever its ideal execution comes back
    within within_m [m] of a point it passed at least min_loop_m [m] of path earlier, the
    stretch between is dropped and the two points are joined straight. The result ends where
    `strategy` ends, with its heading; `strategy` itself when nothing is cut (or within_m is
    0). A hall follower sent round a room records laps; driven back, each lap costs time and
    odometric error for nothing."""
    if within_m <= 0.0:
        return strategy
    pts, end_theta = _path_points(strategy)
    xy = [complex(x, y) for x, y in pts]
    skip = max(1, math.ceil(min_loop_m / _SAMPLE_M))
    kept, i, cut = [xy[0]], 0, False
    while i < len(xy) - 1:
        j = next((j for j in range(len(xy) - 1, i + skip - 1, -1)
                  if abs(xy[j] - xy[i]) <= within_m), None)
        if j is not None:
            cut, i = True, j
        else:
            i += 1
        kept.append(xy[i])
    if not cut:
        return strategy
    steps, heading = [], 0.0
    for a, b in itertools.pairwise(kept):
        if abs(b - a) < 1e-9:
            continue
        turn = wrap_angle(math.atan2((b - a).imag, (b - a).real) - heading)
        steps += [StrategyPrimitive(PrimitiveKind.ROT, round(math.degrees(turn)) % 360),
                  StrategyPrimitive(PrimitiveKind.GO, round(100.0 * abs(b - a)))]
        heading += turn
    steps.append(StrategyPrimitive(PrimitiveKind.ROT,
                                   round(math.degrees(wrap_angle(end_theta - heading))) % 360))
    return normalize_strategy(ControlStrategy(tuple(steps)))
