"""Which unexplored exits lead into space the map already knows: a cost for the planner.

Nearest-first exploration takes the plain exits of the island the robot stands at before any
other, and many of them (a corner's exit back along the corridor an edge has just driven, an
exit at 45 deg off a junction's corridors) lead where the map already goes: the trip ends in
a revisit that adds nothing. Here every unexplored exit gets a look point `lookahead_m` ahead
of it (a side exit: ahead of its opening, after the turn), in the frame of the island the
robot stands at, dead-reckoned along the edges' strategies (`openings.chained_frames`). The
map knows the space around its islands' origins, the paths its edges' strategies drive and
its side exits' openings; an exit whose look point lies within `radius_m` of any of them
costs `penalty_m` more in the planner, so exits into space the map does not know go first and
the others still go, last, before exploration ends.
"""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.geometry import from_frame
from island_msgs_py.types import ControlStrategy, Exit, ExitState, FloatArray, Pose2D

from island_mapping.core.explore.config import NoveltyConfig
from island_mapping.core.explore.openings import chained_frames, exit_pose
from island_mapping.core.graph import TopoGraph


def strategy_points(strategy: ControlStrategy, spacing_m: float) -> FloatArray:
    """Points every `spacing_m` [m] along the path the strategy drives (ideal execution) from
    the origin facing theta 0, both ends included, (N, 2) [m]."""
    pose = Pose2D(0.0, 0.0, 0.0)
    out = [(0.0, 0.0)]
    for s in strategy.steps:
        n = max(1, math.ceil(abs(s.metres) / spacing_m))
        for k in range(1, n + 1):
            p = pose.compose(Pose2D(s.metres * k / n, 0.0, 0.0))
            out.append((p.x, p.y))
        pose = pose.compose(Pose2D(s.metres, 0.0, s.radians))
    return np.asarray(out, dtype=float)


def known_points(graph: TopoGraph, frames: dict[int, Pose2D], spacing_m: float) -> FloatArray:
    """The space the map knows, in the frames' common frame (N, 2) [m]: island origins, the
    paths of edges from an island with a frame, side exits' openings."""
    pts = [np.array([[f.x, f.y]]) for f in frames.values()]
    for e in graph.iter_edges():
        if e.source in frames:
            pts.append(from_frame(strategy_points(e.strategy, spacing_m), frames[e.source]))
    for iid, f in frames.items():
        for ex in graph.get_island(iid).exits:
            if ex.prefix is not None and ex.side is not None:
                o = f.compose(exit_pose(ex.prefix, ex.side))
                pts.append(np.array([[o.x, o.y]]))
    return np.concatenate(pts) if pts else np.zeros((0, 2))


def look_point(frame: Pose2D, ex: Exit, lookahead_m: float) -> tuple[float, float]:
    """Where exit `ex` of the island whose frame is `frame` leads, `lookahead_m` [m] on [m]."""
    if ex.prefix is not None and ex.side is not None:
        start = frame.compose(exit_pose(ex.prefix, ex.side))
    else:
        start = frame.compose(Pose2D(0.0, 0.0, ex.heading_rad))
    p = start.compose(Pose2D(lookahead_m, 0.0, 0.0))
    return p.x, p.y


def known_space_costs(graph: TopoGraph, start: int, cfg: NoveltyConfig
                      ) -> dict[tuple[int, int], float]:
    """The planner's extra cost [m] of each unexplored exit (island id, exit index) of the
    islands within `cfg.chain_m` of route from `start` whose look point the map knows; the
    exits not listed cost nothing extra."""
    frames = chained_frames(graph, start, cfg.chain_m)
    known = known_points(graph, frames, cfg.spacing_m)
    out: dict[tuple[int, int], float] = {}
    for iid, f in frames.items():
        for ex in graph.get_island(iid).exits:
            if ex.state is not ExitState.UNEXPLORED:
                continue
            x, y = look_point(f, ex, cfg.lookahead_m)
            if float(np.min(np.hypot(known[:, 0] - x, known[:, 1] - y))) <= cfg.radius_m:
                out[(iid, ex.index)] = cfg.penalty_m
    return out

