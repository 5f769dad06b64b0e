"""The mapping nodes as a ROS 2 user runs them: the map's first island is where the robot starts
whatever order the nodes come up in; the graph server's markers carry sim time; its parameters
set at run time take effect or are refused; the recorder's parameters all have values."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from island_mapping.nodes.island_builder_node import IslandBuilderNode
from island_mapping.nodes.recorder_node import RecorderNode
from island_mapping.nodes.topo_graph_server_node import LATCHED, TopoGraphServerNode
from island_msgs_py.conversions import island_to_parameter, ns_to_time
from island_msgs_py.types import Island, LineModel, ModelType
from island_sim.nodes.hall_follower_node import HallFollowerNode
from island_sim.nodes.odometry_node import OdometryNode
from island_sim.nodes.sonar_node import SonarNode
from rcl_interfaces.msg import ParameterType, SetParametersResult
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from visualization_msgs.msg import MarkerArray

START = (10.6, 9.0)  # paper_fig4's start pose [m]


def _p(name: str, value: Any) -> Parameter:
    return Parameter(name, value=value)


def _spin(ex: SingleThreadedExecutor, cond: Callable[[], bool], timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            return False
        ex.spin_once(timeout_sec=0.02)
    return True


def _call(ex: SingleThreadedExecutor, client: Node, srv: Any, name: str, request: Any) -> Any:
    cli = client.create_client(srv, name)
    try:
        assert cli.wait_for_service(timeout_sec=5.0)
        fut = cli.call_async(request)
        assert _spin(ex, fut.done, 10.0)
        return fut.result()
    finally:
        client.destroy_client(cli)


def _set(ex: SingleThreadedExecutor, client: Node, node: str, name: str,
         value: Any) -> SetParametersResult:
    req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    return _call(ex, client, SetParameters, f"{node}/set_parameters", req).results[0]


@pytest.mark.parametrize("mapper_first", [False, True], ids=["readme_order", "mapper_first"])
def test_the_first_island_is_where_the_robot_starts_whatever_the_order(
        ros_context: Any, mapper_first: bool) -> None:
    """The README starts the robot, sonar and follower before the graph server and the builder
    (the follower drove ~7 m before the builder came up); the reverse order must work too."""
    ctx = ros_context
    sim_time = _p("use_sim_time", True)
    ex = SingleThreadedExecutor(context=ctx)
    nodes: list[Node] = []

    def robot() -> OdometryNode:
        odo = OdometryNode(context=ctx, parameter_overrides=[
            _p("world", "paper_fig4"), _p("seed", 5), _p("sim.real_time_factor", 0.0),
            _p("sim.lockstep", True), _p("sim.stop_after_s", 120.0)])
        sonar = SonarNode(context=ctx, parameter_overrides=[sim_time, _p("world", "paper_fig4")])
        follower = HallFollowerNode(context=ctx, parameter_overrides=[sim_time])
        for n in (odo, sonar, follower):
            nodes.append(n)
            ex.add_node(n)
        return odo

    def mapper() -> tuple[IslandBuilderNode, TopoGraphServerNode]:
        server = TopoGraphServerNode(context=ctx, parameter_overrides=[
            sim_time, _p("storage_path", "")])
        builder = IslandBuilderNode(context=ctx, parameter_overrides=[sim_time])
        for n in (server, builder):
            nodes.append(n)
            ex.add_node(n)
        return builder, server

    try:
        if mapper_first:
            builder, server = mapper()
            time.sleep(0.5)
            _spin(ex, lambda: False, 1.0)
            assert not builder.mapping  # no follower yet: it does not map
            odo = robot()
        else:
            odo = robot()
            assert _spin(ex, lambda: odo.sim_time_ns >= 20 * 10**9, 60.0)
            # nobody claimed the robot: it held still while sim time ran
            assert odo.robot.distance_m == 0.0 and odo.lockstep_timeouts == 0
            builder, server = mapper()
        assert _spin(ex, lambda: 0 in server.graph or odo.finished, 120.0), (
            odo.sim_time_ns * 1e-9)
        origin = server.graph.get_island(0).origin_truth
        assert origin is not None
        assert math.hypot(origin.x - START[0], origin.y - START[1]) < 0.05, origin
        assert builder.mapping and builder.follower_enabled is not None
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()


def _island(island_id: int) -> Island:
    return Island(id=island_id, model=LineModel([[0.0, 1.0, 4.0, 1.0], [0.0, -1.0, 4.0, -1.0]]),
                  model_type=ModelType.LINE, r=0.8, built_at_s=1.0)


def test_markers_carry_sim_time_and_live_parameters_take_effect(ros_context: Any) -> None:
    ctx = ros_context
    server = TopoGraphServerNode(context=ctx, parameter_overrides=[
        _p("use_sim_time", True), _p("storage_path", "")])
    client = Node("server_client", context=ctx)
    clock = client.create_publisher(Clock, "/clock", QoSProfile(depth=10))
    markers: list[MarkerArray] = []
    client.create_subscription(MarkerArray, "/topo_graph/markers", markers.append, LATCHED)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(server)
    ex.add_node(client)
    t_ns = 1234 * 10**9 + 500_000_000
    try:
        assert _spin(ex, lambda: clock.get_subscription_count() > 0, 5.0)
        clock.publish(Clock(clock=ns_to_time(t_ns)))
        assert _spin(ex, lambda: server.get_clock().now().nanoseconds == t_ns, 5.0)
        req = SetParameters.Request(parameters=[island_to_parameter(_island(0))])
        res = _call(ex, client, SetParameters, "/topo_graph/add", req)
        assert res.results[0].successful, res.results[0].reason
        assert _spin(ex, lambda: bool(markers) and len(markers[-1].markers) > 1, 5.0)
        stamps = {(m.header.stamp.sec, m.header.stamp.nanosec) for m in markers[-1].markers}
        assert stamps == {(1234, 500_000_000)}  # sim time, as everything else in the run
        # live: the display frame is redrawn at once; the request limit is range-checked
        assert _set(ex, client, "/topo_graph_server", "display_frame", "fleet_layout").successful
        assert _spin(ex, lambda: markers[-1].markers[-1].header.frame_id == "fleet_layout", 5.0)
        zero = _set(ex, client, "/topo_graph_server", "max_items_per_request", 0)
        assert not zero.successful and "out of range" in zero.reason
        assert _set(ex, client, "/topo_graph_server", "max_items_per_request", 1).successful
        two = SetParameters.Request(parameters=[island_to_parameter(_island(i)) for i in (1, 2)])
        refused = _call(ex, client, SetParameters, "/topo_graph/add", two)
        assert not any(r.successful for r in refused.results)
        assert "the limit is 1" in refused.results[0].reason
        storage = _set(ex, client, "/topo_graph_server", "storage_path", "/tmp/elsewhere")
        assert not storage.successful and "read-only" in storage.reason
    finally:
        ex.shutdown()
        client.destroy_node()
        server.destroy_node()


def test_recorder_parameters_all_have_values_and_are_read_only(
        ros_context: Any, tmp_path: Path) -> None:
    """`ros2 param dump /recorder` prints every parameter: the list ones have values too."""
    node = RecorderNode(context=ros_context, parameter_overrides=[
        _p("output_dir", str(tmp_path / "bag"))])
    client = Node("recorder_client", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex.add_node(client)
    try:
        names = ["recorder.topics", "recorder.exclude", "recorder.compression", "output_dir"]
        got = _call(ex, client, GetParameters, "/recorder/get_parameters",
                    GetParameters.Request(names=names)).values
        assert [v.type for v in got] == [
            ParameterType.PARAMETER_STRING_ARRAY, ParameterType.PARAMETER_STRING_ARRAY,
            ParameterType.PARAMETER_STRING, ParameterType.PARAMETER_STRING]
        assert list(got[0].string_array_value) == []
        assert list(got[1].string_array_value) == ["/rosout", "/parameter_events"]
        desc = _call(ex, client, DescribeParameters, "/recorder/describe_parameters",
                     DescribeParameters.Request(names=names)).descriptors
        assert all(d.read_only for d in desc)
        res = _set(ex, client, "/recorder", "recorder.topics", ["/odom"])
        assert not res.successful and "read-only" in res.reason
    finally:
        node.close()
        ex.shutdown()
        client.destroy_node()
        node.destroy_node()
