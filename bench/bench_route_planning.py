"""Route planning time vs graph size, and memory per island, for island_mapping.core.graph.

Graphs: a jittered square grid of islands with 4-neighbour edges in both directions, where a
seeded random 30% of the non-tree edges are dropped (a random spanning tree is always kept, so
the graph stays connected); weight = layout distance x U(1, 1.5) [m]. This is sparse and
map-like (roughly planar), the kind of graph a building's island map is.

For each size, the same seeded random (source, target) pairs are planned with:
- networkx: bidirectional Dijkstra on the DiGraph (what small graphs use);
- scipy-cold: scipy's C Dijkstra on the cached CSR matrix, a new source every query;
- scipy-warm: the same source again (the shortest-path tree of a recent source is cached);
- auto: what TopoGraph.plan_route picks.
Times are printed beside Nav2 Route Server's published C++ numbers (0.23 ms at 10,000 nodes,
3.75 ms at 90,000 nodes) as ratios (ours / Nav2; > 1 means slower). Memory per island is the
tracemalloc peak of building a graph of islands with an empty model, and with 20 segments.

Persistence, the SQLite GraphStore beside the JSONL store it replaced (bench/
baseline_jsonl_store.py, kept verbatim) in one run: median ms per acknowledged change (put_island
+ put_edge, each durable before it returns) over 500 islands of 20 segments, and ms to reopen
that store and a 10,000-island one (the SQLite store checks its pages, row checksums and the
graph on open).

Usage: python bench/bench_route_planning.py [--sizes 1000,10000,90000,100000] [--queries 30]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from baseline_jsonl_store import JsonlGraphStore
from island_mapping.core.graph import GraphStore, TopoGraph
from island_mapping.core.graph.store import write_new_database
from island_mapping.core.graph.store_schema import DATABASE
from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType

NAV2_MS = {10_000: 0.23, 90_000: 3.75}  # Nav2 Route Server docs (C++), per route query
DROP_FRACTION = 0.3  # share of non-spanning-tree grid edges removed


def grid_graph_edges(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(src, dst, weight [m]) of a connected, jittered-grid graph on n nodes (both directions)."""
    side = int(np.ceil(np.sqrt(n)))
    idx = np.arange(n)
    xy = np.stack([idx % side, idx // side], axis=1).astype(float) * 5.0
    xy += rng.uniform(-1.0, 1.0, size=xy.shape)
    right = idx[(idx % side < side - 1) & (idx + 1 < n)]
    up = idx[idx + side < n]
    a = np.concatenate([right, up])
    b = np.concatenate([right + 1, up + side])
    # random spanning tree: Kruskal on random priorities (union-find)
    order = rng.permutation(len(a))
    parent = np.arange(n)

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    keep = np.zeros(len(a), dtype=bool)
    for k in order:
        ra, rb = find(int(a[k])), find(int(b[k]))
        if ra != rb:
            parent[ra] = rb
            keep[k] = True
    keep |= rng.random(len(a)) >= DROP_FRACTION
    a, b = a[keep], b[keep]
    w = np.linalg.norm(xy[a] - xy[b], axis=1) * rng.uniform(1.0, 1.5, size=len(a))
    return np.concatenate([a, b]), np.concatenate([b, a]), np.concatenate([w, w])


def build_graph(n: int, rng: np.random.Generator, segments: int = 0) -> TopoGraph:
    g = TopoGraph()
    model = LineModel(rng.uniform(-3, 3, size=(segments, 4)))
    for i in range(n):
        g.add_island(Island(i, model, ModelType.LINE, 1.0, float(i)))
    src, dst, w = grid_graph_edges(n, rng)
    strategy = ControlStrategy.parse("Go 125, Rot 270, Go 652")
    for s, t, wt in zip(src.tolist(), dst.tolist(), w.tolist(), strict=True):
        g.add_edge(Edge(s, t, strategy, wt, length_m=wt))
    return g


def time_queries(g: TopoGraph, pairs: list[tuple[int, int]], backend: str) -> list[float]:
    out = []
    for s, t in pairs:
        t0 = time.perf_counter()
        g.plan_route(s, t, backend=backend)
        out.append((time.perf_counter() - t0) * 1e3)
    return out


def memory_per_island(n: int, segments: int, seed: int) -> float:
    rng = np.random.default_rng(seed)
    tracemalloc.start()
    g = build_graph(n, rng, segments)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    del g
    return peak / n


def persistence_ms(
    n: int, seed: int, open_store: Callable[[str], Any], read: Callable[[str], TopoGraph]
) -> tuple[float, float]:
    """(median ms per acknowledged put_island + put_edge, ms to reload) for n islands."""
    rng = np.random.default_rng(seed)
    model = LineModel(rng.uniform(-3, 3, size=(20, 4)))
    strategy = ControlStrategy.parse("Go 125, Rot 270, Go 652")
    per_change = []
    with tempfile.TemporaryDirectory() as d:
        store = open_store(d)
        for i in range(n):
            t0 = time.perf_counter()
            store.put_island(Island(i, model, ModelType.LINE, 1.0, float(i)))
            if i:
                store.put_edge(Edge(i - 1, i, strategy, 8.0))
            per_change.append((time.perf_counter() - t0) * 1e3 / (2 if i else 1))
        store.close()
        t0 = time.perf_counter()
        assert len(read(d)) == n
        reload_ms = (time.perf_counter() - t0) * 1e3
    return statistics.median(per_change), reload_ms


def reload_big_ms(n: int, seed: int) -> tuple[float, float]:
    """ms to reopen an n-island store (20 segments each, a chain of edges): (SQLite, JSONL)."""
    rng = np.random.default_rng(seed)
    model = LineModel(rng.uniform(-3, 3, size=(20, 4)))
    strategy = ControlStrategy.parse("Go 125, Rot 270, Go 652")
    g = TopoGraph.from_parts(
        [Island(i, model, ModelType.LINE, 1.0, float(i)) for i in range(n)],
        [Edge(i - 1, i, strategy, 8.0) for i in range(1, n)])
    out = []
    with tempfile.TemporaryDirectory() as d:
        write_new_database(Path(d) / DATABASE, g, {})
        t0 = time.perf_counter()
        assert len(GraphStore.read(d)) == n
        out.append((time.perf_counter() - t0) * 1e3)
    with tempfile.TemporaryDirectory() as d:
        old = JsonlGraphStore(d)
        old.graph = g
        old.compact()
        old.close()
        t0 = time.perf_counter()
        assert len(JsonlGraphStore.read(d)) == n
        out.append((time.perf_counter() - t0) * 1e3)
    return out[0], out[1]


def report_persistence(seed: int) -> None:
    n = 500
    stores: list[tuple[str, Callable[[str], Any], Callable[[str], TopoGraph]]] = [
        ("SQLite GraphStore", GraphStore, GraphStore.read),
        ("JSONL store (before)", JsonlGraphStore, JsonlGraphStore.read),
    ]
    for name, open_store, read in stores:
        change_ms, reload_ms = persistence_ms(n, seed, open_store, read)
        print(f"{name:>22}, {n} islands of 20 segments + edges: {change_ms:.2f} ms per "
              f"acknowledged change, reload {reload_ms:.0f} ms")
    big = 10_000
    sqlite_ms, jsonl_ms = reload_big_ms(big, seed)
    print(f"reload of a {big}-island store: SQLite {sqlite_ms:.0f} ms, JSONL {jsonl_ms:.0f} ms "
          f"(ratio {sqlite_ms / jsonl_ms:.2f})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1000,10000,90000,100000")
    ap.add_argument("--queries", type=int, default=30)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--store-only", action="store_true", help="only the persistence figures")
    args = ap.parse_args()
    if args.store_only:
        report_persistence(args.seed)
        return 0
    sizes = [int(s) for s in args.sizes.split(",")]
    print(f"{'islands':>8} {'edges':>7} {'backend':>18} {'median ms':>10} {'p95 ms':>8} "
          f"{'Nav2 ms':>8} {'ratio':>7}")
    for n in sizes:
        rng = np.random.default_rng(args.seed + n)
        g = build_graph(n, rng)
        pairs = [(int(a), int(b)) for a, b in (rng.choice(n, 2, replace=False)
                                               for _ in range(args.queries))]
        # one route check: both backends agree on the cost
        s, t = pairs[0]
        c1 = g.plan_route(s, t, backend="networkx").cost
        c2 = g.plan_route(s, t, backend="scipy").cost
        assert abs(c1 - c2) < 1e-6 * max(1.0, c1), (c1, c2)
        results = {"networkx": time_queries(g, pairs, "networkx")}
        rebuild = []
        for pair in pairs[:5]:
            g.clear_planning_cache()  # as after a change: CSR rebuild + query
            rebuild += time_queries(g, [pair], "scipy")
        results["scipy-after-change"] = rebuild
        results["scipy-cold"] = time_queries(g, pairs, "scipy")  # new source each query
        first = [(pairs[0][0], t) for _, t in pairs]
        results["scipy-warm"] = time_queries(g, first, "scipy")  # cached source tree
        g.clear_planning_cache()
        results["auto"] = time_queries(g, pairs, "auto")
        for name, ms in results.items():
            med = statistics.median(ms)
            p95 = sorted(ms)[max(0, int(0.95 * len(ms)) - 1)]
            nav2 = NAV2_MS.get(n)
            ratio = f"{med / nav2:7.2f}" if nav2 else "      -"
            nav2_s = f"{nav2:8.2f}" if nav2 else "       -"
            print(f"{n:>8} {g.num_edges:>7} {name:>18} {med:>10.3f} {p95:>8.3f} {nav2_s} {ratio}")
    for segs in (0, 20):
        n = 10_000
        b = memory_per_island(n, segs, args.seed)
        print(f"memory per island ({segs:2d}-segment model, {n} islands, ~3.4 edges out each): "
              f"{b / 1024:.2f} KiB (tracemalloc peak / islands)")
    report_persistence(args.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
