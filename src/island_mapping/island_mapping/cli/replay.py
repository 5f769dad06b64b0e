"""islands replay: rebuild the island graph from a recorded run.

  islands replay BAG --out DIR [--reference GRAPH] [--allow-damaged] [--builder-param K=V ...]
  islands replay BAG --passive --out DIR [--relations FILE] [--reference TRAJECTORY] ...

Replays the recorded /clock, /odom, /ground_truth, /sonar/scan and /hall_follower/progress of
BAG (a rosbag2 directory such as `islands explore`'s run_bag/, or its .mcap file) into a fresh
island builder and graph server in the recorded order, awaiting each message's delivery before
the next scan goes out (see island_mapping.replay and docs/replay.md), and writes

  DIR/graph.json, DIR/graph.geojson, DIR/graph.graphml   the rebuilt map
  DIR/replay.json                                          the comparison printed on stdout

The comparison is against --reference, or else the recorded run's graph: BAG_DIR/../graph.json
(what `islands explore --out` leaves beside run_bag/) when it exists. Without --builder-param the
builder takes the overrides the run was made with from BAG_DIR/../summary.json, if any. It also
compares the builder's events with the recorded /island_builder/events. Exit code 0 when the
graphs are identical (or there is nothing to compare with), 1 when they differ, 2 on bad input
(missing or damaged bag: use --allow-damaged to replay the intact part of a truncated recording).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from island_msgs_py.inputs import read_json
from island_msgs_py.json_io import GraphFormatError, atomic_write_text

from island_mapping.cli import CliError
from island_mapping.cli.args import check_output_dir, number
from island_mapping.cli.params import parse_assignments
from island_mapping.core.graph import GraphError, TopoGraph

REFERENCE_NAME = "graph.json"
REPORT_NAME = "replay.json"
SUMMARY_NAME = "summary.json"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("bag", help="rosbag2 directory (e.g. explore's run_bag/) or .mcap file")
    parser.add_argument("--out", required=True, help="output directory (created)")
    parser.add_argument("--reference", default=None,
                        help="graph to compare with (default: BAG_DIR/../graph.json if present); "
                             "with --passive: a reference trajectory (t x y theta or TUM "
                             "lines)")
    parser.add_argument("--allow-damaged", action="store_true",
                        help="replay the intact part of a truncated or corrupted bag (warned)")
    parser.add_argument("--builder-param", action="append", default=[], metavar="NAME=VALUE",
                        help="island_builder_node parameter override, e.g. builder.e_min_m=0.5 "
                             "(VALUE parsed as YAML); repeatable")
    parser.add_argument("--tol", type=number(0.0), default=1e-9,
                        help="comparison tolerance (absolute up to 1, relative above) [-]")
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    from island_mapping.cli import replay_log

    replay_log.add_arguments(parser)


def _beside_bag(bag: Path, name: str) -> Path:
    """The file `name` that `islands explore --out` leaves beside the bag directory (BAG is
    that directory or its .mcap file)."""
    bag_dir = bag if bag.is_dir() else bag.parent
    return bag_dir.parent / name


def default_reference(bag: Path) -> Path:
    """Where `islands explore` leaves the recorded run's graph: beside the bag directory."""
    return _beside_bag(bag, REFERENCE_NAME)


def recorded_builder_params(bag: Path) -> dict[str, Any]:
    """The island_builder_node overrides `islands explore` ran with, from the summary.json it
    leaves beside the bag directory ({} when there is none or it names none)."""
    path = _beside_bag(bag, SUMMARY_NAME)
    if not path.is_file():
        return {}
    try:
        summary = read_json(path, CliError)
    except CliError as exc:
        raise CliError(f"{exc}; pass --builder-param explicitly or move it away") from None
    params = summary.get("parameters", {}) if isinstance(summary, dict) else {}
    builder = params.get("island_builder_node", {}) if isinstance(params, dict) else {}
    if not isinstance(builder, dict):
        raise CliError(f"{path}: parameters.island_builder_node is not a mapping")
    return dict(builder)


def _load_reference(path: Path) -> TopoGraph:
    try:
        return TopoGraph.load_any(path)
    except (GraphFormatError, GraphError, OSError, ValueError) as exc:
        raise CliError(f"reference graph {path}: {exc}") from None


def run(args: argparse.Namespace) -> int:
    from island_mapping.bag.compare import compare_events, compare_graphs
    from island_mapping.replay import ReplayConfig, ReplayError, replay_run

    bag = Path(args.bag)
    if not bag.exists():
        raise CliError(f"{bag}: no such bag directory or .mcap file")
    if args.passive:  # islands from any recording's scans and odometry (cli/replay_log.py)
        from island_mapping.cli import replay_log

        return replay_log.run(args)
    if not (args.tol >= 0):
        raise CliError(f"--tol must be >= 0, got {args.tol}")
    params = parse_assignments(args.builder_param, "--builder-param")
    if not params:
        params = recorded_builder_params(bag)
        if params:
            print(f"islands replay: builder parameters of the recorded run (summary.json): "
                  f"{params}", file=sys.stderr)
    reference = Path(args.reference) if args.reference else default_reference(bag)
    if args.reference and not reference.is_file():
        raise CliError(f"--reference {reference}: no such file")
    expected = _load_reference(reference) if reference.is_file() else None
    out = check_output_dir(args.out)

    def progress(done: int, total: int) -> None:
        print(f"\rreplay: {done}/{total} messages", end="", file=sys.stderr, flush=True)

    try:
        res = replay_run(bag, ReplayConfig(allow_damaged=args.allow_damaged), params,
                         None if args.quiet else progress)
    except ReplayError as exc:
        raise CliError(str(exc)) from None
    finally:
        if not args.quiet:
            print(file=sys.stderr)
    for w in res.warnings:
        print(f"islands replay: warning: {w}", file=sys.stderr)
    out.mkdir(parents=True, exist_ok=True)
    paths = res.graph.save_all(out)
    report: dict[str, Any] = {
        "bag": str(res.bag_path),
        "out": {k: str(v) for k, v in paths.items()},
        "messages": res.messages,
        "superseded": res.superseded,
        "islands": len(res.graph),
        "edges": res.graph.num_edges,
        "wall_seconds": round(res.wall_seconds, 2),
        "warnings": res.warnings,
        "reference": str(reference) if expected is not None else None,
        "graph": (compare_graphs(expected, res.graph, args.tol).to_dict()
                  if expected is not None else None),
        "events": (compare_events(res.recorded_events, res.events)
                   if res.recorded_events is not None else None),
    }
    text = json.dumps(report, indent=2)
    atomic_write_text(out / REPORT_NAME, text + "\n")
    print(text)
    graph_report = report["graph"]
    return 0 if graph_report is None or graph_report["identical"] else 1
