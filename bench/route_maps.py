"""Route following measured on fixed maps, so two versions of it compare on the same edges.

A whole exploration is chaotic (one different decision early changes the map), so the routes
of two explorations say little about route following itself. Here the maps are saved once
(`--explore SECONDS SEED`, with the code that runs it) and every version follows the same
edges and the same random routes:

  python bench/route_maps.py OUT.jsonl --explore 3600 1 --maps paper_fig4@/tmp/pf4_1.json
  python bench/route_maps.py OUT.jsonl --maps paper_fig4@/tmp/pf4_1.json \
      gen:office:seed=11,scale=1@/tmp/o11_1.json --routes 30

Per map, one JSON line: every edge (both ways) followed alone from its source's true origin
(`edges_ok` of `edges`), and `routes` random routes (pairs drawn with a fixed seed) from a
random start near the first island (`routes_ok`), with their wall contacts and false
arrivals (an arrival trusted but > success_tol_m or success_tol_deg off by the truth).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
from pathlib import Path

import numpy as np
from island_mapping.core.graph import TopoGraph
from island_mapping.core.route import NavigateConfig
from island_mapping.evaluation.explore_exits import explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_mapping.evaluation.routes import (
    RouteResult,
    draw_pairs,
    follow_route,
    with_reverse_edges,
)
from island_sim.core.world_loader import load_world

PAIRS_SEED = 5  # the random routes' draw: the same pairs for every version


def _false_arrivals(r: RouteResult) -> int:
    """Arrivals trusted but judged wrong (an edge's success is trusted and within tolerance)."""
    return sum(e.localized and not e.success for e in r.edges)


def measure_map(world: str, graph_file: Path, n_routes: int) -> dict[str, object]:
    """Edges alone and random routes on one saved map (module docstring)."""
    setup = SimSetup(world=load_world(world))
    graph = with_reverse_edges(TopoGraph.load_json(graph_file))
    cfg = NavigateConfig()
    edges = [follow_route(graph, [e.source, e.target], setup, rng=np.random.default_rng(0),
                          start=graph.get_island(e.source).origin_truth)
             for e in graph.iter_edges()]
    draws = draw_pairs(graph, n_routes, np.random.default_rng(PAIRS_SEED), cfg) if len(
        graph) >= 2 else []  # one island: no route to draw
    routes = [follow_route(graph, d.route, setup, rng=np.random.default_rng(d.seed),
                           start=d.start) for d in draws]
    runs = edges + routes
    return {
        "world": world, "map": str(graph_file), "islands": len(graph),
        "edges": len(edges), "edges_ok": sum(r.success for r in edges),
        "edges_failed": [f"{r.route[0]}->{r.route[1]} {r.end}" for r in edges if not r.success],
        "routes": len(routes), "routes_ok": sum(r.success for r in routes),
        "wall_contacts": sum(r.wall_contacts for r in runs),
        "false_arrivals": sum(_false_arrivals(r) for r in runs),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out", type=Path)
    p.add_argument("--maps", nargs="+", required=True, help="WORLD@MAP.json")
    p.add_argument("--explore", nargs=2, type=float, metavar=("SECONDS", "SEED"),
                   help="first explore each world (policy exits) and save the map there")
    p.add_argument("--routes", type=int, default=30)
    a = p.parse_args()
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, check=False, cwd=Path(__file__).parent).stdout.strip()
    for spec in a.maps:
        world, _, path = spec.partition("@")
        if a.explore is not None:
            setup = SimSetup(world=load_world(world))
            run = explore_by_exits(setup, a.explore[0],
                                   rng=np.random.default_rng(int(a.explore[1])))
            run.graph.save_json(Path(path))
        row = measure_map(world, Path(path), a.routes)
        row["commit"], row["load_avg_1m"] = commit, round(os.getloadavg()[0], 2)
        with a.out.open("a") as f:
            f.write(json.dumps(row) + "\n")
        print(json.dumps({k: v for k, v in row.items() if k != "edges_failed"}), flush=True)


if __name__ == "__main__":
    main()
