"""The explorer's own driving, recorded as control-strategy primitives (paper Table 1).

Like the hall follower's record: travel is `Go` [cm] of odometric distance, rotation in place is
`Rot` [deg CCW]; turning while driving is not recorded (a Go follows the hallway). The explorer
hands the record of its departure (turn to an exit, drive through a door) to the builder as the
prefix of the next edge's strategy.
"""

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

from island_mapping.core.graph import normalize_strategy

IN_PLACE_M = 0.004
"""A sensor period moving less than this is a rotation in place (or standing) [m]."""


class MotionRecord:
    """Rot/Go steps of the motion since `start` (odometry poses fed once per sensor period)."""

    def __init__(self, start: Pose2D) -> None:
        self._last = start
        self._steps: list[StrategyPrimitive] = []
        self._go_m = 0.0
        self._rot_rad = 0.0

    def update(self, pose: Pose2D, counted: bool = True) -> None:
        """The odometric pose now [m, rad]; counted False: the motion since the last pose was
        someone else's (not recorded)."""
        if not counted:
            self._last = pose
            return
        ds = math.hypot(pose.x - self._last.x, pose.y - self._last.y)
        if ds < IN_PLACE_M:
            if self._go_m > 0.0:
                self._flush_go()
            self._rot_rad += wrap_angle(pose.theta - self._last.theta)
        else:
            if self._rot_rad != 0.0:
                self._flush_rot()
            self._go_m += ds
        self._last = pose

    def _flush_go(self) -> None:
        self._steps.append(StrategyPrimitive(PrimitiveKind.GO, round(100.0 * self._go_m)))
        self._go_m = 0.0

    def _flush_rot(self) -> None:
        deg = round(math.degrees(wrap_angle(self._rot_rad))) % 360
        self._steps.append(StrategyPrimitive(PrimitiveKind.ROT, deg))
        self._rot_rad = 0.0

    def strategy(self) -> ControlStrategy:
        """The record so far (normalized: no zero steps, neighbours of a kind merged)."""
        steps = list(self._steps)
        if self._rot_rad != 0.0:
            steps.append(StrategyPrimitive(
                PrimitiveKind.ROT, round(math.degrees(wrap_angle(self._rot_rad))) % 360))
        if self._go_m > 0.0:
            steps.append(StrategyPrimitive(PrimitiveKind.GO, round(100.0 * self._go_m)))
        return normalize_strategy(ControlStrategy(tuple(steps)))


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
