"""The island builder's states (`core.builder.machine` describes the transitions)."""

from __future__ import annotations

from enum import StrEnum


class State(StrEnum):
    WAITING = "waiting"  # no odometry/scan yet
    FOLLOWING = "following"
    STAR = "star"
    RETURNING = "returning"  # back to the origin, facing theta 0, then hand back
    DOCKING = "docking"  # onto a recognised island's origin, then hand back
    PROBING = "probing"  # to an origin past the star's legs: look around there, verify it
    ENTERING = "entering"  # into a side opening the robot passed, to attempt inside it
    LEAVING = "leaving"  # back out of it to where the follower stopped (attempt dismissed)
    IDLE = "idle"  # managed mode: at an island, the explorer drives (core.builder.hooks)
    HELD = "held"  # managed mode: a star's decision waits for the explorer (core.builder.held)
