"""topo_graph_server_node in process: every service incl. rejections, latched topics, reload."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
from geometry_msgs.msg import PoseStamped
from island_mapping.core.graph import GraphServerConfig, TopoGraph
from island_mapping.nodes.topo_graph_server_node import LATCHED, TopoGraphServerNode
from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter as RclpyParameter
from std_msgs.msg import String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from island_msgs_py import conversions as cv

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "src/island_mapping/config/topo_graph_server_node.yaml"


def island(i: int) -> Island:
    rng = np.random.default_rng(i)
    return Island(i, LineModel(rng.uniform(-3, 3, (3, 4))), ModelType.LINE, 0.7, float(i))


def edge(a: int, b: int, w: float = 5.0, text: str = "Go 125, Rot 270, Go 652") -> Edge:
    return Edge(a, b, ControlStrategy.parse(text), w, length_m=w)


def raw(name: str, text: str) -> Parameter:
    return Parameter(name=name, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=text))


class Harness:
    def __init__(self, ctx: Any, storage: str, spin: Callable[..., bool]) -> None:
        self.ctx, self.storage, self.spin = ctx, storage, spin
        self.executor = SingleThreadedExecutor(context=ctx)
        self.client_node = Node("graph_test_client", context=ctx)
        self.executor.add_node(self.client_node)
        self.clients = {
            "add": self.client_node.create_client(SetParameters, "/topo_graph/add"),
            "get": self.client_node.create_client(Trigger, "/topo_graph/get"),
            "plan": self.client_node.create_client(GetPlan, "/topo_graph/plan"),
            "save": self.client_node.create_client(Trigger, "/topo_graph/save"),
        }
        self.server: TopoGraphServerNode | None = None
        self.start()

    def start(self, **overrides: Any) -> TopoGraphServerNode:
        params = [RclpyParameter("storage_path", value=self.storage)]
        params += [RclpyParameter(k, value=v) for k, v in overrides.items()]
        self.server = TopoGraphServerNode(context=self.ctx, parameter_overrides=params)
        self.executor.add_node(self.server)
        return self.server

    def stop(self) -> None:
        assert self.server is not None
        self.executor.remove_node(self.server)
        self.server.destroy_node()
        self.server = None

    def call(self, name: str, request: Any) -> Any:
        client = self.clients[name]
        assert self.spin(self.executor, lambda: client.service_is_ready(), 10.0)
        fut = client.call_async(request)
        assert self.spin(self.executor, fut.done, 10.0), f"{name} timed out"
        return fut.result()

    def add(self, *params: Parameter) -> list[tuple[bool, str]]:
        res = self.call("add", SetParameters.Request(parameters=list(params)))
        return [(r.successful, r.reason) for r in res.results]

    def plan(self, start: str, goal: str) -> list[str]:
        req = GetPlan.Request()
        req.start = PoseStamped()
        req.start.header.frame_id = start
        req.goal.header.frame_id = goal
        return cv.path_to_island_frames(self.call("plan", req).plan)

    def close(self) -> None:
        if self.server is not None:
            self.stop()
        self.executor.shutdown()
        self.client_node.destroy_node()


@pytest.fixture
def harness(ros_context: Any, spin: Callable[..., bool], tmp_path: Path) -> Iterator[Harness]:
    h = Harness(ros_context, str(tmp_path / "store"), spin)
    try:
        yield h
    finally:
        h.close()


def _fill(h: Harness) -> None:
    res = h.add(*(cv.island_to_parameter(island(i)) for i in range(4)),
                cv.edge_to_parameter(edge(0, 1)), cv.edge_to_parameter(edge(1, 2, 2.0, "Go 300")),
                cv.edge_to_parameter(edge(0, 2, 9.0)), cv.edge_to_parameter(edge(2, 3)))
    assert all(ok for ok, _ in res), res


def test_add_reports_each_item_and_rejects_bad_ones(harness: Harness) -> None:
    _fill(harness)
    before = harness.call("get", Trigger.Request()).message
    good_nan = json.loads(cv.island_to_parameter(island(7)).value.string_value)
    good_nan["model"]["segments"][1][2] = float("nan")
    self_edge = json.loads(cv.edge_to_parameter(edge(0, 1)).value.string_value)
    self_edge["target"] = 0
    res = harness.add(
        cv.edge_to_parameter(edge(0, 9)),                       # unknown target
        raw("island", json.dumps(good_nan)),                    # NaN coordinate
        raw("edge", json.dumps(self_edge)),                     # edge to itself
        raw("node", "{}"),                                      # unknown item kind
        raw("island", "{not json"),                             # malformed JSON
        Parameter(name="edge", value=ParameterValue(type=ParameterType.PARAMETER_INTEGER)),
        cv.island_to_parameter(dataclasses.replace(island(1), r=0.95)),  # valid replace
        cv.edge_to_parameter(edge(3, 0, 1.0)),                  # valid add
    )
    assert [ok for ok, _ in res] == [False] * 6 + [True, True]
    reasons = [r for _, r in res]
    assert reasons[0] == "edge 0->9: unknown target island 9"
    assert reasons[1].startswith("island.model.segments[1]: NaN")
    assert reasons[2] == "edge: an edge from island 0 to itself"
    assert "expected 'island', 'edge'" in reasons[3]
    assert "not valid JSON" in reasons[4]
    assert "expected a string" in reasons[5]
    assert reasons[6:] == ["replaced island 1", "added edge 3->0"]
    assert harness.server is not None and harness.server.rejected == 6
    after = TopoGraph.from_json(harness.call("get", Trigger.Request()).message)
    want = TopoGraph.from_json(before)
    want.replace_island(dataclasses.replace(island(1), r=0.95))
    want.add_edge(edge(3, 0, 1.0))
    assert after == want
    assert harness.add() == []  # an empty request is fine


def test_plan_returns_island_origins_or_empty(harness: Harness) -> None:
    _fill(harness)
    assert harness.plan("island_0", "island_3") == ["island_0", "island_1", "island_2", "island_3"]
    assert harness.plan("island_2", "island_2") == ["island_2"]
    assert harness.plan("island_3", "island_0") == []  # no route back
    assert harness.plan("island_0", "island_42") == []  # unknown island
    assert harness.plan("map", "island_1") == []  # not an island frame
    req = GetPlan.Request()
    req.start.header.frame_id, req.goal.header.frame_id = "island_0", "island_2"
    plan = harness.call("plan", req).plan
    assert plan.header.frame_id == "island_0"
    assert all(cv.pose_to_pose2d(p.pose).x == 0.0 for p in plan.poses)
    assert harness.server is not None and harness.server.rejected == 3


def test_save_writes_three_formats_that_load_back(harness: Harness, tmp_path: Path) -> None:
    _fill(harness)
    res = harness.call("save", Trigger.Request())
    assert res.success, res.message
    paths = json.loads(res.message)
    assert Path(paths["json"]).parent == tmp_path / "store" / "export"
    want = TopoGraph.from_json(harness.call("get", Trigger.Request()).message)
    for key in ("json", "geojson", "graphml"):
        assert TopoGraph.load_any(paths[key]) == want


def test_save_failure_is_reported_not_fatal(harness: Harness, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    harness.stop()
    harness.start(output_dir=str(blocker / "sub"))  # a directory below a file cannot exist
    res = harness.call("save", Trigger.Request())
    assert not res.success and res.message.startswith("save failed")
    assert harness.call("get", Trigger.Request()).success


def test_latched_topics_reach_a_late_subscriber(harness: Harness) -> None:
    _fill(harness)
    late = Node("late_listener", context=harness.ctx)
    harness.executor.add_node(late)
    got: dict[str, Any] = {}
    late.create_subscription(String, "/topo_graph/json", lambda m: got.__setitem__("json", m),
                             LATCHED)
    late.create_subscription(MarkerArray, "/topo_graph/markers",
                             lambda m: got.__setitem__("markers", m), LATCHED)
    try:
        assert harness.spin(harness.executor, lambda: len(got) == 2, 10.0)
        islands, edges = cv.string_msg_to_graph(got["json"])
        assert [i.id for i in islands] == [0, 1, 2, 3] and len(edges) == 4
        models = cv.marker_array_to_models(got["markers"])
        np.testing.assert_array_equal(models[2], island(2).model.segments)
        # a change is republished
        got.clear()
        assert harness.add(cv.island_to_parameter(island(8))) == [(True, "added island 8")]
        assert harness.spin(harness.executor, lambda: "json" in got, 10.0)
        assert 8 in {i.id for i in cv.string_msg_to_graph(got["json"])[0]}
    finally:
        harness.executor.remove_node(late)
        late.destroy_node()


def test_restart_reloads_the_stored_graph(harness: Harness) -> None:
    _fill(harness)
    want = harness.call("get", Trigger.Request()).message
    harness.stop()
    server = harness.start()
    assert len(server.graph) == 4
    assert harness.call("get", Trigger.Request()).message == want


def test_in_memory_mode_and_yaml_matches_the_config_defaults(
    ros_context: Any, spin: Callable[..., bool]
) -> None:
    h = Harness(ros_context, "", spin)
    try:
        assert h.server is not None and h.server.store is None
        assert h.add(cv.island_to_parameter(island(0))) == [(True, "added island 0")]
    finally:
        h.close()
    doc = yaml.safe_load(CONFIG.read_text())["topo_graph_server"]["ros__parameters"]
    assert doc == dataclasses.asdict(GraphServerConfig())
