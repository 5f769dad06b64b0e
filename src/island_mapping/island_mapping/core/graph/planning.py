"""Route planning on the map: Dijkstra on the edge weights W [m].

A* would need an admissible heuristic, i.e. a metric position of every island in one frame; the
map deliberately has no global frame (positions derived from chained strategies carry unbounded
drift and are not admissible), so A* has nothing to offer. Small graphs use networkx's
bidirectional Dijkstra; from `SCIPY_MIN_ISLANDS` islands on, a cached CSR matrix and scipy's C
Dijkstra are used, with the shortest-path tree of recent sources cached until the graph changes
(see bench/bench_route_planning.py for the numbers).
"""

from __future__ import annotations

import itertools
import math
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum

import networkx as nx
import numpy as np
import scipy.sparse as sp
from island_msgs_py.types import Edge
from scipy.sparse.csgraph import dijkstra

from island_mapping.core.graph.errors import GraphError, NoRouteError

# From this many islands on, plan on a cached CSR matrix with scipy (C Dijkstra). Measured
# (bench/bench_route_planning.py): at 1,000 islands a CSR rebuild + query costs about what one
# networkx bidirectional query does and later queries are 5x faster; below it networkx wins
# because every change would force a rebuild.
SCIPY_MIN_ISLANDS = 1000
# Shortest-path trees of this many recent sources are kept until the graph changes.
ROUTE_TREE_CACHE_SIZE = 8


class Backend(StrEnum):
    """Which Dijkstra plans a route."""

    AUTO = "auto"  # networkx below SCIPY_MIN_ISLANDS islands, else scipy
    NETWORKX = "networkx"
    SCIPY = "scipy"


@dataclass(frozen=True)
class Route:
    """A planned route: island ids in travel order, the edges between them, total weight [m]."""

    islands: tuple[int, ...]
    edges: tuple[Edge, ...]
    cost: float


class RoutePlanner:
    """Plans on a DiGraph whose edges carry `weight` [m] and `edge` (the Edge), with the scipy
    caches (CSR matrix, recent shortest-path trees) keyed on the graph's change counter."""

    def __init__(self) -> None:
        self._csr_version = -1
        self._csr: sp.csr_array | None = None
        self._ids = np.zeros(0, dtype=np.int64)  # sorted island ids = CSR row order
        self._trees: OrderedDict[int, tuple[np.ndarray, np.ndarray]] = OrderedDict()

    def changed(self) -> None:
        """The graph changed: the cached trees are stale (the CSR is rebuilt lazily)."""
        self._trees.clear()

    def clear(self) -> None:
        """Forget the CSR matrix and the cached shortest-path trees (as a change would)."""
        self._csr = None
        self._trees.clear()

    def plan(
        self,
        g: nx.DiGraph,
        weights: Mapping[tuple[int, int], float],
        version: int,
        source: int,
        target: int,
        backend: str = Backend.AUTO,
    ) -> Route:
        """Least-weight directed route; GraphError for unknown islands or backend, NoRouteError
        when the target cannot be reached."""
        for name, i in (("source", source), ("target", target)):
            if i not in g:
                raise GraphError(f"plan: unknown {name} island {i}")
        try:
            chosen = Backend(backend)
        except ValueError:
            known = ", ".join(b.value for b in Backend)
            raise GraphError(f"plan: unknown backend {backend!r} ({known})") from None
        if source == target:
            return Route((source,), (), 0.0)
        if chosen is Backend.AUTO:
            chosen = Backend.SCIPY if len(g) >= SCIPY_MIN_ISLANDS else Backend.NETWORKX
        if chosen is Backend.NETWORKX:
            try:
                cost, path = nx.bidirectional_dijkstra(g, source, target, weight="weight")
            except nx.NetworkXNoPath:
                msg = f"plan: no route from island {source} to island {target}"
                raise NoRouteError(msg) from None
            nodes = [int(n) for n in path]
        else:
            nodes, cost = self._plan_scipy(g, weights, version, source, target)
        edges = tuple(g.edges[u, v]["edge"] for u, v in itertools.pairwise(nodes))
        return Route(tuple(nodes), edges, float(cost))

    def _matrix(
        self, g: nx.DiGraph, weights: Mapping[tuple[int, int], float], version: int
    ) -> sp.csr_array:
        if self._csr is None or self._csr_version != version:
            ids = np.array(sorted(g.nodes), dtype=np.int64)
            n = len(ids)
            m = len(weights)
            flat = itertools.chain.from_iterable(weights)
            uv = np.fromiter(flat, dtype=np.int64, count=2 * m).reshape(m, 2)
            rows, cols = uv[:, 0], uv[:, 1]
            w = np.fromiter(weights.values(), dtype=np.float64, count=m)
            # explicit zero weights stay edges in scipy's csgraph (they are not eliminated)
            self._csr = sp.csr_array(
                (w, (np.searchsorted(ids, rows), np.searchsorted(ids, cols))), shape=(n, n)
            )
            self._ids = ids
            self._csr_version = version
            self._trees.clear()
        return self._csr

    def _plan_scipy(
        self,
        g: nx.DiGraph,
        weights: Mapping[tuple[int, int], float],
        version: int,
        source: int,
        target: int,
    ) -> tuple[list[int], float]:
        csr = self._matrix(g, weights, version)
        s = int(np.searchsorted(self._ids, source))
        t = int(np.searchsorted(self._ids, target))
        tree = self._trees.get(source)
        if tree is None:
            dist, pred = dijkstra(csr, directed=True, indices=s, return_predecessors=True)
            tree = (dist, pred)
            self._trees[source] = tree
            while len(self._trees) > ROUTE_TREE_CACHE_SIZE:
                self._trees.popitem(last=False)
        else:
            self._trees.move_to_end(source)
        dist, pred = tree
        if not math.isfinite(float(dist[t])):
            raise NoRouteError(f"plan: no route from island {source} to island {target}")
        path = [t]
        while path[-1] != s:
            path.append(int(pred[path[-1]]))
        return [int(self._ids[k]) for k in reversed(path)], float(dist[t])
