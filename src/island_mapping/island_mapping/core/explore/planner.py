"""Which exit to explore next: the nearest island with an unexplored exit, by the map.

Distances are shortest routes in the graph (edge weights; an edge may be driven backwards by
its reversed strategy, at the same weight). Ties go to the lower island id, then the lower
exit index, so a map always gives the same choice.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Collection, Mapping
from dataclasses import dataclass

from island_msgs_py.types import Edge, ExitState

from island_mapping.core.explore.config import ExploreError
from island_mapping.core.graph import TopoGraph, reverse_strategy


@dataclass(frozen=True)
class Target:
    """An exit to explore: island `island_id`'s exit `exit_index`, reached from the start by
    `route` (island ids, the start first) of length `distance_m` [m] (edge weights, plus a side
    exit's prefix)."""

    island_id: int
    exit_index: int
    route: tuple[int, ...]
    distance_m: float


Penalties = Mapping[frozenset[int], float]
"""Extra length [m] charged on the edge between two islands (routes that failed there)."""


def _neighbours(graph: TopoGraph, penalty: Penalties | None = None
                ) -> dict[int, list[tuple[int, float]]]:
    out: dict[int, list[tuple[int, float]]] = {i: [] for i in graph.island_ids()}
    pen = penalty if penalty is not None else {}
    for e in graph.iter_edges():
        w = e.weight + pen.get(frozenset((e.source, e.target)), 0.0)
        out[e.source].append((e.target, w))
        out[e.target].append((e.source, w))
    for nbrs in out.values():
        nbrs.sort()
    return out


def distances_from(graph: TopoGraph, start: int, penalty: Penalties | None = None
                   ) -> tuple[dict[int, float], dict[int, int]]:
    """Shortest route lengths from `start` to every reachable island [m] and each one's
    predecessor on its route (Dijkstra; ties broken by island id; `penalty` charged on
    edges)."""
    if start not in graph.island_ids():
        raise ExploreError(f"planner: unknown island {start}")
    nbrs = _neighbours(graph, penalty)
    dist = {start: 0.0}
    prev: dict[int, int] = {}
    heap = [(0.0, start)]
    done: set[int] = set()
    while heap:
        d, i = heapq.heappop(heap)
        if i in done:
            continue
        done.add(i)
        for j, w in nbrs[i]:
            nd = d + w
            if nd < dist.get(j, float("inf")) - 1e-12:
                dist[j], prev[j] = nd, i
                heapq.heappush(heap, (nd, j))
    return dist, prev


def route_to(prev: dict[int, int], start: int, goal: int) -> tuple[int, ...]:
    """The island ids from start to goal along the predecessors."""
    out = [goal]
    while out[-1] != start:
        out.append(prev[out[-1]])
    return tuple(reversed(out))


def nearest_unexplored(graph: TopoGraph, start: int, skip: Collection[tuple[int, int]] = (),
                       extra_m: Mapping[tuple[int, int], float] | None = None,
                       penalty: Penalties | None = None) -> Target | None:
    """The nearest (island, exit) with an unexplored exit reachable from `start`, not in
    `skip` (a side exit is as far as its island plus its prefix's driving; an exit in
    `extra_m` that much farther, e.g. `novelty.known_space_costs`; edges in `penalty` that
    much longer); None when none is left."""
    extra = extra_m if extra_m is not None else {}
    dist, prev = distances_from(graph, start, penalty)
    best: tuple[float, int, int, float] | None = None
    for iid, d in dist.items():
        for e in graph.get_island(iid).exits:
            if e.state is ExitState.UNEXPLORED and (iid, e.index) not in skip:
                way = e.prefix.length_m if e.prefix is not None else 0.0  # a side exit's
                key = (d + way + extra.get((iid, e.index), 0.0), iid, e.index, d + way)
                if best is None or key < best:
                    best = key
    if best is None:
        return None
    _, iid, idx, d = best
    return Target(iid, idx, route_to(prev, start, iid), d)


def unexplored_count(graph: TopoGraph) -> int:
    """Exits of the graph still unexplored."""
    return sum(e.state is ExitState.UNEXPLORED for i in graph.islands() for e in i.exits)


def route_edges(graph: TopoGraph, route: tuple[int, ...]) -> list[Edge]:
    """The edges along `route`, an edge driven backwards as its reverse (reversed strategy)."""
    out = []
    for a, b in itertools.pairwise(route):
        if graph.has_edge(a, b):
            out.append(graph.get_edge(a, b))
            continue
        if not graph.has_edge(b, a):
            raise ExploreError(f"planner: no edge between islands {a} and {b}")
        e = graph.get_edge(b, a)
        out.append(Edge(a, b, reverse_strategy(e.strategy), e.weight, e.length_m,
                        e.expected_error_m, e.target_exit, e.source_exit))
    return out
