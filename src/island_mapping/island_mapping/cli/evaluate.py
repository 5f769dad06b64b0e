"""islands evaluate: a map measured against the world it was built in (issue 16).

Reads what `islands explore --out DIR` wrote (graph.json: islands with their true origins;
summary.json: builder events with the robot's true pose, the followed routes, the start pose)
and writes to --out (default: DIR):

  evaluation.json   places, coverage (all, junctions), places the map knows (covered, or a
                    side exit opens there), islands per place, false merges,
                    cycle rank of the map and of the world, route success and length ratios
  places.png        the world's places, covered (green) or missed (red), and island origins

The ground-truth places come from the world's geometry alone (`island_sim.core.places`): the
skeleton of the free space reachable from the start pose, its branch points and end points,
merged within 2 m. For image worlds they stay inside the image's known-free pixels.
"""

from __future__ import annotations

import argparse
import json
import math
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from island_msgs_py.inputs import read_json
from island_msgs_py.json_checks import describe
from island_msgs_py.json_io import GraphFormatError, atomic_write_text, pose_from_dict
from island_msgs_py.types import Pose2D
from island_sim.core.freespace import FreeSpaceError
from island_sim.core.places import WorldPlaces, world_places
from island_sim.core.world import World, WorldError
from island_sim.core.world_loader import load_world

from island_mapping.cli import CliError
from island_mapping.cli.args import COUNT, METRES, SEED, coordinates, output_dir
from island_mapping.core.graph import GraphError, TopoGraph
from island_mapping.evaluation.world_eval import (
    MapEvaluation,
    WorldEvalConfig,
    WorldEvalError,
    evaluate_map,
    known_free_of,
    route_pairs_from_summary,
)

SUMMARY_FIGURES = ("places", "junctions", "coverage", "junction_coverage", "known_places",
                   "islands",
                   "islands_per_place", "false_merges", "map_cycle_rank",
                   "map_place_cycle_rank", "world_cycle_rank",
                   "route_success_rate", "route_length_ratio_mean")
"""The figures printed on stdout (evaluation.json has all of them)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("--world", default="",
                        help="world file, built-in or gen: spec (default: the one summary.json "
                             "names)")
    parser.add_argument("--map", required=True, help="directory `islands explore --out` wrote")
    parser.add_argument("--out", default="", help="output directory (default: --map)")
    parser.add_argument("--resolution", type=METRES, default=None,
                        help="image worlds: metres per pixel (default: summary.json's, or 0.1)")
    parser.add_argument("--start", default="", metavar="X,Y,THETA",
                        help="start pose [m, m, rad] the reachable free space is taken from "
                             "(default: summary.json's, else the world's)")
    parser.add_argument("--routes", type=COUNT, default=20,
                        help="random island pairs for route lengths when summary.json has no "
                             "followed routes (0 = none)")
    parser.add_argument("--seed", type=SEED, default=1, help="seed of those random pairs")


def parse_pose(text: str, option: str = "--start") -> Pose2D:
    """Pose2D from 'X,Y,THETA' [m, m, rad]; CliError naming `option` if malformed."""
    return Pose2D(*coordinates(text, option, ("X", "Y", "THETA")))


def _read_json(path: Path) -> Any:
    if not path.exists():
        raise CliError(f"{path}: no such file (is --map a directory `islands explore` "
                       "wrote?)")
    return read_json(path, CliError)


def truth_places(world: World, spec: str, resolution_m: float | None,
                 start: Pose2D | None) -> WorldPlaces:
    """The world's ground-truth places from `start`; CliError (exit 2) when there is none."""
    try:
        return world_places(world, start, allowed=known_free_of(spec, resolution_m))
    except (FreeSpaceError, WorldEvalError, WorldError) as exc:
        raise CliError(str(exc)) from None


def evaluate_and_draw(world: World, places: WorldPlaces, graph: TopoGraph,
                      events: Iterable[Mapping[str, Any]],
                      route_pairs: Sequence[tuple[int, int, bool | None]],
                      out: Path, title: str, start: Pose2D | None = None) -> dict[str, Any]:
    """evaluate_map, with places.png drawn into `out`; the JSON form of the figures."""
    from island_mapping.viz.places import places_figure

    try:
        ev: MapEvaluation = evaluate_map(world, places, graph, events, route_pairs,
                                         WorldEvalConfig())
    except WorldEvalError as exc:
        raise CliError(str(exc)) from None
    origins = np.array([[i.origin_truth.x, i.origin_truth.y] for i in graph.islands()
                        if i.origin_truth is not None]).reshape(-1, 2)
    cov = f"{sum(ev.covered)}/{ev.places} places covered"
    places_figure(world.segments, places, out / "places.png", title=f"{title}: {cov}",
                  covered=ev.covered, islands_xy_m=origins, start=start)
    return ev.to_dict()


def _random_pairs(graph: TopoGraph, n: int, seed: int) -> list[Pair]:
    ids = graph.island_ids()
    if n <= 0 or len(ids) < 2:
        return []
    rng = np.random.default_rng(seed)
    out: list[Pair] = []
    for _ in range(n):
        a, b = (int(x) for x in rng.choice(ids, size=2, replace=False))
        out.append((a, b, None))
    return out


Pair = tuple[int, int, bool | None]
"""(source island, target island, route followed successfully; None: not followed)."""


def _connected_pairs(graph: TopoGraph, pairs: list[Pair]) -> list[Pair]:
    """Pairs whose islands the map joins (edges usable both ways), as routes are planned."""
    import networkx as nx

    g: nx.Graph[int] = nx.Graph()
    g.add_nodes_from(graph.island_ids())
    g.add_edges_from((e.source, e.target) for e in graph.iter_edges())
    return [p for p in pairs if nx.has_path(g, p[0], p[1])]


def _load_run(map_dir: Path) -> tuple[dict[str, Any], TopoGraph, list[Any]]:
    """summary.json, graph.json and the builder events of a run directory; CliError if not."""
    if not map_dir.is_dir():
        raise CliError(f"--map {map_dir}: not a directory")
    summary = _read_json(map_dir / "summary.json")
    if not isinstance(summary, dict):
        raise CliError(f"{map_dir / 'summary.json'}: expected a JSON object")
    try:
        graph = TopoGraph.load_json(map_dir / "graph.json")
    except (GraphError, GraphFormatError, OSError, ValueError) as exc:
        raise CliError(f"{map_dir / 'graph.json'}: {exc}") from None
    events = summary.get("builder_events")
    if not isinstance(events, list):
        raise CliError(f"{map_dir / 'summary.json'}: no builder_events list (written by "
                       "`islands explore` since it evaluates maps; re-run the exploration)")
    bad = next((k for k, e in enumerate(events) if not isinstance(e, dict)), None)
    if bad is not None:
        raise CliError(f"{map_dir / 'summary.json'}: builder_events[{bad}]: expected an object, "
                       f"got {describe(events[bad])}")
    return summary, graph, events


def _start(args: argparse.Namespace, summary: Mapping[str, Any], world: World) -> Pose2D:
    """--start, else the run's start pose, else the world's."""
    if args.start:
        return parse_pose(args.start)
    if isinstance(summary.get("start_pose"), dict):
        try:
            return pose_from_dict(summary["start_pose"], "summary.json start_pose")
        except GraphFormatError as exc:
            raise CliError(str(exc)) from None
    return world.start_pose


def run(args: argparse.Namespace) -> int:
    map_dir = Path(args.map)
    summary, graph, events = _load_run(map_dir)
    spec = args.world or summary.get("world_spec", "")
    if not spec or not isinstance(spec, str):
        raise CliError(f"--world is required (summary.json names no world_spec: "
                       f"{describe(spec)})")
    resolution = args.resolution if args.resolution is not None else summary.get("resolution_m")
    if resolution is not None and (isinstance(resolution, bool)
                                   or not isinstance(resolution, int | float)
                                   or not (math.isfinite(resolution) and resolution > 0)):
        raise CliError(f"{map_dir / 'summary.json'}: resolution_m: expected a number > 0, got "
                       f"{describe(resolution)}")
    try:
        world = load_world(spec, resolution)
    except WorldError as exc:
        raise CliError(str(exc)) from None
    start = _start(args, summary, world)
    try:
        pairs = route_pairs_from_summary(summary)
    except WorldEvalError as exc:
        raise CliError(str(exc)) from None
    if not pairs:
        pairs = _connected_pairs(graph, _random_pairs(graph, args.routes, args.seed))
    places = truth_places(world, str(spec), resolution, start)
    out = output_dir(args.out, "--out") if args.out else map_dir
    figures = evaluate_and_draw(world, places, graph, events, pairs, out,
                                title=f"{world.name} ({map_dir.name})", start=start)
    figures["world"] = world.name
    for key in ("seed", "collisions", "wall_seconds", "route_eval_wall_seconds"):
        if key in summary:
            figures[key] = summary[key]
    atomic_write_text(out / "evaluation.json", json.dumps(figures, indent=2) + "\n")
    print(json.dumps({k: figures[k] for k in ("world", *SUMMARY_FIGURES)}))
    print(f"results in {out}/evaluation.json and {out}/places.png")
    return 0


def explore_figures(world: World, spec: str, resolution_m: float | None, start: Pose2D,
                    graph: TopoGraph, events: Sequence[Mapping[str, Any]],
                    routes: Mapping[str, Any], out: Path, title: str) -> dict[str, Any]:
    """What `islands explore` adds to summary.json (and places.png): the figures of
    `evaluate_and_draw`, or {"error": why} when the world or the map cannot be evaluated."""
    try:
        places = truth_places(world, spec, resolution_m, start)
        pairs = route_pairs_from_summary({"routes": routes})
        return evaluate_and_draw(world, places, graph, events, pairs, out, title, start)
    except (CliError, ValueError) as exc:  # WorldEvalError, FreeSpaceError, WorldError...
        return {"error": str(exc)}  # the run's own results are still written


def check_image_resolution(image: Path, resolution_m: float) -> None:
    """CliError unless `image` is an existing .pgm/.png and `resolution_m` [m/px] is > 0."""
    if image.suffix.lower() not in (".pgm", ".png"):
        raise CliError(f"--resolution applies to image worlds (.pgm, .png), not {image}")
    if not (math.isfinite(resolution_m) and resolution_m > 0):
        raise CliError(f"--resolution must be > 0, got {resolution_m}")
    if not image.exists():
        raise CliError(f"{image}: no such file")


def map_world_file(image: Path, resolution_m: float, out: Path) -> Path:
    """A ROS map YAML in `out` naming `image` at `resolution_m` [m/px]: how a resolution other
    than the default reaches every node, which all load the world from one spec string."""
    check_image_resolution(image, resolution_m)
    path = out / "world_map.yaml"
    atomic_write_text(path, json.dumps({"image": str(image.resolve()), "resolution": resolution_m,
                                        "origin": [0.0, 0.0, 0.0], "name": image.stem}) + "\n")
    return path
