"""Exploration by the map without ROS: the closed loop the nodes run under `--policy exits`.

Simulator-backed (numpy + island_sim cores, no ROS) and deterministic for a seed. Per sensor
period: a scan at the true pose; the builder decides (managed mode: `core.builder.hooks`); the
map (a TopoGraph, as the graph server would hold it) takes the builder's items; the explorer
(`core.explore.Explorer`) decides; exactly one controller answers the scan (the explorer, the
builder, or the hall follower); then the explorer's requests reach the builder and the map, as
the nodes' messages would after the scan. Every arrival's localization is judged against the
simulator's truth (false arrivals: trusted, yet more than 0.5 m or 10 deg off).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from island_msgs_py.raycast import NearbyRayCaster
from island_msgs_py.types import ExitUpdate, FloatArray, Island, NewExit, Pose2D, wrap_angle
from island_sim.core.hall_follower import HallFollower, HallFollowerConfig, TurnPolicy
from island_sim.core.robot import SimRobot
from island_sim.core.sonar import SonarModel

from island_mapping.core.builder import (
    BuilderConfig,
    BuilderError,
    BuilderEvent,
    CommandMode,
    IslandBuilder,
    event_to_dict,
)
from island_mapping.core.builder.hooks import graph_items
from island_mapping.core.explore import (
    Explorer,
    ExplorerConfig,
    FollowerAction,
    apply_to_builder,
    explorer_hooks,
)
from island_mapping.core.explore.requests import Request
from island_mapping.core.graph import TopoGraph
from island_mapping.core.route import Fix, NavigateConfig, Sense
from island_mapping.evaluation.navigate import SimSetup

STRAIGHT_DECISIONS = 2000
"""Decisions a straight-first follower's script covers (far more than a run makes)."""

FALSE_ARRIVAL_M = 0.5
FALSE_ARRIVAL_DEG = 10.0
"""A trusted arrival this far off the truth (position or heading) is a false arrival."""


@dataclass
class ArrivalCheck:
    """One arrival's localization against the truth: island, trusted, error [m, deg]."""

    island_id: int
    t_s: float
    trusted: bool
    error_m: float
    error_deg: float

    @property
    def false(self) -> bool:
        return self.trusted and (self.error_m > FALSE_ARRIVAL_M
                                 or self.error_deg > FALSE_ARRIVAL_DEG)


@dataclass
class ExitsRun:
    """What an exploration by exits produced: the map (with exit states), every builder event
    as summary.json keeps it (with the true pose), the paths, wall contacts, arrivals judged
    against the truth, the explorer's counts, whether it ended by itself (and when) and the
    scans no controller answered."""

    graph: TopoGraph
    events: list[dict[str, Any]]
    truth_path: FloatArray
    odom_path: FloatArray
    collisions: int
    arrivals: list[ArrivalCheck]
    explorer_counts: dict[str, int]
    done: bool
    sim_seconds: float
    unanswered_scans: int = 0
    contacts: list[tuple[float, float, float, str]] = field(default_factory=list)
    revisit_refusals: dict[str, int] = field(default_factory=dict)
    origins_odom: dict[int, Pose2D] = field(default_factory=dict)
    calibration: dict[str, float | int] = field(default_factory=dict)
    refused_requests: list[str] = field(default_factory=list)  # the builder's reasons

    @property
    def false_arrivals(self) -> int:
        return sum(a.false for a in self.arrivals)


_SCANS_PER_S = 10.0  # scans (and truth poses kept) per simulated second


def straight_first(cfg: HallFollowerConfig) -> HallFollowerConfig:
    """The follower's config preferring straight on at every decision (left-hand order where
    straight is closed): handed over at an exit, it carries the robot along that exit's
    hallway to the next place instead of turning off at the junction it starts in (the
    explorer, not the follower, chooses where to branch)."""
    return dataclasses.replace(cfg, policy=TurnPolicy.SCRIPTED,
                               script=",".join(["straight"] * STRAIGHT_DECISIONS))


def apply_items(graph: TopoGraph, event: BuilderEvent) -> None:
    """Apply a builder event's items to the map, as the graph server does."""
    for item in graph_items(event):
        if isinstance(item, ExitUpdate):
            graph.apply_exit_update(item)
        elif isinstance(item, Island):
            graph.put_island(item)
        else:
            graph.put_edge(item)


class _Judge:
    """Every arrival's fix against the true pose in the island's frame."""

    def __init__(self, graph: TopoGraph, robot: SimRobot) -> None:
        self.graph, self.robot = graph, robot
        self.checks: list[ArrivalCheck] = []

    def __call__(self, fix: Fix) -> None:
        island = self.graph.get_island(fix.island_id) if fix.island_id in self.graph else None
        if island is None or island.origin_truth is None:
            return
        truth = self.robot.true_pose.relative_to(island.origin_truth)
        err_m = math.hypot(fix.pose.x - truth.x, fix.pose.y - truth.y)
        err_deg = abs(math.degrees(wrap_angle(fix.pose.theta - truth.theta)))
        self.checks.append(ArrivalCheck(fix.island_id, self.robot.time_s, fix.trusted, err_m,
                                        err_deg))


def explore_by_exits(
    setup: SimSetup,
    sim_s: float,
    builder_cfg: BuilderConfig | None = None,
    explorer_cfg: ExplorerConfig | None = None,
    rng: np.random.Generator | None = None,
    start: Pose2D | None = None,
    nav: NavigateConfig | None = None,
    trace: list[dict[str, Any]] | None = None,
    follow_straight: bool = True,
) -> ExitsRun:
    """Explore `setup.world` by its exits until the explorer is done or `sim_s` simulated
    seconds have passed (module docstring); follow_straight: the follower prefers straight
    on (`straight_first`), else it keeps `setup.follower`'s policy."""
    gen = rng if rng is not None else np.random.default_rng(0)
    world = setup.world
    robot = SimRobot(world, start or world.start_pose, gen, setup.robot, setup.odometry)
    sonar, near = SonarModel(setup.sonar), NearbyRayCaster(world, setup.sonar.range_max_m)
    fcfg = straight_first(setup.follower) if follow_straight else setup.follower
    follower_rng = np.random.default_rng(int(gen.integers(2**31)))
    follower = HallFollower(fcfg, follower_rng)
    ecfg = explorer_cfg if explorer_cfg is not None else ExplorerConfig()
    graph = TopoGraph()
    judge = _Judge(graph, robot)
    explorer = Explorer(ecfg, nav, setup.follower.perception,
                        setup.follower.default_hall_width_m, on_fix=judge)
    builder = IslandBuilder(builder_cfg, hooks=explorer_hooks(ecfg, lambda: graph))
    steps, dt = max(1, round(50.0 / 10.0)), 1.0 / 50.0
    events: list[dict[str, Any]] = []
    truth, odom = list[FloatArray](), list[FloatArray]()  # one pose per scan each
    unanswered = 0
    contacts: list[tuple[float, float, float, str]] = []
    refused: list[str] = []
    builder.on_odometry(0.0, robot.odom_pose, robot.odom_covariance)
    builder.on_ground_truth(robot.true_pose)
    blocked = False
    for _ in range(int(sim_s * _SCANS_PER_S)):
        t = robot.time_s
        ranges = sonar.scan(near, robot.true_pose, gen)
        builder.set_strategy(follower.strategy())
        builder.on_scan(t, ranges, sonar.angles_rad)
        cmd = builder.command(t)
        _record(cmd.events, graph, robot.true_pose, events, truth)
        explorer.on_events(cmd.events)
        explorer.on_strategy(follower.strategy())
        explorer.on_graph(graph)
        sense = Sense(t, robot.odom_pose, ranges, sonar.angles_rad, robot.velocity[1], blocked)
        ecmd = explorer.step(sense)
        if trace is not None:
            _trace(trace, explorer, robot, ecmd.requests)
        follower.set_enabled(not ecmd.drive and cmd.mode is CommandMode.FOLLOW)
        v, w = follower.update(ranges, sonar.angles_rad, robot.odom_pose, t)
        if ecmd.drive:
            v, w = ecmd.v_mps, ecmd.w_radps
        elif cmd.mode is CommandMode.DRIVE:
            v, w = cmd.v_mps, cmd.w_radps
        elif cmd.mode is CommandMode.IDLE:
            unanswered += 1
        who = ("explorer" if ecmd.drive else "builder" if cmd.mode is CommandMode.DRIVE
               else "follower")
        if _apply_requests(ecmd.requests, builder, graph, refused):
            # a fresh follower per handover: nothing of its last stretch (hallway axis, stall
            # timer, pending turn) carries over to the exit it is handed
            follower = HallFollower(fcfg, follower_rng)
        truth.append(robot.true_pose.as_array())
        odom.append(robot.odom_pose.as_array())
        before = robot.collisions
        blocked = _advance(robot, builder, v, w, steps, dt)
        if robot.collisions > before:
            contacts.append((round(t, 1), round(robot.true_pose.x, 2), round(robot.true_pose.y, 2),
                             who))
        if explorer.done:
            break
    return ExitsRun(graph, events, np.array(truth).reshape(-1, 3), np.array(odom).reshape(-1, 3),
                    robot.collisions, judge.checks, dict(explorer.counts), explorer.done,
                    robot.time_s, unanswered, contacts, dict(builder.revisit_refusals),
                    dict(builder.island_origins_odom), builder.calibration, refused)


def _advance(robot: SimRobot, builder: IslandBuilder, v: float, w: float, steps: int,
             dt: float) -> bool:
    """Drive the robot `steps` physics steps of dt [s] at (v [m/s], w [rad/s]), the builder
    hearing odometry and the truth after each; was it blocked by a wall in any?"""
    blocked = False
    for _ in range(steps):
        blocked |= robot.step(v, w, dt).blocked
        builder.on_odometry(robot.time_s, robot.odom_pose, robot.odom_covariance)
        builder.on_ground_truth(robot.true_pose)
    return blocked


def _record(new: tuple[BuilderEvent, ...], graph: TopoGraph, truth: Pose2D,
            events: list[dict[str, Any]], history: list[FloatArray]) -> None:
    """Apply the builder's new events to the map, and keep them with the true pose (when the
    event's island_pose was seen before, the true pose then: `history`, one per scan)."""
    for e in new:
        apply_items(graph, e)
        d = event_to_dict(e)
        at = truth
        if e.island_pose_t_s is not None and history:
            k = min(len(history) - 1, max(0, round(e.island_pose_t_s * _SCANS_PER_S)))
            at = Pose2D(*(float(v) for v in history[k]))
        d["truth_pose"] = {"x": at.x, "y": at.y, "theta": at.theta}
        events.append(d)


def _trace(trace: list[dict[str, Any]], explorer: Explorer, robot: SimRobot,
           requests: tuple[object, ...]) -> None:
    """Keep the explorer's status whenever it changes, and every request, with the truth."""
    st = explorer.status.to_dict()
    tp = robot.true_pose
    if not trace or {k: trace[-1].get(k) for k in st} != st or requests:
        trace.append({"t": round(robot.time_s, 1), **st, "truth": [round(tp.x, 2),
                      round(tp.y, 2), round(math.degrees(tp.theta))],
                      "requests": [repr(r) for r in requests]})


def _apply_requests(requests: tuple[Request, ...], builder: IslandBuilder, graph: TopoGraph,
                    refused: list[str]) -> bool:
    """The explorer's requests, as the builder and graph server nodes take them (one the
    builder refuses is dropped with its reason in `refused`, as the node refuses it); True
    when the robot was handed over (the follower starts afresh)."""
    handed = False
    for r in requests:
        if isinstance(r, ExitUpdate):
            graph.apply_exit_update(r)
        elif isinstance(r, NewExit):
            graph.add_exit(r)
        else:
            try:
                done = apply_to_builder(builder, r)
            except BuilderError as exc:
                refused.append(str(exc))
                continue
            handed = handed or done.follower is FollowerAction.RESTART
    return handed

