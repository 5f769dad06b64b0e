"""Docking onto a recognised island's origin: drive there by odometry, face its heading, turn a
full circle and re-localize in its model (up to revisit.dock_looks looks, until within
dock_tol_m / dock_tol_deg), re-placing the origin in the odometry frame after each look."""

from __future__ import annotations

import math
from dataclasses import dataclass

from island_msgs_py.types import Island, Pose2D

from island_mapping.core.builder import motion
from island_mapping.core.builder.config import BuilderConfig
from island_mapping.core.builder.geometry import concat, to_frame
from island_mapping.core.builder.motion import STOP, LookPhase, Twist
from island_mapping.core.localize import localize


@dataclass
class Dock(motion.Look):
    """A docking under way: the island, its origin in the odometry frame (estimated) [m, rad],
    and the looks left."""

    island: Island
    target: Pose2D
    looks_left: int


def dock_step(dock: Dock, odom: Pose2D, ahead_free_m: float, cfg: BuilderConfig) -> Twist | None:
    """The twist that goes on docking, or None when docked at dock.target (odometry pose
    `odom`; ahead_free_m: the nearest echo ahead [m])."""
    sc, rc = cfg.star, cfg.revisit
    rel = odom.relative_to(dock.target)  # the robot in the island frame
    if dock.phase is not LookPhase.LOOK:
        tol = math.radians(min(sc.heading_tol_deg, rc.dock_tol_deg))
        cmd = motion.go_align(dock, rel, tol, ahead_free_m, sc)
        if cmd is not None:
            return cmd
        if dock.looks_left <= 0:
            return None
        motion.start_look(dock, odom.theta)
    cmd = motion.look_step(dock, odom.theta, sc)  # a full circle, then localize
    if cmd is not None:
        return cmd
    dock.looks_left -= 1
    res = localize(dock.island.model, to_frame(concat(dock.points), odom), rel, cfg.localize)
    moved = math.hypot(res.pose.x - rel.x, res.pose.y - rel.y)
    if res.converged and res.residual_m <= rc.max_residual_m and moved <= rc.max_dock_m:
        dock.target = odom.compose(res.pose.inverse())
        if math.hypot(res.pose.x, res.pose.y) <= rc.dock_tol_m and abs(
            res.pose.theta
        ) <= math.radians(rc.dock_tol_deg):
            dock.looks_left = 0
    else:
        dock.looks_left = 0  # cannot do better than odometry
    dock.phase = LookPhase.GO
    return STOP
