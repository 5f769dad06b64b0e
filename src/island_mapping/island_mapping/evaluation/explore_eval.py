"""One exploration measured against its world, without ROS: the figures of issue 16 per run.

`measure_exploration(spec, policy, seed, sim_s)` explores the world offline (`Policy.EXITS`:
`explore_exits.explore_by_exits`, the explorer; `Policy.HALL_FOLLOWING`: `explore.explore`, the
paper's plain hall following), follows `routes` random island pairs by the map
(`routes.evaluate_routes`) and measures the map with the world yardstick (`world_eval`):
coverage of places and junctions, islands per place, false merges, cycle rank against the
world's, route success and route length ratio, plus wall contacts, false arrivals and whether
the exploration ended by itself. Deterministic for a seed.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from enum import StrEnum
from typing import Any

import numpy as np
from island_msgs_py.geometry import wrap_angles
from island_msgs_py.types import Pose2D, wrap_angle
from island_sim.core.places import world_places
from island_sim.core.world_loader import load_world

from island_mapping.core.builder import event_to_dict
from island_mapping.core.graph import TopoGraph
from island_mapping.core.route import NavigateError, RouteEnd
from island_mapping.evaluation.explore import explore
from island_mapping.evaluation.explore_exits import explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_mapping.evaluation.routes import evaluate_routes
from island_mapping.evaluation.world_eval import evaluate_map, known_free_of

SENSOR_RATE_HZ = 10.0
"""Scans per simulated second in both harnesses (the truth path has one pose per scan)."""

HEADLINE = ("places", "covered_places", "coverage", "junctions", "covered_junctions",
            "junction_coverage", "known_places", "known_junctions", "islands",
            "islands_per_place", "islands_off_places",
            "false_merges", "missed_closures", "revisits", "map_cycle_rank",
            "map_place_cycle_rank", "world_cycle_rank", "routes", "route_success_rate",
            "route_length_ratio_mean", "route_length_ratio_max")
"""The world-evaluation figures a measurement reports."""


class Policy(StrEnum):
    EXITS = "exits"  # exploration by the map (the explorer)
    HALL_FOLLOWING = "hall_following"  # the paper's plain hall following


def _plain(setup: SimSetup, sim_s: float, rng: np.random.Generator, start: Pose2D | None
           ) -> tuple[TopoGraph, list[dict[str, Any]], dict[int, Pose2D], dict[str, Any]]:
    res = explore(setup, sim_s, rng=rng, start=start)
    events = []
    for e in res.events:
        d = event_to_dict(e)
        k = min(len(res.truth_path) - 1, round(e.t_s * SENSOR_RATE_HZ))
        x, y, th = (float(v) for v in res.truth_path[k])
        d["truth_pose"] = {"x": x, "y": y, "theta": th}
        events.append(d)
    extra = {"wall_contacts": res.collisions, "ended_by_itself": False, "sim_seconds": sim_s,
             "false_arrivals": None}
    return res.graph(), events, dict(res.origins_odom), extra


def _heading_drift(truth: np.ndarray, odom: np.ndarray) -> dict[str, float]:
    """The odometry's heading error at the end of the run and the robot's net turn [deg]."""
    if len(truth) < 2:
        return {"odom_heading_error_deg": 0.0, "net_turn_deg": 0.0}
    err = wrap_angle(float(odom[-1, 2] - truth[-1, 2] - (odom[0, 2] - truth[0, 2])))
    turn = float(np.sum(wrap_angles(np.diff(truth[:, 2]))))
    return {"odom_heading_error_deg": round(math.degrees(err), 1),
            "net_turn_deg": round(math.degrees(turn))}


def _exits(setup: SimSetup, sim_s: float, rng: np.random.Generator, start: Pose2D | None
           ) -> tuple[TopoGraph, list[dict[str, Any]], dict[int, Pose2D], dict[str, Any]]:
    run = explore_by_exits(setup, sim_s, rng=rng, start=start)
    # the scan periods with a contact, by who drove then
    by = dict(Counter(who for *_, who in run.contacts))
    extra = {"wall_contacts": run.collisions, "contact_periods_by_driver": by,
             "ended_by_itself": run.done,
             "sim_seconds": round(run.sim_seconds, 1), "false_arrivals": run.false_arrivals,
             "arrivals": len(run.arrivals), "explorer": run.explorer_counts,
             "unanswered_scans": run.unanswered_scans, "calibration": run.calibration,
             "revisit_refusals": run.revisit_refusals,
             "refused_requests": dict(Counter(r.split(":")[0] for r in run.refused_requests)),
             **_heading_drift(run.truth_path, run.odom_path),
             "exits_left": sum(e.state.value == "unexplored" for i in run.graph.islands()
                               for e in i.exits)}
    return run.graph, run.events, dict(run.origins_odom), extra


def measure_exploration(spec: str, policy: Policy, seed: int, sim_s: float, routes: int = 10,
                        resolution_m: float | None = None, start: Pose2D | None = None
                        ) -> dict[str, Any]:
    """Explore world `spec` by `policy` for at most sim_s [s] (seed `seed`), follow `routes`
    random island pairs by the map, and measure (module docstring); a flat JSON-able dict."""
    world = load_world(spec, resolution_m)
    setup = SimSetup(world=world)
    t0 = time.monotonic()
    run = _exits if policy is Policy.EXITS else _plain
    graph, events, origins_odom, extra = run(setup, sim_s, np.random.default_rng(seed), start)
    explore_wall_s = time.monotonic() - t0
    pairs: list[tuple[int, int, bool | None]] = []
    ends: dict[str, int] = {}
    if routes > 0 and len(graph) >= 2:
        try:
            ev = evaluate_routes(graph, setup, routes, np.random.default_rng(seed), origins_odom)
            pairs = [(a, b, r.success) for (a, b), r in zip(ev.pairs, ev.islands, strict=True)]
            for r in ev.islands:
                key = r.end.value if r.success or r.end is not RouteEnd.COMPLETED else (
                    "off_target")
                ends[key] = ends.get(key, 0) + 1
        except NavigateError:
            pairs = []
    places = world_places(world, start, allowed=known_free_of(spec, resolution_m))
    figures = evaluate_map(world, places, graph, events, pairs).to_dict()
    return {"world": spec, "policy": policy.value, "seed": seed,
            **{k: figures[k] for k in HEADLINE}, **extra,
            "route_ends": ends,
            "explore_wall_s": round(explore_wall_s, 1),
            "total_wall_s": round(time.monotonic() - t0, 1),
            "missed_places": [p for p in figures["place_list"] if not p["covered"]]}
