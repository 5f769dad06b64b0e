"""The record of an executed control strategy: the paper's Table 1 primitives.

`StrategyRecorder` accumulates odometric travel as Go [cm] and odometric rotation as
Rot [deg CCW, 0-360); consecutive primitives of one kind merge. The hall follower feeds it.
Headings are odometric [rad]; `None` means no pose has been seen yet (nothing to measure from).
"""

from __future__ import annotations

import math

from island_msgs_py.types import (
    ControlStrategy,
    PrimitiveKind,
    StrategyPrimitive,
    wrap_angle,
)


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


class StrategyRecorder:
    """Go and Rot primitives executed since the start or the last `reset`."""

    def __init__(self) -> None:
        self._steps: list[StrategyPrimitive] = []
        self._go_m = 0.0  # travel not yet closed into a Go [m]
        self._rot_rad = 0.0  # rotation not yet closed into a Rot [rad]
        self._rot_start: float | None = None  # heading a rotation in progress started at [rad]

    def add_travel(self, distance_m: float) -> None:
        """Odometric travel [m] that belongs to the current Go."""
        self._go_m += distance_m

    def close_go(self) -> None:
        """End the current Go (its travel becomes a step)."""
        _append(self._steps, PrimitiveKind.GO, self._go_m)
        self._go_m = 0.0

    def start_rotation(self, heading_rad: float) -> None:
        """A rotation in place starts at `heading_rad`: what it turns is measured from there."""
        self._rot_start = heading_rad

    def close_rotation(self, heading_rad: float | None) -> None:
        """End the rotation in progress at `heading_rad` (its turn becomes a step)."""
        if self._rot_start is not None and heading_rad is not None:
            self._rot_rad += wrap_angle(heading_rad - self._rot_start)
        self._rot_start = None
        _append(self._steps, PrimitiveKind.ROT, self._rot_rad)
        self._rot_rad = 0.0

    def reset(self, heading_rad: float | None) -> None:
        """Forget the record; a rotation in progress is measured on from `heading_rad`."""
        self._steps = []
        self._go_m = 0.0
        self._rot_rad = 0.0
        if self._rot_start is not None and heading_rad is not None:
            self._rot_start = heading_rad

    def strategy(self, heading_rad: float | None) -> ControlStrategy:
        """The record, including the Go and the rotation in progress (up to `heading_rad`)."""
        steps = list(self._steps)
        rot = self._rot_rad
        if self._rot_start is not None and heading_rad is not None:
            rot += wrap_angle(heading_rad - self._rot_start)
        _append(steps, PrimitiveKind.ROT, rot)
        _append(steps, PrimitiveKind.GO, self._go_m)
        return ControlStrategy(tuple(steps))
