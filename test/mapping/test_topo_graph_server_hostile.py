"""topo_graph_server_node against hostile and boundary input: every item over a limit is refused
naming the field and the limit, a request over the item limit is refused whole, exit items
change one exit, and the server restarts on its own store whatever it acknowledged."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from island_mapping.core.graph import GraphStore, TopoGraph
from island_mapping.nodes.topo_graph_server_node import LATCHED, TopoGraphServerNode
from island_msgs_py.limits import MAX_ISLAND_ID
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitState,
    ExitUpdate,
    Island,
    LineModel,
    ModelType,
)
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter as RclpyParameter
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from island_msgs_py import conversions as cv

TOP = MAX_ISLAND_ID  # the largest island id


def raw(name: str, text: str) -> Parameter:
    return Parameter(name=name, value=ParameterValue(
        type=ParameterType.PARAMETER_STRING, string_value=text))


def island(i: int, exits: tuple[Exit, ...] = (), bound_m: float = 3.0) -> Island:
    rng = np.random.default_rng(i % 1000)
    segs = rng.uniform(-3, 3, (3, 4))
    segs[0] = (-bound_m, bound_m, bound_m, -bound_m)
    return Island(i, LineModel(segs), ModelType.LINE, 0.7, 1.0, exits=exits)


class Server:
    """A graph server on a store in `storage`, its clients, and a spin helper."""

    def __init__(self, ctx: Any, storage: Path, spin: Callable[..., bool], **params: Any) -> None:
        self.ctx, self.storage, self.spin, self.params = ctx, storage, spin, params
        self.executor = SingleThreadedExecutor(context=ctx)
        self.client = Node("hostile_client", context=ctx)
        self.executor.add_node(self.client)
        self.add_cli = self.client.create_client(SetParameters, "/topo_graph/add")
        self.get_cli = self.client.create_client(Trigger, "/topo_graph/get")
        self.plan_cli = self.client.create_client(GetPlan, "/topo_graph/plan")
        self.node: TopoGraphServerNode | None = None
        self.start()

    def start(self) -> None:
        overrides = [RclpyParameter("storage_path", value=str(self.storage))]
        overrides += [RclpyParameter(k, value=v) for k, v in self.params.items()]
        self.node = TopoGraphServerNode(context=self.ctx, parameter_overrides=overrides)
        self.executor.add_node(self.node)

    def stop(self) -> None:
        assert self.node is not None
        self.executor.remove_node(self.node)
        self.node.destroy_node()
        self.node = None

    def call(self, client: Any, request: Any) -> Any:
        assert self.spin(self.executor, client.service_is_ready, 10.0)
        fut = client.call_async(request)
        assert self.spin(self.executor, fut.done, 30.0)
        return fut.result()

    def add(self, *params: Parameter) -> list[tuple[bool, str]]:
        res = self.call(self.add_cli, SetParameters.Request(parameters=list(params)))
        return [(r.successful, r.reason) for r in res.results]

    def graph(self) -> TopoGraph:
        return TopoGraph.from_json(self.call(self.get_cli, Trigger.Request()).message)

    def close(self) -> None:
        if self.node is not None:
            self.stop()
        self.executor.shutdown()
        self.client.destroy_node()


@pytest.fixture
def server(ros_context: Any, spin: Callable[..., bool], tmp_path: Path) -> Iterator[Server]:
    s = Server(ros_context, tmp_path / "store", spin, max_items_per_request=8)
    try:
        yield s
    finally:
        s.close()


def test_a_request_over_the_item_limit_is_refused_whole(server: Server) -> None:
    ok = server.add(*(cv.island_to_parameter(island(i)) for i in range(8)))
    assert all(s for s, _ in ok)
    res = server.add(*(cv.island_to_parameter(island(100 + i)) for i in range(10_000)))
    assert len(res) == 10_000 and not any(s for s, _ in res)
    assert res[0][1].startswith("request refused: 10000 items, the limit is 8 per request")
    assert server.graph().island_ids() == list(range(8))  # nothing of it was applied
    assert server.node is not None and server.node.rejected == 1


def _hostile_items() -> list[tuple[Parameter, str]]:
    good = json.loads(cv.island_to_parameter(island(1)).value.string_value)

    def with_(**kw: Any) -> Parameter:
        return raw("island", json.dumps({**good, **kw}))

    far = json.loads(json.dumps(good))
    far["model"]["segments"][1][2] = 2.0e6
    many = {**good, "model": {"segments": [[0, 0, 1, 1]] * 10_001}}
    edge = cv.edge_to_parameter(Edge(0, 1, ControlStrategy.parse("Go 10"), 1.0)).value
    e = json.loads(edge.string_value)
    return [
        (with_(id=TOP + 1), f"island.id: must be <= {TOP} (the limit)"),
        (with_(id=10**18), "island.id: must be <= 2147483647 (the limit)"),
        (with_(id=10**30), "island: an integer of 31 digits (the limit is 20)"),
        (raw("island", json.dumps(good).replace('"id": 1', '"id": ' + "7" * 5000)),
         "island: an integer of 5000 digits (the limit is 20)"),
        (raw("island", "[" * 100_000 + "]" * 100_000), "island: JSON nested 100000 deep "
                                                       "(the limit is 32)"),
        (raw("island", json.dumps(far)), "island.model.segments[1]: coordinate 2 is 2e+06"),
        (raw("island", json.dumps(many)), "island.model.segments: 10001 entries (the limit is "
                                          "10000)"),
        (with_(r=math.inf), "island.r: infinite value"),
        (raw("edge", json.dumps({**e, "weight": 1e300})), "edge.weight: |value| must be <= 1e+06"),
        (raw("edge", json.dumps({**e, "strategy": "Go " + "9" * 5000})),
         "edge.strategy: control strategy: step 'Go 9999"),
        (raw("edge", json.dumps({**e, "strategy": ", ".join(["Rot 90"] * 2000)})),
         "edge.strategy: control strategy: more than 1000 steps (the limit)"),
        (raw("edge", json.dumps({**e, "source_exit": 5})), "edge 0->1: source_exit 5: island 0 "
                                                           "has no exit 5"),
        (raw("exit", json.dumps({"island": 0, "exit": 3, "state": "blocked"})),
         "island 0: exit 3: no such exit"),
        (raw("exit", json.dumps({"island": 0, "exit": 0, "state": "explored", "edge": [0, 7]})),
         "island 0: exit 0 explored by edge 0->7, which is not in the graph"),
    ]


def test_hostile_items_are_refused_naming_field_and_limit_and_nothing_is_lost(
    server: Server,
) -> None:
    assert server.add(cv.island_to_parameter(island(0, (Exit(0, 0.0, 1.0),))),
                      cv.island_to_parameter(island(1))) == [
        (True, "added island 0"), (True, "added island 1")]
    before = server.graph()
    for param, message in _hostile_items():
        [(ok, reason)] = server.add(param)
        assert not ok and reason.startswith(message), (message, reason)
    assert server.graph() == before
    server.stop()
    server.start()  # the store still opens, with what was acknowledged
    assert server.graph() == before


def test_exit_items_change_one_exit_and_survive_a_restart(server: Server) -> None:
    four = tuple(Exit(k, a, 1.2) for k, a in enumerate((0.0, 1.57, 3.14, -1.57)))
    res = server.add(
        cv.island_to_parameter(island(3, four)), cv.island_to_parameter(island(5, four)),
        cv.edge_to_parameter(Edge(3, 5, ControlStrategy.parse("Go 400"), 4.0,
                                  source_exit=1, target_exit=3)),
        cv.exit_update_to_parameter(ExitUpdate(3, 1, ExitState.EXPLORED, (3, 5))),
        raw("exit", '{"island": 5, "exit": 0, "state": "blocked"}'),
    )
    assert [r for _, r in res[3:]] == ["set exit 1 of island 3 to explored",
                                       "set exit 0 of island 5 to blocked"]
    server.stop()
    server.start()
    g = server.graph()
    assert g.get_island(3).exits[1].edge == (3, 5)
    assert g.get_island(5).exits[0].state is ExitState.BLOCKED
    assert g.get_edge(3, 5).source_exit == 1


def test_the_server_restarts_on_its_store_with_items_at_every_bound(server: Server) -> None:
    res = server.add(
        cv.island_to_parameter(island(0, bound_m=1.0e6)),
        cv.island_to_parameter(island(TOP, (Exit(2**31 - 1, -math.pi, 1.0e6),), bound_m=-1.0e6)),
        cv.edge_to_parameter(Edge(0, TOP, ControlStrategy.parse("Go 100000000, Rot 359"),
                                  1.0e6, 1.0e6, 1.0e6, target_exit=2**31 - 1)),
    )
    assert all(ok for ok, _ in res), res
    want = server.graph()
    server.stop()
    server.start()
    assert server.graph() == want
    assert GraphStore.read(server.storage) == want
    req = GetPlan.Request()
    req.start.header.frame_id, req.goal.header.frame_id = "island_0", f"island_{TOP}"
    plan = server.call(server.plan_cli, req).plan
    assert cv.path_to_island_frames(plan) == ["island_0", f"island_{TOP}"]
    got: list[MarkerArray] = []
    server.client.create_subscription(MarkerArray, "/topo_graph/markers", got.append, LATCHED)
    assert server.spin(server.executor, lambda: bool(got), 10.0)
    assert TOP in {m.id for m in got[-1].markers if m.ns == "island_models"}


def test_a_server_on_a_damaged_store_exits_2_naming_it(tmp_path: Path) -> None:
    import sqlite3

    with GraphStore(tmp_path / "store") as store:
        store.put_island(island(0))
    conn = sqlite3.connect(tmp_path / "store" / "graph.sqlite3")
    conn.execute("UPDATE islands SET built_at_s = 2.0")
    conn.commit()
    conn.close()
    for storage, message in [(tmp_path / "store", "damaged store"),
                             (Path("/etc"), "not a graph store")]:
        out = subprocess.run(
            [sys.executable, "-m", "island_mapping.nodes.topo_graph_server_node", "--ros-args",
             "-p", f"storage_path:={storage}"], capture_output=True, text=True, timeout=60)
        assert out.returncode == 2, out.stderr
        assert out.stderr.startswith("topo_graph_server_node: error:") and message in out.stderr
