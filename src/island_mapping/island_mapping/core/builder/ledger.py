"""The map as the builder has built it so far: islands, edges (origin to origin, with the hall
follower's strategy), where each island's origin lies in the odometry frame, and the island the
robot left last. Adding an island also tells the `Recognizer` where it is and links it to the
last island."""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.types import ControlStrategy, Edge, FloatArray, Island, Pose2D

from island_mapping.core.builder.geometry import drive_clear
from island_mapping.core.builder.motion import drive_onto_origin
from island_mapping.core.builder.recognition import Recognizer
from island_mapping.core.graph import normalize_strategy


class Ledger:
    """islands, edges and island_origins_odom are the builder's public lists; last_island is
    the island the robot was handed back at (or built) last, left at path start_path_m [m]."""

    def __init__(self, recognizer: Recognizer) -> None:
        self.recognizer = recognizer
        self.islands: list[Island] = []
        self.edges: list[Edge] = []
        self.island_origins_odom: dict[int, Pose2D] = {}
        self.last_island: Island | None = None
        self.start_path_m = 0.0

    def island(self, island_id: int) -> Island:
        return next(i for i in self.islands if i.id == island_id)

    def edge_to(self, target: int, strategy: ControlStrategy, path_m: float, shift: Pose2D,
                epsilon_m: float, min_go_m: float | None = None) -> Edge | None:
        """The edge from the last island to `target`: the follower's record `strategy` (path_m
        [m] when it ends) plus the drive from `shift` (where the record ended, in the target's
        frame; heading 0 unless min_go_m is given: then as a recognition's drive onto the
        origin), weighted by its length plus epsilon; None without a last island."""
        if self.last_island is None:
            return None
        if min_go_m is None:  # a new island's origin moved from the anchor (same heading)
            moved = shift.x != 0.0 or shift.y != 0.0
            drive = drive_onto_origin(shift, min_go_m=0.0) if moved else ()
        else:
            drive = drive_onto_origin(shift, min_go_m)
        length = max(path_m - self.start_path_m, 0.0) + math.hypot(shift.x, shift.y)
        return Edge(
            source=self.last_island.id, target=target,
            strategy=normalize_strategy(ControlStrategy(strategy.steps + drive)),
            weight=length + epsilon_m, length_m=length, expected_error_m=epsilon_m,
        )

    def put_edge(self, new: Edge) -> Edge | None:
        """Add `new`, or let it replace the edge between the same islands when cheaper; the
        edge added or made cheaper, else None."""
        pair = (new.source, new.target)
        old = next((k for k, e in enumerate(self.edges) if (e.source, e.target) == pair), None)
        if old is None:
            self.edges.append(new)
            return new
        if new.weight < self.edges[old].weight:
            self.edges[old] = new
            return new
        return None

    def edge(self, source: int, target: int) -> Edge | None:
        """The edge source -> target, or None."""
        return next((e for e in self.edges if (e.source, e.target) == (source, target)), None)

    def replace_edge(self, edge: Edge) -> Edge:
        """Put `edge` in place of the edge between the same islands (which must exist)."""
        k = next(k for k, e in enumerate(self.edges) if (e.source, e.target) == (
            edge.source, edge.target))
        self.edges[k] = edge
        return edge

    def add_island(self, island: Island, origin_odom: Pose2D, odom_cov: FloatArray,
                   edge: Edge | None, epsilon_m: float, heading_sigma_rad: float,
                   cov_at: Pose2D | None = None) -> None:
        """A new island with its origin at origin_odom (odometry frame; the odometry's
        covariance odom_cov taken at odometric pose cov_at, default the origin), reached from
        the last island by `edge` (epsilon_m, and heading_sigma_rad of odometry since the
        last island, are the link's sigmas)."""
        if edge is not None:
            self.edges.append(edge)
        self.islands.append(island)
        self.island_origins_odom[island.id] = origin_odom
        self.link_from_last(island.id, origin_odom, epsilon_m, heading_sigma_rad)
        self.recognizer.remember(island.id, origin_odom, odom_cov, cov_at)
        self.last_island = island

    def revisit(self, island_id: int, strategy: ControlStrategy, path_m: float, end: Pose2D,
                epsilon_m: float, min_go_m: float, origin_odom: Pose2D,
                heading_sigma_rad: float) -> Edge | None:
        """A known island recognised with its origin at origin_odom: the edge from the last
        island (the record `strategy` up to path_m [m], then the drive from `end`, the pose in
        its frame where the record ended) is added, or replaces a dearer one, and linked. The
        edge added or made cheaper, else None (also when the island is the last one)."""
        prev = self.last_island
        edge = None
        if prev is not None and prev.id != island_id:
            new = self.edge_to(island_id, strategy, path_m, end, epsilon_m, min_go_m)
            assert new is not None
            edge = self.put_edge(new)
        self.link_from_last(island_id, origin_odom, epsilon_m, heading_sigma_rad)
        return edge

    def near_last_island(self, odom: Pose2D, vicinity_m: float, sight: bool = False) -> bool:
        """Is `odom` within vicinity_m [m] of the last island's origin as last known? With
        `sight`, not when a wall of the island's own model stands between the origin and the
        robot (another room behind a wall, however near)."""
        last = self.last_island
        known = None if last is None else self.recognizer.known(last.id)
        if last is None or known is None:
            return False
        origin = known[0]
        if math.hypot(odom.x - origin.x, odom.y - origin.y) >= vicinity_m:
            return False
        return not sight or in_sight(last.model.segments, odom.relative_to(origin))

    def link_from_last(self, target: int, origin_odom: Pose2D, sigma_m: float,
                       sigma_rad: float) -> None:
        """Link the last island (if known) to `target`, whose origin is at origin_odom."""
        last = self.last_island
        if last is not None and last.id != target and (
            self.recognizer.known(last.id) is not None
        ):
            self.recognizer.link(last.id, target, origin_odom, sigma_m, sigma_rad)

    def handed_back(self, island: Island | None, path_m: float) -> None:
        """The robot is handed back to the follower at `island`'s origin (None: at a dismissed
        attempt's anchor, nothing changes) at path path_m [m]."""
        if island is not None:
            self.last_island = island
            self.start_path_m = path_m


# A wall nearer than this to the robot or the origin does not hide one from the other (the
# wall the robot follows, the walls around the origin) [m]; a sight line passing a model
# segment nearer than _HIDDEN_M crosses it [m].
_SIGHT_END_M = 0.4
_HIDDEN_M = 0.04


def in_sight(segments: FloatArray, at: Pose2D) -> bool:
    """Does the straight line from an island's origin to `at` (its frame) cross none of its
    model's walls `segments` (N, 4) [m], but for their last _SIGHT_END_M at either end?"""
    d = math.hypot(at.x, at.y)
    if segments.shape[0] == 0 or d <= 2.0 * _SIGHT_END_M:
        return True
    u = np.array([at.x, at.y]) / d
    return drive_clear(segments, _SIGHT_END_M * u, (d - _SIGHT_END_M) * u, _HIDDEN_M)
