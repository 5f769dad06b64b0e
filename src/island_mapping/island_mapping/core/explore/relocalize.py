"""Finding the island again after a way back that did not localize (`core.explore.mission`).

A return (or retreat) drives the way out reversed and localizes at the island left within
`return_max_shift_m` of where odometry says the robot is. After a long way out odometry can
be farther off than that while the robot still stands at the island's place: handing it over
as lost then builds a second island there, and the wander that follows recognises nothing it
can trust. Instead the robot looks once more, accepts a fit up to `relocalize_max_shift_m`
from odometry's estimate only as a hypothesis, drives to the origin that fit shows, and
localizes there again within `return_max_shift_m`: two looks from two places must agree
before it calls itself docked.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Generator

from island_msgs_py.types import Island, Pose2D

from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.explore.departure import go_clear
from island_mapping.core.route import (
    Command,
    Drive,
    Fix,
    localize_and_dock,
    localize_multi,
    look_around,
)


def relocalize(d: Drive, island: Island, origin_odom: Pose2D, cfg: ExplorerConfig,
               on_fix: Callable[[Fix], None] | None = None
               ) -> Generator[Command, None, Fix | None]:
    """Look for `island` near `origin_odom` (its origin as odometry last had it; driven to
    first when the robot is farther from it than return_max_shift_m) and dock (module
    docstring); the docking fix (trusted or not), or None when the first look found
    no hypothesis (nothing is reported to `on_fix` then). Raises RouteTimeoutError past the
    drive's deadline."""
    if cfg.relocalize_max_shift_m <= cfg.return_max_shift_m:
        return None
    near = d.sense.odom.relative_to(origin_odom)
    if math.hypot(near.x, near.y) > cfg.return_max_shift_m:
        # The way back ended short of the origin (a wall ahead, a lap cut): what is seen from
        # the origin holds the place's own walls, not only a hallway's.
        yield from go_clear(d, origin_odom)
    pts = yield from look_around(d)
    near = d.sense.odom.relative_to(origin_odom)
    loose = dataclasses.replace(d.cfg, max_turn_deg=cfg.relocalize_max_turn_deg,
                                max_residual_m=cfg.relocalize_max_residual_m)
    res, trusted = localize_multi(island, pts, near, loose, cfg.relocalize_max_shift_m)
    if not trusted:
        return None
    origin = d.sense.odom.compose(res.pose.inverse())  # where this look puts the origin
    yield from go_clear(d, origin)
    here = d.sense.odom.relative_to(origin)
    return (yield from localize_and_dock(d, island, here, on_fix, cfg.return_max_shift_m))
