"""Motion primitives stop where the robot is blocked (a wall the sonar missed, e.g. a door
jamb beside the robot), instead of pushing until the edge's time limit."""

from __future__ import annotations

import math

import numpy as np
from island_mapping.core.route import Drive, Sense, go_along_hall
from island_msgs_py.types import Pose2D

ANGLES = np.linspace(-math.pi, math.pi, 16, endpoint=False)


def _run(blocked_after: int | None) -> int:
    """Periods go_along_hall(2 m) drives, the robot moving 0.04 m per period until (from
    period `blocked_after` on) it is stopped by a contact."""
    sense = Sense(0.0, Pose2D(0.0, 0.0, 0.0), np.full(16, np.inf), ANGLES)
    motion = go_along_hall(Drive(sense), 2.0)
    periods = 0
    for v, _w in motion:
        periods += 1
        stopped = blocked_after is not None and periods >= blocked_after
        step_m = 0.0 if stopped else 0.04 * (v > 0)
        sense.t_s += 0.1
        sense.odom = Pose2D(sense.odom.x + step_m, 0.0, 0.0)
        sense.blocked = stopped and v > 0
        assert periods < 10_000, "never stopped"
    return periods


def test_go_along_hall_stops_at_a_contact() -> None:
    free = _run(None)
    assert free > 40  # 2 m at 0.04 m per period, slowing near the end
    assert _run(10) == 11  # the blocked period, then the stop command
