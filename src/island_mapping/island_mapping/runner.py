"""Every node of the system in one process on one executor, on simulated time.

This is what `islands explore` runs: odometry_node (the robot; it owns /clock and steps in
lockstep with the controller so a seed fixes the run), sonar_node, hall_follower_node,
island_builder_node, island_localizer_node and topo_graph_server_node, plus a RunRecorder that
writes every topic to a rosbag2 MCAP directory, and an observer that keeps what the figures and
the summary need (true and odometric paths, builder events).

Policy `exits` (exploration by the map, issue 16) adds explorer_node, runs the builder managed
(`managed:=true`) and the follower straight-first (the explorer, not the follower, chooses where
to branch; as the offline harness `evaluation.explore_exits` does), and ends when the explorer
reports done or at `sim_seconds`. Policy `hall_following` is the paper's plain run.

The nodes talk only over their topics and services, exactly as they do when started one by one
with `ros2 run`; this module only creates them with parameter overrides and spins.
"""

from __future__ import annotations

import bisect
import json
import os
import random
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import rclpy
from island_msgs_py.conversions import ConversionError
from island_msgs_py.errors import InputError
from island_msgs_py.inputs import parse_int
from island_msgs_py.limits import MAX_DOMAIN_ID, MAX_SEED
from island_msgs_py.ros_params import destroy_nodes, ensure_ros_env
from island_msgs_py.serialized import odometry_cdr_to_pose
from island_msgs_py.types import FloatArray
from island_sim.core.hall_follower_config import HallFollowerConfig
from island_sim.core.sim_loop import SimLoopConfig
from island_sim.nodes.hall_follower_node import HallFollowerNode
from island_sim.nodes.odometry_node import OdometryNode
from island_sim.nodes.sonar_node import SonarNode
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.context import Context
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rclpy.task import Future
from std_msgs.msg import String

from island_mapping.bag.recorder import RunRecorder
from island_mapping.core.explore import unexplored_count
from island_mapping.core.graph import TopoGraph
from island_mapping.evaluation.explore_eval import Policy
from island_mapping.evaluation.explore_exits import straight_first
from island_mapping.evaluation.navigate import SimSetup
from island_mapping.executors import ExecutorKind, make_executor
from island_mapping.nodes.explorer_node import ExplorerNode
from island_mapping.nodes.island_builder_node import IslandBuilderNode
from island_mapping.nodes.island_localizer_node import IslandLocalizerNode
from island_mapping.nodes.topo_graph_server_node import TopoGraphServerNode

OBSERVER_QOS = QoSProfile(depth=1000)
"""Deep enough that a burst of ground truth between two spins is never dropped."""
RECORDER_MATCH_WAIT_S = 5.0
"""Wall time to wait for the recorder to match the run's publishers before the clock starts."""
PROGRESS_PERIOD_S = 0.2
"""Wall time between two progress reports while the run spins [s]."""
BUILDER_READY_WAIT_S = 10.0
"""Wall time to wait for the builder to find its services and subscribe before the clock
starts (it maps from the first step, so a recording replays into the same events)."""
PRIVATE_DOMAIN_MIN, PRIVATE_DOMAIN_MAX = 102, 232
"""Domains picked for unattended runs: valid for Fast DDS on Linux, above those tests use."""
NODE_NAMES = ("odometry_node", "sonar_node", "hall_follower_node", "island_builder_node",
              "island_localizer_node", "topo_graph_server_node", "explorer_node")
"""The nodes of a run, by the names `RunConfig.params` takes (explorer_node: policy exits)."""
EXPLORER_PREFIX = "explorer."
"""explorer_node's mission parameters; the managed builder takes the same (exits, revisits)."""
RECORDED_TOPICS_REQUIRED = ("/odom", "/ground_truth", "/sonar/scan", "/cmd_vel", "/clock")


class RunError(RuntimeError):
    """The in-process run could not be set up or did not finish."""


class RunParameterError(RunError, InputError):
    """A parameter override names no node of the run, or one its node rejects or lacks."""


@dataclass(frozen=True)
class RunConfig:
    """One in-process run (the defaults are the README's main job)."""

    world: str = field(default="paper_fig4", metadata={"help": "built-in world or world file"})
    seed: int = field(default=1, metadata={"help": "seed of all simulated noise [-]"})
    sim_seconds: float = field(default=900.0, metadata={"help": "simulated duration [s]"})
    record_dir: str = field(default="", metadata={"help": "MCAP output directory; empty = none"})
    wall_timeout_s: float = field(
        default=3600.0, metadata={"help": "give up after this much wall time [s]"}
    )
    domain_id: int = field(
        default=-1,
        metadata={"help": "ROS domain of the run; -1 = ROS_DOMAIN_ID if set, else a random free "
                          "one so that concurrent runs never hear each other [-]"},
    )
    params: dict[str, dict[str, Any]] = field(
        default_factory=dict,
        metadata={"help": "extra parameter overrides per node name, e.g. {'odometry_node': {...}}"},
    )
    policy: Policy = field(
        default=Policy.HALL_FOLLOWING,
        metadata={"help": "hall_following: the paper's plain run; exits: exploration by the map "
                          "(explorer_node), ending when it is done or at sim_seconds"},
    )
    executor: ExecutorKind = field(
        default=ExecutorKind.EVENTS,
        metadata={"help": "events: rclpy's events executor (the single-threaded one where rclpy "
                          "has none); single_threaded: rclpy's SingleThreadedExecutor"},
    )


@dataclass
class RunRecord:
    """What the observer saw. Paths are (K, 4) rows (t [s], x [m], y [m], theta [rad])."""

    truth_path: FloatArray
    odom_path: FloatArray
    events: list[dict[str, Any]]
    graph: TopoGraph
    sim_seconds: float
    wall_seconds: float
    collisions: int
    lockstep_timeouts: int
    bag_dir: Path | None
    # Why the builder refused revisit hypotheses (diagnostics): reason -> count.
    revisit_refusals: dict[str, int] = field(default_factory=dict)
    # What the simulated robot ran with (parameters included): route evaluation drives the same.
    sim_setup: SimSetup | None = None
    # Policy exits: did the explorer say it was done, and what it said last (status, counts).
    ended_by_itself: bool | None = None
    exits_left: int | None = None
    explorer: dict[str, Any] = field(default_factory=dict)

    @property
    def real_time_factor(self) -> float:
        return self.sim_seconds / self.wall_seconds if self.wall_seconds > 0 else float("inf")


class _Observer(Node):
    """Keeps the true and odometric paths and the builder events (subscribes like any client)."""

    def __init__(self, context: Context) -> None:
        super().__init__("islands_run_observer", context=context)
        self.truth: list[tuple[float, float, float, float]] = []
        self.odom: list[tuple[float, float, float, float]] = []
        self.events: list[dict[str, Any]] = []
        # raw: read from the bytes (island_msgs_py.serialized), without building the messages
        self.create_subscription(Odometry, "ground_truth", self._on_truth, OBSERVER_QOS, raw=True)
        self.create_subscription(Odometry, "odom", self._on_odom, OBSERVER_QOS, raw=True)
        self.create_subscription(String, "island_builder/events", self._on_event, OBSERVER_QOS)

    def _append(self, path: list[tuple[float, float, float, float]], data: bytes) -> None:
        try:
            pose, _cov, stamp_ns = odometry_cdr_to_pose(data)
        except ConversionError as exc:
            self.get_logger().warn(f"odometry ignored: {exc}", throttle_duration_sec=5.0)
            return
        path.append((stamp_ns * 1e-9, pose.x, pose.y, pose.theta))

    def _on_truth(self, data: bytes) -> None:
        self._append(self.truth, data)

    def _on_odom(self, data: bytes) -> None:
        self._append(self.odom, data)

    def _on_event(self, msg: String) -> None:
        try:
            event = json.loads(msg.data)
        except json.JSONDecodeError:
            self.get_logger().warn("builder event is not JSON; ignored")
            return
        if self.truth:  # where the robot really was (evaluation and figures only)
            at = self.truth[-1]
            seen = event.get("island_pose_t_s")  # a pose seen before the event: the truth then
            if isinstance(seen, int | float):
                k = bisect.bisect_left(self.truth, float(seen), key=lambda p: p[0])
                at = self.truth[min(k, len(self.truth) - 1)]
            event["truth_pose"] = dict(zip(("x", "y", "theta"), at[1:], strict=True))
        self.events.append(event)


def resolve_domain_id(requested: int) -> int:
    """The domain a run uses: `requested` if >= 0, else ROS_DOMAIN_ID, else a random one.

    A run publishes /odom, /cmd_vel, ... like any robot; two runs (or a run and a test) in one
    domain would drive each other's nodes, so an unset domain means a private one."""
    if requested >= 0:
        return requested
    env = os.environ.get("ROS_DOMAIN_ID", "").strip()
    if env:
        try:
            return parse_int(env, "ROS_DOMAIN_ID", RunParameterError, 0, MAX_DOMAIN_ID)
        except RunParameterError as exc:
            raise RunParameterError(f"{exc} (a Fast DDS domain on Linux)") from None
    return random.SystemRandom().randint(PRIVATE_DOMAIN_MIN, PRIVATE_DOMAIN_MAX)


_N = TypeVar("_N", bound=Node)


def _seed(seed: int, offset: int) -> int:
    """The seed of the run's node number `offset`: seed + offset, kept in the int64 range of a
    ROS integer parameter."""
    return (seed + offset) % (MAX_SEED + 1)


def _make_node(ctx: Context, cls: Callable[..., _N], name: str, base: dict[str, Any],
               params: dict[str, dict[str, Any]], made: list[Node]) -> _N:
    """The node `name` with the run's parameters `base` and the user's `params[name]` over
    them, appended to `made` (destroyed on the way out); a RunError naming a rejected value or
    a parameter the node does not declare."""
    extra = params.get(name, {})
    overrides = [Parameter(k, value=v) for k, v in {**base, **extra}.items()]
    try:
        node = cls(context=ctx, parameter_overrides=overrides)
    except Exception as exc:  # a bad value: rclpy and the core configs raise various types
        raise RunParameterError(f"{name} rejected the parameters {extra}: {exc}") from None
    made.append(node)
    unknown = sorted(k for k in extra if not node.has_parameter(k))
    if unknown:
        raise RunParameterError(f"{name} has no parameter {', '.join(unknown)}")
    return node


def run(cfg: RunConfig, progress: Callable[[float], None] | None = None) -> RunRecord:
    """Run every node in one process until `cfg.sim_seconds` of simulated time have passed."""
    ensure_ros_env()
    ctx = Context()
    rclpy.init(context=ctx, domain_id=resolve_domain_id(cfg.domain_id))
    nodes: list[Node] = []
    recorder: RunRecorder | None = None
    executor = make_executor(cfg.executor, ctx)
    try:
        sim_time = {"use_sim_time": True}
        exits = cfg.policy is Policy.EXITS
        names = NODE_NAMES if exits else NODE_NAMES[:-1]
        unknown = sorted(set(cfg.params) - set(names))
        if unknown:
            raise RunParameterError(f"no node {', '.join(unknown)} in the run (nodes: "
                           f"{', '.join(names)}; explorer_node runs with the policy exits)")
        odo = _make_node(ctx, OdometryNode, "odometry_node", {
            "world": cfg.world, "seed": _seed(cfg.seed, 0), "sim.real_time_factor": 0.0,
            "sim.lockstep": True, "sim.stop_after_s": float(cfg.sim_seconds),
            **_sensor_rate_topics(cfg.params),
        }, cfg.params, nodes)
        sonar = _make_node(ctx, SonarNode, "sonar_node",
                           {**sim_time, "world": cfg.world, "seed": _seed(cfg.seed, 1)}, cfg.params,
                           nodes)
        follower = _make_node(ctx, HallFollowerNode, "hall_follower_node",
                              {**sim_time, "seed": _seed(cfg.seed, 2),
                               **(_straight_first() if exits else {})}, cfg.params, nodes)
        builder = _make_node(ctx, IslandBuilderNode, "island_builder_node",
                             {**sim_time, **(_managed(cfg.params) if exits else {})},
                             cfg.params, nodes)
        explorer = _make_node(ctx, ExplorerNode, "explorer_node", sim_time, cfg.params,
                              nodes) if exits else None
        _make_node(ctx, IslandLocalizerNode, "island_localizer_node", sim_time, cfg.params, nodes)
        server = _make_node(ctx, TopoGraphServerNode, "topo_graph_server_node",
                            {**sim_time, "storage_path": ""}, cfg.params, nodes)
        observer = _Observer(ctx)
        nodes.append(observer)
        # The recorder matches every publisher before the simulation may take its first step.
        executor.add_node(observer)
        if cfg.record_dir:
            recorder = RunRecorder(observer, cfg.record_dir)
            _wait_for_recorder(executor, recorder)
        for n in nodes[:-1]:
            if n is not odo:
                executor.add_node(n)
        _wait_for_builder(executor, builder, explorer)
        executor.add_node(odo)  # the clock starts
        wall = _spin_until_finished(executor, odo, explorer, observer, cfg, progress)
        if progress is not None:
            progress(1.0)
        return RunRecord(
            truth_path=np.asarray(observer.truth, dtype=np.float64).reshape(-1, 4),
            odom_path=np.asarray(observer.odom, dtype=np.float64).reshape(-1, 4),
            events=list(observer.events),
            graph=server.graph,
            sim_seconds=odo.sim_time_ns * 1e-9,
            wall_seconds=wall,
            collisions=int(odo.robot.collisions),
            lockstep_timeouts=int(odo.lockstep_timeouts),
            revisit_refusals=dict(builder.builder.revisit_refusals),
            sim_setup=SimSetup(world=odo.world, sonar=sonar.cfg.sonar, robot=odo.cfg.robot,
                               odometry=odo.cfg.odometry, follower=follower.cfg.follower),
            bag_dir=recorder.path if recorder is not None else None,
            ended_by_itself=None if explorer is None else explorer.done,
            exits_left=None if explorer is None else unexplored_count(server.graph),
            explorer={} if explorer is None else {
                "status": explorer.explorer.status.to_dict(),
                "counts": dict(explorer.explorer.counts),
                "scans_decided": explorer.scans_decided,
                "scans_answered": explorer.scans_answered,
                "refused_requests": explorer.refused_requests + builder.refused_requests},
        )
    finally:
        if recorder is not None:
            recorder.close()
        executor.shutdown()
        destroy_nodes(nodes)
        ctx.try_shutdown()


def _spin_until_finished(executor: Executor, odo: OdometryNode,
                         explorer: ExplorerNode | None, observer: Node, cfg: RunConfig,
                         progress: Callable[[float], None] | None) -> float:
    """Spin until the simulator has run `cfg.sim_seconds` (or the explorer, if any, is done),
    then let the last messages and the builder's final service calls arrive; returns the wall
    time since the clock started [s].

    One `spin_until_future_complete` call: the executor (the events executor's loop is C++)
    dispatches every callback without a return to Python per message, and stops right after
    the callback in which the simulator reached the end or the explorer said it is done."""
    wall0 = time.monotonic()
    stop = Future()

    def _stop(_done: Future) -> None:
        if not stop.done():
            stop.set_result(True)

    odo.finished_future.add_done_callback(_stop)
    if explorer is not None:
        explorer.done_future.add_done_callback(_stop)
    timer = None
    if progress is not None:
        report = progress
        timer = observer.create_timer(
            PROGRESS_PERIOD_S,
            lambda: report(min(1.0, odo.sim_time_ns * 1e-9 / cfg.sim_seconds)),
            clock=Clock(clock_type=ClockType.STEADY_TIME))
    executor.spin_until_future_complete(stop, timeout_sec=cfg.wall_timeout_s)
    if timer is not None:
        observer.destroy_timer(timer)
    if not stop.done():
        raise RunError(
            f"run did not reach {cfg.sim_seconds:.0f} s of sim time within "
            f"{cfg.wall_timeout_s:.0f} s wall (at {odo.sim_time_ns * 1e-9:.0f} s)"
        )
    settle = time.monotonic() + 0.5
    while time.monotonic() < settle:
        executor.spin_once(timeout_sec=0.02)
    return time.monotonic() - wall0


def _sensor_rate_topics(params: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """/clock and /ground_truth at the sensor rate (unless the user sets them): in lockstep the
    steps between two sensor instants are taken at once, so a sim-time node learns nothing from
    a /clock in between, and /ground_truth is read at the sensor stamps only (the sonar fires on
    them, the builder and the observer keep the sample of each scan's stamp). /odom stays at
    every step: the builder's eq. 3 integrates every increment. Saves about 450 of the about
    950 message deliveries per simulated second (`bench/bench_live_speed.py`)."""
    own = params.get("odometry_node", {})
    rate = float(own.get("sim.sensor_rate_hz", SimLoopConfig.sensor_rate_hz))
    return {k: own.get(k, rate) for k in ("sim.clock_rate_hz", "sim.truth_rate_hz")}


def _straight_first() -> dict[str, Any]:
    """The follower's parameters for policy exits: straight on at every decision."""
    cfg = straight_first(HallFollowerConfig())
    return {"follower.policy": cfg.policy.value, "follower.script": cfg.script}


def _managed(params: dict[str, dict[str, Any]]) -> dict[str, Any]:
    """The builder's parameters for policy exits: managed, with explorer_node's `explorer.*`
    overrides (the exits and revisits it finds are the explorer's)."""
    shared = {k: v for k, v in params.get("explorer_node", {}).items()
              if k.startswith(EXPLORER_PREFIX)}
    return {"managed": True, **shared}


def _wait_for_builder(executor: Executor, builder: IslandBuilderNode,
                      explorer: ExplorerNode | None = None) -> None:
    """Spin until the builder maps (its services found) and hears the robot's topics, and the
    explorer (if any) explores."""
    deadline = time.monotonic() + BUILDER_READY_WAIT_S
    waiting: list[Node] = [builder] if explorer is None else [builder, explorer]
    while time.monotonic() < deadline:
        if builder.mapping and (explorer is None or explorer.exploring) and all(
            s.get_publisher_count() > 0 for n in waiting for s in n.subscriptions
            if s.topic_name not in ("/clock", "/island_builder/decision")
        ):
            return
        executor.spin_once(timeout_sec=0.05)
    raise RunError(f"island_builder_node did not start mapping within {BUILDER_READY_WAIT_S:g} "
                   "s wall (its services or the robot's topics were not found)")


def _wait_for_recorder(executor: Executor, recorder: RunRecorder) -> None:
    """Spin until the recorder has matched the publishers whose first messages matter."""
    deadline = time.monotonic() + RECORDER_MATCH_WAIT_S
    while time.monotonic() < deadline:
        recorder.rescan()
        matched = recorder.matched_publishers()
        if all(matched.get(t, 0) > 0 for t in RECORDED_TOPICS_REQUIRED):
            return
        executor.spin_once(timeout_sec=0.05)
