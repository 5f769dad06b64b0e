"""`islands graph`: inspect, convert and plan on saved island graphs (no ROS needed).

  islands graph info GRAPH                 counts, components, model types (JSON)
  islands graph convert GRAPH OUT          .json <-> .geojson (Nav2 Route Server) <-> .graphml
  islands graph plan GRAPH --from A --to B least-weight route with its strategies (JSON)
  islands graph strategies GRAPH           the edges as the paper's Table 1
  islands graph salvage STORE --out NEW    copy what is intact of a damaged store into a new one

GRAPH is a graph.json / graph.geojson / graph.graphml file, or a graph server's storage
directory (graph.sqlite3, or the old snapshot.json + changes.jsonl), which is read without
being changed. A directory that holds no store is an error, not an empty graph.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from pathlib import Path

import networkx as nx
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.limits import MAX_ISLAND_ID

from island_mapping.cli import CliError
from island_mapping.cli.args import integer, output_file
from island_mapping.core.graph import (
    GraphError,
    GraphStore,
    NoRouteError,
    TopoGraph,
    exit_state_counts,
    salvage_store,
)

ISLAND_ID = integer(0, MAX_ISLAND_ID)
"""An island id on the command line."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="graph_command", required=True, metavar="ACTION")
    p = sub.add_parser("info", help="counts, connectivity and model types as JSON")
    p.add_argument("graph", help="graph file (.json/.geojson/.graphml) or storage directory")
    p = sub.add_parser("convert", help="convert between .json, .geojson and .graphml")
    p.add_argument("graph", help="input graph file or storage directory")
    p.add_argument("out", help="output file; the format follows its extension")
    p = sub.add_parser("plan", help="least-weight route between two islands")
    p.add_argument("graph", help="graph file or storage directory")
    p.add_argument("--from", dest="source", type=ISLAND_ID, required=True,
                   help="source island id")
    p.add_argument("--to", dest="target", type=ISLAND_ID, required=True, help="target island id")
    p = sub.add_parser("strategies", help="print the edges like the paper's Table 1")
    p.add_argument("graph", help="graph file or storage directory")
    p = sub.add_parser("salvage", help="copy the intact rows of a damaged store into a new "
                                       "store and list what was lost (the damaged one is only "
                                       "read)")
    p.add_argument("graph", help="the damaged storage directory")
    p.add_argument("--out", required=True, help="a missing or empty directory for the new store")


def load(path_text: str) -> TopoGraph:
    """A graph from a file or a storage directory; bad input raises CliError."""
    path = Path(path_text).expanduser()
    try:
        if path.is_dir():
            return GraphStore.read(path)
        if not path.exists():
            raise CliError(f"{path}: no such file or directory")
        return TopoGraph.load_any(path)
    except (GraphFormatError, GraphError) as exc:
        raise CliError(str(exc)) from exc


def info(graph: TopoGraph) -> dict[str, object]:
    g = graph.nx_graph
    islands = graph.islands()
    return {
        "islands": len(graph),
        "edges": graph.num_edges,
        "weakly_connected_components": nx.number_weakly_connected_components(g) if len(g) else 0,
        "strongly_connected_components": nx.number_strongly_connected_components(g)
        if len(g) else 0,
        "model_types": dict(sorted(Counter(i.model_type.value for i in islands).items())),
        "segments": sum(len(i.model) for i in islands),
        "total_weight_m": sum(e.weight for e in graph.edges()),
        "with_origin_truth": sum(i.origin_truth is not None for i in islands),
        "exits": exit_state_counts(islands),
    }


def strategies_table(graph: TopoGraph) -> str:
    """The paper's Table 1: one line per edge, `Link  Source->Target  Control Strategies`."""
    lines = ["Link\tEdge\tControl Strategies"]
    for k, e in enumerate(graph.edges()):
        lines.append(f"{k}\t{e.source}->{e.target}\t{e.strategy}")
    return "\n".join(lines)


def salvage(args: argparse.Namespace) -> int:
    try:
        report = salvage_store(Path(args.graph).expanduser(), Path(args.out).expanduser())
    except (GraphFormatError, GraphError, OSError) as exc:
        raise CliError(str(exc)) from exc
    print(json.dumps({"out": args.out, **report.as_dict()}, indent=1))
    return 0


def run(args: argparse.Namespace) -> int:
    if args.graph_command == "salvage":
        return salvage(args)
    graph = load(args.graph)
    if args.graph_command == "info":
        print(json.dumps(info(graph), indent=1))
    elif args.graph_command == "convert":
        target = output_file(args.out, "OUT")
        try:
            written = graph.save_any(target)
        except GraphFormatError as exc:
            raise CliError(str(exc)) from exc
        print(f"wrote {written} ({len(graph)} islands, {graph.num_edges} edges)")
    elif args.graph_command == "plan":
        try:
            route = graph.plan_route(args.source, args.target)
        except NoRouteError as exc:
            print(json.dumps({"error": str(exc)}))
            return 1
        except GraphError as exc:
            raise CliError(str(exc)) from exc
        print(json.dumps({
            "islands": list(route.islands),
            "cost": route.cost,
            "edges": [{"source": e.source, "target": e.target, "strategy": str(e.strategy),
                       "weight": e.weight} for e in route.edges],
        }, indent=1))
    elif args.graph_command == "strategies":
        print(strategies_table(graph))
    return 0
