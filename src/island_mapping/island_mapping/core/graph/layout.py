"""A display layout of the map: a pose per island for DRAWING only (there is no global frame)."""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
from island_msgs_py.types import Island, Pose2D

from island_mapping.core.graph.strategy import strategy_displacement

DEFAULT_MARGIN_M = 2.0  # gap between weakly connected components laid side by side [m]


def model_points(segments: np.ndarray, pose: Pose2D) -> np.ndarray:
    """Segment endpoints and the origin, transformed by `pose` into the layout frame, (K, 2) [m]."""
    pts = np.vstack([np.zeros((1, 2)), segments.reshape(-1, 2)])
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    rot = np.array([[c, -s], [s, c]])
    out: np.ndarray = pts @ rot.T + np.array([pose.x, pose.y])
    return out


def _chain_component(g: nx.DiGraph, und: nx.Graph, root: int) -> dict[int, Pose2D]:
    """Poses of one weakly connected component by chaining ideal executions from `root`
    (backwards along reversed edges)."""
    local: dict[int, Pose2D] = {root: Pose2D(0.0, 0.0, 0.0)}
    stack = [root]
    while stack:
        u = stack.pop()
        for v in sorted(und.neighbors(u)):
            if v in local:
                continue
            if g.has_edge(u, v):
                step = strategy_displacement(g.edges[u, v]["edge"].strategy)
            else:
                step = strategy_displacement(g.edges[v, u]["edge"].strategy).inverse()
            local[v] = local[u].compose(step)
            stack.append(v)
    return local


def display_layout(g: nx.DiGraph, margin_m: float = DEFAULT_MARGIN_M) -> dict[int, Pose2D]:
    """A pose per island of `g` (node attr `island`, edge attr `edge`) for DISPLAY only.

    When every island knows its simulator `origin_truth`, that is used. Otherwise each weakly
    connected component is laid out by chaining ideal executions of the edge strategies from its
    lowest id (backwards along reversed edges), and components are placed side by side,
    `margin_m` apart. Drift makes this picture wrong at large scale; nothing may use it for
    computation.
    """
    islands: dict[int, Island] = {i: g.nodes[i]["island"] for i in sorted(g.nodes)}
    if islands and all(i.origin_truth is not None for i in islands.values()):
        return {k: v.origin_truth for k, v in islands.items() if v.origin_truth is not None}
    layout: dict[int, Pose2D] = {}
    und = g.to_undirected(as_view=True)
    x_offset = 0.0
    for comp in sorted(nx.connected_components(und), key=min):
        local = _chain_component(g, und, min(comp))
        pts = np.vstack([model_points(islands[i].model.segments, p) for i, p in local.items()])
        shift = x_offset - float(pts[:, 0].min())
        y0 = float(pts[:, 1].min())
        for i, p in local.items():
            layout[i] = Pose2D(p.x + shift, p.y - y0, p.theta)
        x_offset += float(pts[:, 0].max() - pts[:, 0].min()) + margin_m
    return layout
