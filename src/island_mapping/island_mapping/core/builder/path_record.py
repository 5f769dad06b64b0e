"""An edge's strategy from the way the robot drove (odometry), instead of the hall follower's
own record of its primitives.

The follower records `Rot` only for its turns in place; the steering inside a `Go` (round a
corner, through a doorway at an angle, back off a wall) is not in it, and a replay of such a
record by hall centring can head somewhere else (`Rot 37, Go 816` after a doorway). Here the
odometric positions the follower drove through are kept and simplified to a polyline
(Douglas-Peucker, `tolerance_m`); each corner becomes `Rot` to the next leg's direction and each
leg a `Go` of its length, then a last `Rot` to the heading the record ends with. A way driven
out and back (a dead end) keeps its far end as a corner; a back-off along the way vanishes.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
from island_msgs_py.geometry import douglas_peucker
from island_msgs_py.types import (
    ControlStrategy,
    FloatArray,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
)

from island_mapping.core.builder.motion import rot
from island_mapping.core.graph import normalize_strategy, without_loops

SPACING_M = 0.05
"""A position is kept once the robot moved this far from the last one kept [m]."""
MAX_POINTS = 20_000
"""Past this many positions the record is simplified in place (its memory stays bounded)."""


def strategy_from_path(points: FloatArray, start_heading_rad: float, end_heading_rad: float,
                       tolerance_m: float) -> ControlStrategy:
    """Rot/Go steps along the simplified polyline of `points` (odometry, (N, 2) [m]), starting
    at heading start_heading_rad and ending at end_heading_rad (odometry) [rad]."""
    corners = douglas_peucker(points, tolerance_m)
    steps: list[StrategyPrimitive] = []
    heading = start_heading_rad
    for a, b in itertools.pairwise(corners):
        length_cm = round(100.0 * math.hypot(*(b - a)))
        if length_cm == 0:
            continue
        leg = math.atan2(b[1] - a[1], b[0] - a[0])
        steps += [rot(leg - heading), StrategyPrimitive(PrimitiveKind.GO, length_cm)]
        heading = leg
    steps.append(rot(end_heading_rad - heading))
    return normalize_strategy(ControlStrategy(tuple(steps)))


class PathRecord:
    """The odometric positions driven since `restart` (fed by `add`), as a strategy without
    the loops it drove (`without_loops` with shortcut_m, loop_m [m]; shortcut_m 0: with
    them); off (keeps nothing, an empty strategy) with tolerance_m <= 0."""

    def __init__(self, tolerance_m: float, shortcut_m: float = 0.0, loop_m: float = 3.0
                 ) -> None:
        self.tolerance_m = tolerance_m
        self.shortcut_m, self.loop_m = shortcut_m, loop_m  # loops cut (`without_loops`) [m]
        self._start: Pose2D | None = None
        self._end: Pose2D | None = None
        self._points: list[tuple[float, float]] = []

    def restart(self, pose: Pose2D | None) -> None:
        """The record starts again at `pose` (None: empty until the next `add`)."""
        self._start = self._end = pose
        self._points = [] if pose is None else [(pose.x, pose.y)]

    @property
    def on(self) -> bool:
        """Does the record keep the way (tolerance_m > 0)?"""
        return self.tolerance_m > 0.0

    def add(self, pose: Pose2D) -> None:
        """The robot drove to `pose` (odometry); nothing is kept when off (`on`)."""
        if not self.on:
            return
        if self._start is None:
            self.restart(pose)
            return
        self._end = pose
        last = self._points[-1]
        if math.hypot(pose.x - last[0], pose.y - last[1]) >= SPACING_M:
            self._points.append((pose.x, pose.y))
        if len(self._points) > MAX_POINTS:
            kept = douglas_peucker(np.array(self._points), 0.5 * self.tolerance_m)
            if kept.shape[0] > MAX_POINTS // 2:  # a wander with corners everywhere
                kept = np.concatenate((kept[:-1:2], kept[-1:]))
            self._points = [(float(x), float(y)) for x, y in kept]

    def strategy(self) -> ControlStrategy:
        """The record so far: from the start's heading along the way to the last pose's."""
        if self._start is None or self._end is None:
            return ControlStrategy(())
        pts = np.array([*self._points, (self._end.x, self._end.y)])
        way = strategy_from_path(pts, self._start.theta, self._end.theta, self.tolerance_m)
        return without_loops(way, self.shortcut_m, self.loop_m)
