"""Following routes of islands on the simulated robot, and the global-odometry baseline.

Simulator-backed (numpy + island_sim cores, no ROS). `follow_route` drives a planned route of
islands with no global frame: localize and dock at the source island, then per edge execute its
strategy and localize in the next island starting from the estimate (0, 0, 0) (the strategy
ends at the target origin) and dock there: `island_mapping.core.route`, the same generators the
explorer node runs, driven here on the simulated robot (`navigate.SimRunner`).

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

import functools
import math
import multiprocessing
from collections.abc import Generator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from island_msgs_py.types import Edge, Island, Pose2D, wrap_angle
from island_sim.core.robot import SimRobot

from island_mapping.core.graph import GraphError, TopoGraph, reverse_strategy
from island_mapping.core.route import (
    Command,
    Drive,
    Fix,
    NavigateConfig,
    NavigateError,
    RouteEnd,
    RouteTimeoutError,
    execute_strategy,
    go_to,
    route_edges,
)
from island_mapping.core.route import (
    follow_route as follow_route_by_map,
)
from island_mapping.evaluation.navigate import SimRunner, SimSetup


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
    end: RouteEnd = RouteEnd.COMPLETED  # how the route ended
    wall_contacts: int = 0  # times a wall stopped the robot on the way


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


def truth_in(island: Island, true_pose: Pose2D) -> Pose2D:
    """The true pose in the island's frame (its origin_truth), or a NavigateError."""
    if island.origin_truth is None:
        raise NavigateError(f"island {island.id} has no origin_truth: cannot evaluate")
    return true_pose.relative_to(island.origin_truth)


def pose_error(a: Pose2D, b: Pose2D) -> tuple[float, float]:
    """(position error [m], heading error [deg]) between two poses."""
    return math.hypot(a.x - b.x, a.y - b.y), abs(math.degrees(wrap_angle(a.theta - b.theta)))


def _edges(graph: TopoGraph, route: Sequence[int]) -> list[Edge]:
    return route_edges({(e.source, e.target): e for e in graph.iter_edges()}, route)


class _JudgedByTruth:
    """Route observer of the evaluation: an arrival goes on when its localization is trusted
    and, by the simulator's truth at the moment it was made, within the success tolerance."""

    def __init__(self, graph: TopoGraph, robot: SimRobot, cfg: NavigateConfig) -> None:
        self.graph, self.robot, self.cfg = graph, robot, cfg
        self.error = (math.inf, math.inf)
        self.results: list[EdgeResult] = []

    def fixed(self, fix: Fix) -> None:
        truth = truth_in(self.graph.get_island(fix.island_id), self.robot.true_pose)
        self.error = pose_error(fix.pose, truth)

    def arrived(self, edge: Edge | None, fix: Fix) -> bool:
        if edge is None:
            return fix.trusted
        c = self.cfg
        err_m, err_deg = self.error
        good = fix.trusted and err_m <= c.success_tol_m and err_deg <= c.success_tol_deg
        self.results.append(EdgeResult(edge.source, edge.target, str(edge.strategy),
                                       fix.trusted, err_m, err_deg, good))
        return good


def _result(graph: TopoGraph, route: Sequence[int], robot: SimRobot, completed: bool,
            edges: list[EdgeResult], cfg: NavigateConfig, end: RouteEnd = RouteEnd.COMPLETED
            ) -> RouteResult:
    target = graph.get_island(route[-1])
    fin_m, fin_deg = pose_error(truth_in(target, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
    success = completed and fin_m <= cfg.success_tol_m and fin_deg <= cfg.success_tol_deg
    return RouteResult(tuple(route), tuple(edges), fin_m, fin_deg, success, robot.time_s, end,
                       robot.collisions)


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
    edges = _edges(graph, route)
    src = graph.get_island(route[0])
    true_start = start if start is not None else _random_start(src, c, gen)
    robot = SimRobot(setup.world, true_start, gen, setup.robot, setup.odometry,
                     track_covariance=False)
    sim = SimRunner(setup, robot, gen, c)
    judge = _JudgedByTruth(graph, robot, c)
    islands = {i.id: i for i in graph.islands()}
    outcome = sim.run(follow_route_by_map(sim.drive, islands, edges, route[0], judge))
    return _result(graph, route, robot, outcome.completed, judge.results, c, outcome.end)


def _baseline_trip(d: Drive, graph: TopoGraph, edges: list[Edge], robot: SimRobot,
                   origins_odom: Mapping[int, Pose2D],
                   results: list[EdgeResult]) -> Generator[Command, None, bool]:
    """The baseline's motion: per edge its strategy, then by odometry to the target's recorded
    odometric pose; no re-localization. False when an edge ran out of time."""
    c = d.cfg
    try:
        for e in edges:
            d.deadline_s = d.sense.t_s + c.max_edge_time_s
            yield from execute_strategy(d, e.strategy)
            yield from go_to(d, origins_odom[e.target])
            tgt = graph.get_island(e.target)
            err_m, err_deg = pose_error(truth_in(tgt, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
            good = err_m <= c.success_tol_m and err_deg <= c.success_tol_deg
            results.append(
                EdgeResult(e.source, e.target, str(e.strategy), False, err_m, err_deg, good)
            )
    except RouteTimeoutError:
        return False
    return True


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
    edges = _edges(graph, route)
    for i in route:
        if i not in origins_odom:
            raise NavigateError(f"baseline: no recorded odometric pose of island {i}")
    src = graph.get_island(route[0])
    true_start = start if start is not None else _random_start(src, c, gen)
    robot = SimRobot(
        setup.world, true_start, gen, setup.robot, setup.odometry,
        odom_start=origins_odom[route[0]], track_covariance=False,
    )
    sim = SimRunner(setup, robot, gen, c)
    results: list[EdgeResult] = []
    ok = sim.run(_baseline_trip(sim.drive, graph, edges, robot, origins_odom, results))
    return _result(graph, route, robot, ok, results, c)


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


@dataclass(frozen=True)
class RouteDraw:
    """One random pair of the evaluation: its route, the robot's true start, the trips' seed."""

    pair: tuple[int, int]
    route: tuple[int, ...]
    start: Pose2D
    seed: int


def draw_pairs(graph: TopoGraph, n_pairs: int, rng: np.random.Generator,
               cfg: NavigateConfig | None = None) -> list[RouteDraw]:
    """`n_pairs` draws of ordered pairs of distinct islands, uniform, from `rng`; a pair joined
    by no route in `graph` is drawn (and uses up its randomness) but left out. NavigateError
    when the graph has fewer than 2 islands."""
    c = cfg if cfg is not None else NavigateConfig()
    ids = graph.island_ids()
    if len(ids) < 2:
        raise NavigateError(f"draw_pairs: needs at least 2 islands, the graph has {len(ids)}")
    draws: list[RouteDraw] = []
    for _ in range(n_pairs):
        a, b = (int(x) for x in rng.choice(ids, size=2, replace=False))
        try:
            route = tuple(graph.plan_route(a, b).islands)
        except GraphError:
            continue
        start = _random_start(graph.get_island(a), c, rng)
        draws.append(RouteDraw((a, b), route, start, int(rng.integers(2**31))))
    return draws


def run_trip(graph: TopoGraph, setup: SimSetup, origins_odom: Mapping[int, Pose2D],
             cfg: NavigateConfig, baseline: bool, draw: RouteDraw) -> RouteResult:
    """One trip of a draw, by the map or (`baseline`) on global odometry, on the draw's seed.

    It depends on nothing but its arguments, so trips may run in any order or process."""
    gen = np.random.default_rng(draw.seed)
    if baseline:
        return follow_route_global_odometry(graph, draw.route, origins_odom, setup, cfg, gen,
                                            draw.start)
    return follow_route(graph, draw.route, setup, cfg, gen, draw.start)


def evaluate_routes(
    graph: TopoGraph,
    setup: SimSetup,
    n_pairs: int,
    rng: np.random.Generator,
    origins_odom: Mapping[int, Pose2D],
    cfg: NavigateConfig | None = None,
    workers: int = 1,
) -> RouteEvaluation:
    """Success rates of `follow_route` and of the baseline over random island pairs.

    Pairs are drawn uniformly among ordered pairs of distinct islands joined by a route in the
    graph with every edge also usable backwards; both methods start from the same true pose.
    `workers` > 1 runs the trips in that many processes: every trip has its own seed, drawn
    before any runs, so the result is the sequential one whatever the number of workers.
    """
    c = cfg if cfg is not None else NavigateConfig()
    if n_pairs < 1:
        raise NavigateError(f"n_pairs: must be >= 1, got {n_pairs}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise NavigateError(f"workers: must be an int >= 1, got {workers!r}")
    g2 = with_reverse_edges(graph)
    if len(g2.island_ids()) < 2:
        raise NavigateError(
            f"evaluate_routes: needs at least 2 islands, the graph has {len(g2.island_ids())}")
    draws = draw_pairs(g2, n_pairs, rng, c)
    trip = functools.partial(run_trip, g2, setup, dict(origins_odom), c)
    kinds = [False, True] * len(draws)  # per draw: by the map, then the baseline
    jobs = [d for d in draws for _ in (0, 1)]
    if workers == 1 or len(jobs) < 2:
        results = [trip(k, d) for k, d in zip(kinds, jobs, strict=True)]
    else:
        # spawn: the caller may hold threads (DDS, executors) that a fork would copy half-way.
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=ctx) as pool:
            results = list(pool.map(trip, kinds, jobs))
    return RouteEvaluation(tuple(d.pair for d in draws), tuple(results[0::2]),
                           tuple(results[1::2]))
