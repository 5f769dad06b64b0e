"""explorer_node and the builder's explorer interface (issue 16), in process: the explorer answers
a scan only when its mission drives or nobody else does, and is silent while handed over; bad
explorer requests to the builder are refused with a reason and never kill it; a small world
explored live by `islands explore --policy exits` ends by itself with no unexplored exit left."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import TwistStamped
from island_mapping.cli import main
from island_mapping.conversions import decision_to_msg, msg_to_decision
from island_mapping.core.builder import BuilderEvent, CommandMode, EventKind
from island_mapping.core.graph import TopoGraph
from island_mapping.evaluation.explore_eval import Policy
from island_mapping.nodes.explorer_node import ExplorerNode
from island_mapping.nodes.island_builder_node import IslandBuilderNode
from island_mapping.runner import RunConfig, RunParameterError, run
from island_msgs_py.conversions import (
    arrays_to_scan,
    island_to_parameter,
    parameter_to_item,
    pose_to_odometry,
    time_to_ns,
)
from island_msgs_py.qos import LATCHED
from island_msgs_py.types import (
    Exit,
    ExitState,
    ExitUpdate,
    Island,
    LineModel,
    ModelType,
    Pose2D,
)
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue, SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String

QOS = QoSProfile(depth=100)
ORIGIN = Pose2D(0.0, 0.0, 0.0)
ANGLES = np.linspace(-np.pi, np.pi, 16, endpoint=False)
CORRIDOR = np.array([[-5.0, -1.5, 10.0, -1.5], [-5.0, 1.5, 10.0, 1.5], [-5.0, -1.5, -5.0, 1.5]])
"""A corridor end: island 0's model, its one exit straight ahead (theta 0)."""


def _p(name: str, value: Any) -> Parameter:
    return Parameter(name, value=value)


class _FakeRobotAndBuilder(Node):
    """The explorer's world: odometry, scans, the builder's decisions, the map; it serves
    island_builder/explorer and topo_graph/add (recording what it is asked) and hears cmd_vel."""

    def __init__(self, context: Any) -> None:
        super().__init__("explorer_test_world", context=context)
        self.odom = self.create_publisher(Odometry, "/odom", QOS)
        self.scan = self.create_publisher(LaserScan, "/sonar/scan", QOS)
        self.decision = self.create_publisher(String, "/island_builder/decision", QOS)
        self.graph = self.create_publisher(String, "/topo_graph/json", LATCHED)
        self.requests: list[tuple[str, dict[str, Any]]] = []
        self.map_items: list[Any] = []
        self.answers: list[int] = []  # stamps of the cmd_vel heard [ns]
        self.create_service(SetParameters, "/island_builder/explorer", self._on_request)
        self.create_service(SetParameters, "/topo_graph/add", self._on_add)
        self.create_subscription(TwistStamped, "/cmd_vel",
                                 lambda m: self.answers.append(time_to_ns(m.header.stamp)), QOS)

    def _on_request(self, req: SetParameters.Request, resp: SetParameters.Response) -> Any:
        for p in req.parameters:
            self.requests.append((p.name, json.loads(p.value.string_value)))
            resp.results.append(SetParametersResult(successful=True))
        return resp

    def _on_add(self, req: SetParameters.Request, resp: SetParameters.Response) -> Any:
        for p in req.parameters:
            self.map_items.append(parameter_to_item(p))
            resp.results.append(SetParametersResult(successful=True))
        return resp

    def tick(self, k: int, mode: CommandMode, events: tuple[BuilderEvent, ...] = ()) -> int:
        """Scan k (stamp k * 0.1 s) with its odometry and the builder's verdict; its stamp."""
        t_ns = k * 100_000_000
        self.odom.publish(pose_to_odometry(ORIGIN, np.zeros((3, 3)), t_ns, "odom", "base_link"))
        self.scan.publish(arrays_to_scan(np.full(ANGLES.size, np.inf), ANGLES, (0.1, 5.0), t_ns))
        self.decision.publish(decision_to_msg(t_ns, mode, events))
        return t_ns


def _handed_back(k: int) -> tuple[BuilderEvent, ...]:
    return (BuilderEvent(EventKind.HANDED_BACK, k * 0.1, ORIGIN, 0.0, anchor_odom=ORIGIN,
                         accepted_island_id=0),)


def test_the_explorer_answers_only_when_it_drives_or_nobody_else_does(
        ros_context: Any, spin: Any) -> None:
    ctx = ros_context
    explorer = ExplorerNode(context=ctx, parameter_overrides=[_p("wait_for_services", False)])
    world = _FakeRobotAndBuilder(ctx)
    ex = SingleThreadedExecutor(context=ctx)
    for n in (explorer, world):
        ex.add_node(n)
    island = Island(0, LineModel(CORRIDOR), ModelType.LINE, 1.0, 0.0,
                    exits=(Exit(0, 0.0, 3.0, ExitState.UNEXPLORED),))
    statuses: list[dict[str, Any]] = []
    world.create_subscription(String, "/explorer/status",
                              lambda m: statuses.append(json.loads(m.data)), LATCHED)
    k = 0

    def step(mode: CommandMode, events: tuple[BuilderEvent, ...] = ()) -> int:
        nonlocal k
        k += 1
        t_ns = world.tick(k, mode, events)
        assert spin(ex, lambda: explorer.scans_decided == k, 5.0), f"scan {k} not decided"
        for _ in range(5):  # let an answer arrive
            ex.spin_once(timeout_sec=0.01)
        return t_ns

    try:
        assert spin(ex, lambda: world.count_subscribers("/island_builder/decision") > 0, 5.0)
        # Before the first island the builder side answers: the explorer is silent.
        silent = [step(CommandMode.DRIVE), step(CommandMode.FOLLOW)]
        # The builder hands back at island 0 and idles: the explorer answers every scan.
        answered = [step(CommandMode.IDLE, _handed_back(k + 1)), step(CommandMode.IDLE)]
        world.graph.publish(String(data=TopoGraph.from_parts([island], []).to_json()))
        assert spin(ex, lambda: 0 in explorer.explorer.graph, 5.0)
        answered += [step(CommandMode.IDLE) for _ in range(3)]
        assert spin(ex, lambda: any(name == "handover" for name, _ in world.requests), 5.0)
        assert ("handover", {"island": 0, "exit": 0, "prefix": ""}) in world.requests
        # Handed over: the follower or the builder answers; the explorer stays silent.
        silent += [step(CommandMode.FOLLOW) for _ in range(3)] + [step(CommandMode.DRIVE)]
        assert statuses[-1]["state"] == "handed_over" and not statuses[-1]["done"]
        assert not explorer.done_future.done()
        # Back at island 0 with nothing new: the exit is blocked (in the map) and the explorer
        # is done; it holds the robot still.
        answered += [step(CommandMode.IDLE, _handed_back(k + 1)), step(CommandMode.IDLE)]
        assert spin(ex, lambda: bool(world.map_items), 5.0)
        assert world.map_items == [ExitUpdate(0, 0, ExitState.BLOCKED)]
        assert explorer.done and statuses[-1]["done"] and statuses[-1]["exits_left"] == 1
        assert explorer.done_future.done()  # what `islands explore` spins until
        assert sorted(world.answers) == sorted(answered)  # one answer each, none elsewhere
        assert not set(silent) & set(world.answers)
        assert explorer.bad_msg_count == 0
    finally:
        ex.shutdown()
        for n in (explorer, world):
            n.destroy_node()


def _string(name: str, text: str) -> ParameterMsg:
    return ParameterMsg(name=name, value=ParameterValue(type=ParameterType.PARAMETER_STRING,
                                                        string_value=text))


def test_bad_explorer_requests_are_refused_with_a_reason_and_the_builder_lives_on(
        ros_context: Any, spin: Any) -> None:
    ctx = ros_context
    builder = IslandBuilderNode(context=ctx, parameter_overrides=[
        _p("wait_for_services", False), _p("managed", True)])
    probe = Node("explorer_request_probe", context=ctx)
    decisions: list[String] = []
    probe.create_subscription(String, "/island_builder/decision", decisions.append, QOS)
    odom = probe.create_publisher(Odometry, "/odom", QOS)
    scan = probe.create_publisher(LaserScan, "/sonar/scan", QOS)
    cli = probe.create_client(SetParameters, "/island_builder/explorer")
    ex = SingleThreadedExecutor(context=ctx)
    for n in (builder, probe):
        ex.add_node(n)
    bad = [
        _string("handover", "{not json"),
        _string("teleport", "{}"),
        ParameterMsg(name="docked", value=ParameterValue(type=ParameterType.PARAMETER_INTEGER,
                                                         integer_value=3)),
        _string("handover", json.dumps({"island": 7, "exit": 0, "prefix": ""})),
        _string("handover", json.dumps({"island": 0, "exit": 0, "prefix": "Fly 3"})),
        _string("docked", json.dumps({"island": -1, "origin_odom": {"x": 0, "y": 0,
                                                                    "theta": 0}})),
        _string("docked", json.dumps({"island": 0, "origin_odom": {"x": "a", "y": 0,
                                                                   "theta": 0}})),
        island_to_parameter(Island(0, LineModel(CORRIDOR), ModelType.LINE, 1.0, 0.0)),
    ]
    try:
        assert cli.wait_for_service(timeout_sec=5.0)
        fut = cli.call_async(SetParameters.Request(parameters=bad))
        assert spin(ex, fut.done, 10.0)
        results = fut.result().results
        assert [r.successful for r in results] == [False] * len(bad)
        reasons = [r.reason for r in results]
        assert "parameters[0]" in reasons[0] and "teleport" in reasons[1]
        assert "string" in reasons[2] and "unknown island 7" in reasons[3]
        assert "Fly" in reasons[4] and "island" in reasons[5] and "x" in reasons[6]
        assert "island" in reasons[7]  # a map item is not an explorer request
        assert builder.refused_requests == len(bad)
        # Before any island, a well-formed abort is refused: the builder is busy starting.
        fut = cli.call_async(SetParameters.Request(parameters=[_string("abort", "{}")]))
        assert spin(ex, fut.done, 10.0)
        (r,) = fut.result().results
        assert not r.successful and "busy" in r.reason
        # It lives on: a scan with its odometry is decided, and the decision says so.
        odom.publish(pose_to_odometry(ORIGIN, np.zeros((3, 3)), 100_000_000, "odom",
                                      "base_link"))
        scan.publish(arrays_to_scan(np.full(ANGLES.size, 2.0), ANGLES, (0.1, 5.0),
                                    100_000_000))
        odom.publish(pose_to_odometry(ORIGIN, np.zeros((3, 3)), 120_000_000, "odom",
                                      "base_link"))
        assert spin(ex, lambda: bool(decisions), 5.0)
        d = msg_to_decision(decisions[0])
        assert d.stamp_ns == 100_000_000 and d.mode is CommandMode.DRIVE  # the first star
        assert d.events and d.events[0].kind is EventKind.ATTEMPT_STARTED
    finally:
        ex.shutdown()
        for n in (builder, probe):
            n.destroy_node()


def test_explorer_parameters_need_the_exits_policy() -> None:
    with pytest.raises(RunParameterError, match="explorer_node runs with the policy exits"):
        run(RunConfig(world="t_junction", params={"explorer_node": {"explorer.exit_cap_s": 60.0}}))


@pytest.mark.slow
def test_a_small_world_explored_live_by_exits_ends_by_itself(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The T world (a corridor with a branch), every node on one executor: the explorer says it
    is done well before the cap, the map shows no unexplored exit, no wall was touched and the
    lockstep was fed (a timeout or two while the builder computes an island is allowed). The
    branch, passed without an island, is a side exit of the first island: explored too (offline
    at 251 s, live seed 1 at 287 s; the cap leaves room for a slower live run)."""
    out = tmp_path / "run"
    code = main(["explore", "--world", "t_junction", "--policy", "exits", "--out", str(out),
                 "--seed", "1", "--sim-seconds", "700", "--routes", "0", "--no-record",
                 "--quiet"])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["policy"] == Policy.EXITS.value
    assert summary["ended_by_itself"] is True and summary["exits_left"] == 0
    assert summary["sim_seconds"] < 700.0
    assert summary["islands"] >= 2 and summary["edges"] >= 1
    assert summary["collisions"] == 0 and summary["lockstep_timeouts"] <= 3
    assert summary["explorer"]["status"]["done"] is True
    assert summary["explorer"]["refused_requests"] == 0
    graph = TopoGraph.from_json((out / "graph.json").read_text())
    exits = [e for i in graph.islands() for e in i.exits]
    assert exits and all(e.state is not ExitState.UNEXPLORED for e in exits)
    assert "ended by itself" in capsys.readouterr().out


def test_bad_messages_to_the_explorer_are_counted_and_it_decides_on(
        ros_context: Any, spin: Any) -> None:
    ctx = ros_context
    explorer = ExplorerNode(context=ctx, parameter_overrides=[_p("wait_for_services", False)])
    world = _FakeRobotAndBuilder(ctx)
    progress = world.create_publisher(String, "/hall_follower/progress", QOS)
    ex = SingleThreadedExecutor(context=ctx)
    for n in (explorer, world):
        ex.add_node(n)
    try:
        assert spin(ex, lambda: world.count_subscribers("/island_builder/decision") > 0, 5.0)
        world.decision.publish(String(data="not json"))
        world.decision.publish(String(data=json.dumps({"stamp_ns": 1, "mode": "fly",
                                                       "events": []})))
        world.graph.publish(String(data='{"islands": 3}'))
        progress.publish(String(data="Fly 3"))
        assert spin(ex, lambda: explorer.bad_msg_count >= 4, 5.0)
        world.tick(1, CommandMode.IDLE, _handed_back(1))
        assert spin(ex, lambda: explorer.scans_decided == 1 and bool(world.answers), 5.0)
        assert world.answers == [100_000_000]
    finally:
        ex.shutdown()
        for n in (explorer, world):
            n.destroy_node()
