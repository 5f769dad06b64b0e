"""Following routes of islands on the simulated robot, and the global-odometry baseline.

Simulator-backed (numpy + island_sim cores, no ROS). `follow_route` drives a planned route of
islands with no global frame: localize and dock at the source island, then per edge execute its
strategy and localize in the next island starting from the estimate (0, 0, 0) (the strategy
ends at the target origin) and dock there (`evaluation.docking`).

An edge succeeds when that localization converged and its pose is within `success_tol_m` and
`success_tol_deg` of the robot's true pose expressed in the island frame (the island's
`origin_truth`, kept for evaluation only). The route succeeds when every edge did and the robot,
docked at the last island, truly stands within the same tolerance of that island's true origin.

`follow_route_global_odometry` is the baseline: the same trip on global odometry alone. The robot
starts with its odometry set to the source island's odometric pose recorded at exploration time,
runs the same strategies, and after each edge drives by odometry to the next island's recorded
odometric pose; no re-localization. It succeeds when it ends within the same tolerance of the
target's true origin. `evaluate_routes` compares the two on random island pairs.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from island_msgs_py.types import Edge, Island, Pose2D
from island_sim.core.hall_follower import HallFollower
from island_sim.core.robot import SimRobot
from island_sim.core.sonar import SonarModel

from island_mapping.core.graph import GraphError, TopoGraph, reverse_strategy
from island_mapping.evaluation.docking import localize_and_dock, pose_error, truth_in
from island_mapping.evaluation.navigate import (
    NavigateConfig,
    NavigateError,
    SimDriver,
    SimSetup,
    SimTimeoutError,
    execute_strategy,
)


@dataclass(frozen=True)
class EdgeResult:
    """One edge of a followed route.

    localized: the localization converged with a small residual; error_m / error_deg: its pose
    vs the true pose in the island frame; success: localized and within tolerance.
    """

    source: int
    target: int
    strategy: str
    localized: bool
    error_m: float
    error_deg: float
    success: bool


@dataclass(frozen=True)
class RouteResult:
    """A followed route: per edge results, the final true offset from the target origin."""

    route: tuple[int, ...]
    edges: tuple[EdgeResult, ...]
    final_error_m: float
    final_error_deg: float
    success: bool
    sim_time_s: float


@dataclass(frozen=True)
class RouteEvaluation:
    """Success rates of island navigation and of the global-odometry baseline on the same pairs."""

    pairs: tuple[tuple[int, int], ...]
    islands: tuple[RouteResult, ...]
    baseline: tuple[RouteResult, ...]

    @property
    def islands_success_rate(self) -> float:
        return _rate(self.islands)

    @property
    def baseline_success_rate(self) -> float:
        return _rate(self.baseline)


def _rate(results: Sequence[RouteResult]) -> float:
    return sum(r.success for r in results) / len(results) if results else math.nan


def _random_start(island: Island, cfg: NavigateConfig, rng: np.random.Generator) -> Pose2D:
    if island.origin_truth is None:
        raise NavigateError(f"island {island.id} has no origin_truth: cannot place the robot")
    rad = cfg.start_offset_m * math.sqrt(float(rng.uniform()))
    ang = float(rng.uniform(-math.pi, math.pi))
    dth = math.radians(cfg.start_offset_deg) * float(rng.uniform(-1.0, 1.0))
    return island.origin_truth.compose(Pose2D(rad * math.cos(ang), rad * math.sin(ang), dth))


def _route_edges(graph: TopoGraph, route: Sequence[int]) -> list[Edge]:
    if len(route) < 1:
        raise NavigateError("route: needs at least one island")
    edges = []
    for a, b in itertools.pairwise(route):
        try:
            edges.append(graph.get_edge(a, b))
        except (GraphError, KeyError):
            raise NavigateError(f"route: no edge {a}->{b} in the graph") from None
    return edges


def follow_route(
    graph: TopoGraph,
    route: Sequence[int],
    setup: SimSetup,
    cfg: NavigateConfig | None = None,
    rng: np.random.Generator | None = None,
    start: Pose2D | None = None,
) -> RouteResult:
    """Follow `route` (island ids joined by edges of `graph`) by island localization."""
    c = cfg if cfg is not None else NavigateConfig()
    gen = rng if rng is not None else np.random.default_rng(0)
    edges = _route_edges(graph, route)
    src = graph.get_island(route[0])
    true_start = start if start is not None else _random_start(src, c, gen)
    robot = SimRobot(setup.world, true_start, gen, setup.robot, setup.odometry)
    sim = SimDriver(setup.world, robot, SonarModel(setup.sonar), c, gen)
    follower = HallFollower(setup.follower)
    results: list[EdgeResult] = []
    ok_all = True
    try:
        sim.deadline_s = sim.t + c.max_edge_time_s
        trusted, _, _ = localize_and_dock(sim, src, Pose2D(0.0, 0.0, 0.0))
        ok_all = trusted
        for e in edges if ok_all else []:
            sim.deadline_s = sim.t + c.max_edge_time_s
            execute_strategy(sim, e.strategy, follower)
            trusted, err_m, err_deg = localize_and_dock(
                sim, graph.get_island(e.target), Pose2D(0.0, 0.0, 0.0)
            )
            good = trusted and err_m <= c.success_tol_m and err_deg <= c.success_tol_deg
            results.append(
                EdgeResult(e.source, e.target, str(e.strategy), trusted, err_m, err_deg, good)
            )
            if not good:
                ok_all = False
                break
    except SimTimeoutError:
        ok_all = False
    target = graph.get_island(route[-1])
    fin_m, fin_deg = pose_error(truth_in(target, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
    success = ok_all and fin_m <= c.success_tol_m and fin_deg <= c.success_tol_deg
    return RouteResult(tuple(route), tuple(results), fin_m, fin_deg, success, sim.t)


def follow_route_global_odometry(
    graph: TopoGraph,
    route: Sequence[int],
    origins_odom: Mapping[int, Pose2D],
    setup: SimSetup,
    cfg: NavigateConfig | None = None,
    rng: np.random.Generator | None = None,
    start: Pose2D | None = None,
) -> RouteResult:
    """The baseline: the same trip on global odometry alone (see the module docstring)."""
    c = cfg if cfg is not None else NavigateConfig()
    gen = rng if rng is not None else np.random.default_rng(0)
    edges = _route_edges(graph, route)
    for i in route:
        if i not in origins_odom:
            raise NavigateError(f"baseline: no recorded odometric pose of island {i}")
    src = graph.get_island(route[0])
    true_start = start if start is not None else _random_start(src, c, gen)
    robot = SimRobot(
        setup.world, true_start, gen, setup.robot, setup.odometry, odom_start=origins_odom[route[0]]
    )
    sim = SimDriver(setup.world, robot, SonarModel(setup.sonar), c, gen)
    follower = HallFollower(setup.follower)
    results: list[EdgeResult] = []
    ok = True
    try:
        for e in edges:
            sim.deadline_s = sim.t + c.max_edge_time_s
            execute_strategy(sim, e.strategy, follower)
            sim.go_to(origins_odom[e.target])
            tgt = graph.get_island(e.target)
            err_m, err_deg = pose_error(truth_in(tgt, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
            good = err_m <= c.success_tol_m and err_deg <= c.success_tol_deg
            results.append(
                EdgeResult(e.source, e.target, str(e.strategy), False, err_m, err_deg, good)
            )
    except SimTimeoutError:
        ok = False
    target = graph.get_island(route[-1])
    fin_m, fin_deg = pose_error(truth_in(target, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
    success = ok and fin_m <= c.success_tol_m and fin_deg <= c.success_tol_deg
    return RouteResult(tuple(route), tuple(results), fin_m, fin_deg, success, sim.t)


def with_reverse_edges(graph: TopoGraph) -> TopoGraph:
    """A copy of the graph where every edge also exists backwards (graph.reverse_strategy)."""
    edges = list(graph.iter_edges())
    have = {(e.source, e.target) for e in edges}
    for e in list(edges):
        if (e.target, e.source) not in have:
            edges.append(
                Edge(
                    e.target,
                    e.source,
                    reverse_strategy(e.strategy),
                    e.weight,
                    e.length_m,
                    e.expected_error_m,
                )
            )
            have.add((e.target, e.source))
    return TopoGraph.from_parts(graph.islands(), edges)


def evaluate_routes(
    graph: TopoGraph,
    setup: SimSetup,
    n_pairs: int,
    rng: np.random.Generator,
    origins_odom: Mapping[int, Pose2D],
    cfg: NavigateConfig | None = None,
) -> RouteEvaluation:
    """Success rates of `follow_route` and of the baseline over random island pairs.

    Pairs are drawn uniformly among ordered pairs of distinct islands joined by a route in the
    graph with every edge also usable backwards; both methods start from the same true pose.
    """
    c = cfg if cfg is not None else NavigateConfig()
    if n_pairs < 1:
        raise NavigateError(f"n_pairs: must be >= 1, got {n_pairs}")
    g2 = with_reverse_edges(graph)
    ids = g2.island_ids()
    if len(ids) < 2:
        raise NavigateError(f"evaluate_routes: needs at least 2 islands, the graph has {len(ids)}")
    pairs: list[tuple[int, int]] = []
    isl: list[RouteResult] = []
    base: list[RouteResult] = []
    for k in range(n_pairs):
        a, b = (int(x) for x in rng.choice(ids, size=2, replace=False))
        try:
            route = g2.plan_route(a, b).islands
        except GraphError:
            continue
        start = _random_start(g2.get_island(a), c, rng)
        seed = int(rng.integers(2**31))
        isl.append(follow_route(g2, route, setup, c, np.random.default_rng(seed), start))
        base.append(
            follow_route_global_odometry(
                g2, route, origins_odom, setup, c, np.random.default_rng(seed), start
            )
        )
        pairs.append((a, b))
        del k
    return RouteEvaluation(tuple(pairs), tuple(isl), tuple(base))
