"""The explorer's own driving, recorded as control-strategy primitives (paper Table 1).

Like the hall follower's record: travel is `Go` [cm] of odometric distance, rotation in place is
`Rot` [deg CCW]; turning while driving is not recorded (a Go follows the hallway). The explorer
hands the record of its departure (turn to an exit, drive through a door) to the builder as the
prefix of the next edge's strategy.
"""

from __future__ import annotations

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
