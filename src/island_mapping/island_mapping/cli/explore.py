"""islands explore: the main job (paper section 8.2).

Runs every node in one process on simulated time (robot, sonar, hall follower, island builder,
island localizer, topological graph server, recorder; with --policy exits also the explorer,
which drives by the map to the nearest unexplored exit, and the run ends when it says no
unexplored exit is left, or at --sim-seconds), then writes to --out:

  graph.json, graph.geojson, graph.graphml   the map M = {V, E} (Nav2 Route Server GeoJSON)
  exploration.png                            path and island attempts, like Fig. 4a
  topology.png                               island line models in their own frames, Fig. 4b
  strategies.txt                             the links' control strategies, like Table 1
  run_bag/                                   the MCAP recording of every topic (rosbag2 layout)
  summary.json                               counts, true island origins, where islands landed,
                                             route-following success vs global odometry, the
                                             builder events and the map measured against the
                                             world's places (`islands evaluate`)
  places.png                                 the world's places, covered or missed
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from island_msgs_py.json_io import atomic_write_text, pose_from_dict, pose_to_dict
from island_msgs_py.types import FloatArray, Pose2D
from island_sim.core.world import World, WorldError
from island_sim.core.world_loader import load_world

from island_mapping.cli import CliError
from island_mapping.cli.args import (
    COUNT,
    DOMAIN_ID,
    METRES,
    POSITIVE_SECONDS,
    SEED,
    output_dir,
)
from island_mapping.cli.params import parse_assignments, parse_node_assignments
from island_mapping.cli.progress import ProgressBar
from island_mapping.core.graph import TopoGraph
from island_mapping.core.placement import (
    PlaceKind,
    classify_place,
    feature_distance_m,
    placement_counts,
)
from island_mapping.core.route import NavigateError
from island_mapping.evaluation.explore_eval import Policy
from island_mapping.evaluation.navigate import SimSetup
from island_mapping.evaluation.routes import EdgeResult, evaluate_routes
from island_mapping.executors import ExecutorKind

if TYPE_CHECKING:
    from island_mapping.runner import RunRecord

PROGRESS_STEPS = 1000
"""Resolution of the progress bar (per mille of the simulated duration)."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.description = __doc__
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.add_argument("--world", default="paper_fig4",
                        help="world file, built-in name or gen:office:seed=N,scale=S")
    parser.add_argument("--resolution", type=METRES, default=None,
                        help="image worlds: metres per pixel (default 0.1)")
    parser.add_argument("--start", default="", metavar="X,Y,THETA",
                        help="start pose [m, m, rad] (default: the world's)")
    parser.add_argument("--out", required=True, help="output directory (created)")
    parser.add_argument("--seed", type=SEED, default=1, help="seed of every simulated noise")
    parser.add_argument("--sim-seconds", type=POSITIVE_SECONDS, default=900.0,
                        help="simulated exploration time [s] (default 900)")
    parser.add_argument("--routes", type=COUNT, default=20,
                        help="random island pairs for the route-following evaluation (0 = skip)")
    parser.add_argument("--route-workers", type=COUNT, default=1,
                        help="processes following the evaluation's routes (default 1; 0 = one "
                             "per CPU); the figures do not depend on it")
    parser.add_argument("--no-record", action="store_true", help="do not write run_bag/")
    parser.add_argument("--wall-timeout", type=POSITIVE_SECONDS, default=3600.0,
                        help="give up after this much wall time [s]")
    parser.add_argument("--domain-id", type=DOMAIN_ID, default=None,
                        help="ROS domain of the run (default: ROS_DOMAIN_ID if set, else a random "
                             "private one, printed, so concurrent runs stay apart)")
    parser.add_argument("--builder-param", action="append", default=[], metavar="NAME=VALUE",
                        help="island_builder_node parameter, e.g. builder.register_legs=true "
                             "(VALUE parsed as YAML, typed as ROS parameters are: 1.0 for a "
                             "float); repeatable")
    parser.add_argument("--param", action="append", default=[], metavar="NODE:NAME=VALUE",
                        help="any node's parameter, e.g. "
                             "odometry_node:odometry.var_heading_rad2_per_rad=0.002; repeatable")
    parser.add_argument("--policy", choices=[p.value for p in Policy],
                        default=Policy.HALL_FOLLOWING.value,
                        help="hall_following (default): the paper's plain hall following; "
                             "exits: exploration by the map (explorer_node), ending by itself "
                             "when no unexplored exit is left")
    parser.add_argument("--executor", choices=[k.value for k in ExecutorKind],
                        default=ExecutorKind.EVENTS.value,
                        help="the executor all nodes share: events (default; rclpy's events "
                             "executor, the single-threaded one where rclpy has none) or "
                             "single_threaded")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")


def _origins_odom(events: list[dict[str, Any]]) -> dict[int, Pose2D]:
    """Each accepted island's origin in the odometry frame, from the builder's events."""
    out: dict[int, Pose2D] = {}
    for e in events:
        if e.get("kind") == "island_accepted" and e.get("anchor_odom") and e.get("island"):
            out[int(e["island"]["id"])] = pose_from_dict(e["anchor_odom"])
    return out


def _counts(events: list[dict[str, Any]]) -> dict[str, int]:
    kinds = [e.get("kind") for e in events]
    return {
        "attempts": kinds.count("attempt_started") + kinds.count("attempt_failed_at_once"),
        "stars_started": kinds.count("attempt_started"),
        "failed_at_once": kinds.count("attempt_failed_at_once"),
        "accepted": kinds.count("island_accepted"),
        "dismissed": kinds.count("attempt_dismissed"),
        "revisits": kinds.count("island_revisited"),
    }


def _route_summary(graph: TopoGraph, setup: SimSetup, events: list[dict[str, Any]],
                   n_pairs: int, seed: int, workers: int) -> dict[str, Any]:
    if n_pairs <= 0:
        return {"skipped": "--routes 0"}
    try:
        ev = evaluate_routes(graph, setup, n_pairs, np.random.default_rng(seed),
                             _origins_odom(events), workers=workers or os.cpu_count() or 1)
    except NavigateError as exc:
        return {"skipped": str(exc)}
    return {
        "pairs": len(ev.pairs),
        "islands_success_rate": ev.islands_success_rate,
        "global_odometry_success_rate": ev.baseline_success_rate,
        "per_route": [
            {"source": a, "target": b, "islands_success": r.success,
             "global_odometry_success": base.success,
             "islands_final_error_m": round(r.final_error_m, 3),
             "islands_final_error_deg": round(r.final_error_deg, 2),
             "global_odometry_final_error_m": round(base.final_error_m, 3),
             "islands_edges": [_edge_summary(e) for e in r.edges]}
            for (a, b), r, base in zip(ev.pairs, ev.islands, ev.baseline, strict=True)
        ],
    }


def _edge_summary(e: EdgeResult) -> dict[str, Any]:
    """One followed edge: its strategy, whether the arrival localized, and how far that fit was
    from the true pose in the target island's frame."""
    return {**dataclasses.asdict(e), "error_m": round(e.error_m, 3),
            "error_deg": round(e.error_deg, 2)}


def _ending(by_itself: bool | None, exits_left: int | None, sim_s: float) -> str:
    """What the console says about how an exploration by exits ended."""
    if by_itself:
        return (f"exploration ended by itself at {sim_s:.0f} s: no unexplored exit left "
                f"(the map shows {exits_left})")
    return (f"exploration stopped at the sim-time cap ({sim_s:.0f} s) with {exits_left} "
            "unexplored exit(s) left")


def run(args: argparse.Namespace) -> int:
    from island_mapping.cli.evaluate import (
        check_image_resolution,
        explore_figures,
        map_world_file,
        parse_pose,
    )
    from island_mapping.evaluation.world_eval import compact_events
    from island_mapping.runner import RunConfig, RunError, RunParameterError
    from island_mapping.runner import run as run_nodes

    if not args.sim_seconds > 0:
        raise CliError(f"--sim-seconds must be > 0, got {args.sim_seconds}")
    params = _node_params(args.param, args.builder_param)
    try:
        world = load_world(args.world, args.resolution)
    except WorldError as exc:
        raise CliError(str(exc)) from None
    start = parse_pose(args.start) if args.start else world.start_pose
    if args.start:
        params.setdefault("odometry_node", {})["start_pose"] = args.start
    if args.resolution is not None:
        check_image_resolution(Path(args.world), args.resolution)
    out = output_dir(args.out)
    spec = (str(map_world_file(Path(args.world), args.resolution, out))
            if args.resolution is not None else args.world)
    bag_dir = out / "run_bag"
    if bag_dir.exists() and not args.no_record:
        raise CliError(f"{bag_dir} exists: choose another --out or remove it")
    bar = None if args.quiet else ProgressBar(f"explore {world.name}")
    progress = None if bar is None else (
        lambda frac: bar(round(frac * PROGRESS_STEPS), PROGRESS_STEPS))
    cfg = RunConfig(world=spec, seed=args.seed, sim_seconds=args.sim_seconds,
                    record_dir="" if args.no_record else str(bag_dir),
                    wall_timeout_s=args.wall_timeout, domain_id=_domain_id(args.domain_id),
                    params=params, policy=Policy(args.policy),
                    executor=ExecutorKind(args.executor))
    try:
        rec = run_nodes(cfg, progress)
    except RunParameterError as exc:
        raise CliError(str(exc)) from None
    except RunError as exc:
        print(f"islands explore: {exc}", file=sys.stderr)
        return 1
    graph = rec.graph
    graph.save_all(out)
    title = f"{world.name}, seed {args.seed}, {rec.sim_seconds:.0f} s"
    _write_figures(world, rec, out, title)
    t0 = time.monotonic()
    setup = rec.sim_setup if rec.sim_setup is not None else SimSetup(world=world)
    routes = _route_summary(graph, setup, rec.events, args.routes, args.seed, args.route_workers)
    origins = {i.id: i.origin_truth for i in graph.islands() if i.origin_truth is not None}
    summary = {
        "world": world.name,
        "seed": args.seed,
        "parameters": {k: v for k, v in params.items() if v},
        "sim_seconds": rec.sim_seconds,
        "wall_seconds": round(rec.wall_seconds, 2),
        "real_time_factor": round(rec.real_time_factor, 2),
        "route_eval_wall_seconds": round(time.monotonic() - t0, 2),
        **_counts(rec.events),
        "islands": len(graph),
        "edges": len(graph.edges()),
        "collisions": rec.collisions,
        "lockstep_timeouts": rec.lockstep_timeouts,
        "revisit_refusals": rec.revisit_refusals,
        **_placement_summary(world.segments, origins),
        "routes": routes,
        "bag": str(rec.bag_dir) if rec.bag_dir is not None else None,
        "world_spec": spec,
        "resolution_m": args.resolution,
        "start_pose": pose_to_dict(start),
        "world_evaluation": explore_figures(world, spec, args.resolution, start, graph,
                                            rec.events, routes, out, title),
        "builder_events": compact_events(rec.events),
        **_explorer_summary(cfg.policy, rec),
    }
    atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
    _print_result(summary, routes, out)
    return 0


def _explorer_summary(policy: Policy, rec: RunRecord) -> dict[str, Any]:
    """summary.json's keys of an exploration by exits: how it ended (none for plain runs)."""
    if policy is not Policy.EXITS:
        return {}
    return {"policy": policy.value, "ended_by_itself": rec.ended_by_itself,
            "exits_left": rec.exits_left, "explorer": rec.explorer}


def _node_params(param: list[str], builder_param: list[str]
                 ) -> dict[str, dict[str, Any]]:
    """--param NODE:NAME=V and --builder-param NAME=V as parameters per node."""
    params = parse_node_assignments(param, "--param")
    params.setdefault("island_builder_node", {}).update(
        parse_assignments(builder_param, "--builder-param"))
    return params


def _domain_id(requested: int | None) -> int:
    """The run's ROS_DOMAIN_ID (the requested one, the environment's, or a random private one),
    printed with how to watch the run."""
    from island_mapping.runner import RunParameterError, resolve_domain_id

    try:
        domain = resolve_domain_id(-1 if requested is None else requested)
    except RunParameterError as exc:
        raise CliError(str(exc)) from None
    print(f"islands explore: ROS_DOMAIN_ID={domain} (watch with "
          f"`ROS_DOMAIN_ID={domain} islands topic echo /hall_follower/strategy`)", file=sys.stderr)
    return domain


def _write_figures(world: World, rec: RunRecord, out: Path, title: str) -> None:
    """exploration.png (Fig. 4a), topology.png (Fig. 4b), strategies.txt (Table 1)."""
    from island_mapping.viz.explore import exploration_figure, strategies_table, topology_figure

    exploration_figure(world.segments, rec.truth_path, rec.events, out / "exploration.png",
                       title=f"Exploration: {title} (cf. paper Fig. 4a)")
    topology_figure(rec.graph, out / "topology.png",
                    title=f"Islands of reliability: {title} (cf. paper Fig. 4b)")
    atomic_write_text(out / "strategies.txt", strategies_table(rec.graph))


def _placement_summary(segments: FloatArray, origins: dict[int, Pose2D]) -> dict[str, Any]:
    """Where the islands' true origins landed (summary.json keys)."""
    return {
        "island_origins_truth": {str(k): pose_to_dict(v) for k, v in origins.items()},
        "island_places": {
            str(k): classify_place(segments, v.x, v.y).value for k, v in origins.items()
        },
        "island_feature_distance_m": {
            str(k): feature_distance_m(segments, v.x, v.y) for k, v in origins.items()
        },
        "placement_counts": placement_counts(segments, origins.values()),
        "plain_hallway_islands": sum(
            classify_place(segments, v.x, v.y) is PlaceKind.PLAIN_HALLWAY
            for v in origins.values()
        ),
    }


def _print_result(summary: dict[str, Any], routes: dict[str, Any], out: Path) -> None:
    print(json.dumps({k: summary[k] for k in (
        "world", "sim_seconds", "real_time_factor", "attempts", "accepted", "dismissed",
        "failed_at_once", "revisits", "islands", "edges", "plain_hallway_islands",
        "collisions")}))
    if isinstance(routes.get("islands_success_rate"), float):
        print(f"routes: islands {routes['islands_success_rate']:.0%}, "
              f"global odometry {routes['global_odometry_success_rate']:.0%} "
              f"over {routes['pairs']} pairs")
    if "ended_by_itself" in summary:
        print(_ending(summary["ended_by_itself"], summary["exits_left"], summary["sim_seconds"]))
    print(f"results in {out}/")
