"""How the robot leaves an island by an exit: along a free lane planned on what it sees now.

At the island's origin the explorer has just looked around (docking, or the builder's star), so
its recent echoes and the island's line model say where the free lanes are (`exits.free_lanes`,
in the island frame). The lane whose entry heading lies nearest the exit's heading (within
merge_deg) is driven: sideways to where it leaves the origin's line (when that is more than
`lane_snap_m` off), then along it; a lane narrower than `door_max_width_m` (a doorway) is driven
`door_through_m` into before the hall follower takes over. No such lane: the robot turns to the
exit's heading and passes the doorway it leads to (`core.explore.doorway`: a look finds the
doorway's wall and jambs; with `doorway.enabled` off, it drives along the exit as route
following drives a Go; `drive_departure`). Everything in the island frame [m, rad].
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass

import numpy as np
from island_msgs_py.hall_perception import HallPerceptionConfig, perceive
from island_msgs_py.types import Exit, FloatArray, LineModel, Pose2D, wrap_angle

from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.explore.doorway import pass_doorway
from island_mapping.core.explore.exits import ExitEvidence, Lane, free_lanes
from island_mapping.core.route import Command, Drive, go_along_hall, go_to, rotate_to

STOP: Command = (0.0, 0.0)
"""Stand still (v, w)."""


@dataclass(frozen=True)
class DeparturePlan:
    """Drive to each waypoint, turn to heading_rad, then (a doorway) drive to `through`;
    `lane` is the lane chosen (None: the exit's heading alone)."""

    waypoints: tuple[Pose2D, ...]
    heading_rad: float
    through: Pose2D | None = None
    lane: Lane | None = None


def choose_lane(lanes: list[Lane], ex: Exit, cfg: ExplorerConfig) -> Lane | None:
    """The lane whose entry heading is nearest the exit's (within merge_deg), the wider one
    on a tie. A lane must also run along the exit (its heading within merge_deg of the
    exit's) or along an island axis (a side corridor entered from an offset): a diagonal lane
    whose entry happens to lie toward the exit would hand the robot over facing across the
    hallway, where the hall follower takes that diagonal for the hallway's axis."""
    best: tuple[float, float, Lane] | None = None
    merge = math.radians(cfg.exit.merge_deg)
    for lane in lanes:
        if lane.width_m < cfg.exit.min_width_m:
            continue
        if abs(wrap_angle(lane.heading_rad - ex.heading_rad)) > merge and not _on_axis(
                lane.heading_rad, cfg):
            continue
        ex_, ey = lane.entry(cfg.exit.entry_m)
        off = abs(wrap_angle(math.atan2(ey, ex_) - ex.heading_rad))
        if off > merge:
            continue
        key = (round(off, 3), -lane.width_m)
        if best is None or key < best[:2]:
            best = (key[0], key[1], lane)
    return None if best is None else best[2]


def _on_axis(heading_rad: float, cfg: ExplorerConfig) -> bool:
    """Within half a lane heading step of one of the island's axes."""
    quarter = 0.5 * math.pi
    off = abs(heading_rad - quarter * round(heading_rad / quarter))
    return off <= 0.5 * math.radians(cfg.exit.heading_step_deg)


def plan_departure(model: LineModel, ex: Exit, points: FloatArray, cfg: ExplorerConfig
                   ) -> DeparturePlan:
    """The departure by exit `ex` of an island whose model is `model`, with the echoes seen
    lately `points` (M, 2) in the island frame (module docstring)."""
    lanes = free_lanes(ExitEvidence(model.segments, points, np.zeros((0, 4))), cfg.exit)
    lane = choose_lane(lanes, ex, cfg)
    if lane is None:
        return DeparturePlan((), ex.heading_rad)
    h = lane.heading_rad
    sx, sy = lane.entry(0.0)
    waypoints = () if abs(lane.offset_m) <= cfg.lane_snap_m else (Pose2D(sx, sy, h),)
    through = None
    if lane.width_m <= cfg.door_max_width_m:
        d = cfg.door_through_m
        through = Pose2D(sx + d * math.cos(h), sy + d * math.sin(h), h)
    return DeparturePlan(waypoints, h, through, lane)


def go_clear(d: Drive, target_odom: Pose2D) -> Generator[Command, None, None]:
    """`go_to` the odometric pose, stopping short where the sonar shows a wall closer ahead
    than the route's stop_distance_m (a waypoint planned on a sparse model can lie at a wall:
    driving on would touch it)."""
    motion = go_to(d, target_odom)
    for cmd in motion:
        if cmd[0] > 0.0 and perceive(d.sense.ranges_m, d.sense.angles_rad,
                                     d.perception).front_m < d.cfg.stop_distance_m:
            motion.close()
            yield STOP
            return
        yield cmd


def drive_departure(d: Drive, plan: DeparturePlan, origin_odom: Pose2D, cfg: ExplorerConfig,
                    perception: HallPerceptionConfig) -> Generator[Command, None, bool]:
    """Drive `plan` from the island whose origin odometry puts at `origin_odom`: its waypoints
    and the turn to its heading; there, with less than depart_min_free_m free ahead, back to
    the origin and False. Then through its doorway (`plan.through`), or, where no lane was
    seen, by `go_along_hall` along the heading to the opening's entry (exit.entry_m) and
    door_through_m on: a doorway the sonar's wide cones show too narrow for a lane is still
    found by its jambs and passed at its middle (the hall follower would take the jambs for a
    wall ahead), so with no lane only the range straight ahead must be free. True: the robot
    has left."""
    for p in plan.waypoints:
        yield from go_clear(d, origin_odom.compose(p))
    yield from rotate_to(d, wrap_angle(origin_odom.theta + plan.heading_rad))
    seen = perceive(d.sense.ranges_m, d.sense.angles_rad, perception)
    if (seen.front_m if plan.lane is not None else seen.front_free_m) < cfg.depart_min_free_m:
        yield from go_clear(d, origin_odom)
        return False
    if plan.through is not None:
        yield from go_clear(d, origin_odom.compose(plan.through))
    elif plan.lane is None and cfg.doorway.enabled:
        yield from pass_doorway(d, d.sense.odom.theta, cfg.doorway,
                                cfg.exit.entry_m + cfg.door_through_m, cfg.door_through_m)
    elif plan.lane is None:
        yield from go_along_hall(d, cfg.exit.entry_m + cfg.door_through_m)
    return True
