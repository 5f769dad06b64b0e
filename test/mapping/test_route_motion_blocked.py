"""Motion primitives stop where the robot is blocked (a wall the sonar missed, e.g. a door
jamb beside the robot), after backing off and trying again a few times, instead of pushing
until the edge's time limit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.route import Drive, NavigateConfig, Sense, go_along_hall
from island_msgs_py.types import Pose2D

ANGLES = np.linspace(-math.pi, math.pi, 16, endpoint=False)


def _run(wall_at_m: float | None, retries: int = 2) -> tuple[int, int, float]:
    """(periods, back-offs, how far it got [m]) of go_along_hall(2 m) on a robot moving
    0.04 m per period forward (0.015 m back), held by a wall ahead at wall_at_m (a contact the
    sonar missed: a door jamb beside)."""
    sense = Sense(0.0, Pose2D(0.0, 0.0, 0.0), np.full(16, np.inf), ANGLES)
    motion = go_along_hall(Drive(sense, NavigateConfig(contact_retries=retries)), 2.0)
    periods = backoffs = 0
    backing = False
    for v, _w in motion:
        periods += 1
        x = sense.odom.x
        step_m = 0.04 if v > 0 else -0.015 if v < 0 else 0.0
        held = wall_at_m is not None and v > 0 and x + step_m > wall_at_m
        backoffs += v < 0 and not backing
        backing = v < 0
        sense.t_s += 0.1
        sense.odom = Pose2D(x if held else x + step_m, 0.0, 0.0)
        sense.blocked = held
        assert periods < 10_000, "never stopped"
    return periods, backoffs, sense.odom.x


def test_go_along_hall_backs_off_a_contact_then_stops_there() -> None:
    free, backoffs, got = _run(None)
    assert free > 40 and backoffs == 0 and got == pytest.approx(2.0, abs=0.05)
    periods, backoffs, got = _run(0.4)
    assert backoffs == 2  # contact_retries: backed off and went on twice
    assert got <= 0.4 and periods < 100  # then stopped at the wall, not pushing on
    assert _run(0.4, retries=0)[1] == 0  # no retries: stops at the first contact
