"""island_builder_node and island_localizer_node in process: with the three simulator nodes and
the graph server on one executor (lockstep, sim time) in paper_fig4; bad input; YAML defaults."""

from __future__ import annotations

import dataclasses
import json
import math
import time
from enum import Enum
from pathlib import Path
from typing import Any

import pytest
import yaml
from geometry_msgs.msg import PoseWithCovarianceStamped
from island_mapping.core.builder import BuilderConfig
from island_mapping.core.explore import ExplorerConfig
from island_mapping.core.tracker import TrackerConfig
from island_mapping.nodes.explorer_node import ExplorerNodeConfig
from island_mapping.nodes.island_builder_node import IslandBuilderNode, IslandBuilderNodeConfig
from island_mapping.nodes.island_localizer_node import IslandLocalizerNode
from island_mapping.nodes.topo_graph_server_node import TopoGraphServerNode
from island_sim.nodes.hall_follower_node import HallFollowerNode
from island_sim.nodes.odometry_node import OdometryNode
from island_sim.nodes.sonar_node import SonarNode
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String

CONFIG_DIR = Path(__file__).resolve().parents[2] / "src" / "island_mapping" / "config"
QOS = QoSProfile(depth=100)


def _p(name: str, value: Any) -> Parameter:
    return Parameter(name, value=value)


@pytest.mark.slow
def test_exploration_builds_linked_islands_and_localizes_in_them(ros_context: Any) -> None:
    ctx = ros_context
    sim_time = _p("use_sim_time", True)
    odo = OdometryNode(context=ctx, parameter_overrides=[
        _p("world", "paper_fig4"), _p("seed", 3), _p("sim.real_time_factor", 0.0),
        _p("start_pose", "28,9,0"),  # 7 m west of the T junction of the middle corridor
        _p("sim.lockstep", True), _p("sim.stop_after_s", 400.0)])
    sonar = SonarNode(context=ctx, parameter_overrides=[sim_time, _p("world", "paper_fig4"),
                                                         _p("seed", 4)])
    follower = HallFollowerNode(context=ctx, parameter_overrides=[sim_time])
    builder = IslandBuilderNode(context=ctx, parameter_overrides=[sim_time])
    localizer = IslandLocalizerNode(context=ctx, parameter_overrides=[sim_time])
    server = TopoGraphServerNode(context=ctx, parameter_overrides=[_p("storage_path", "")])
    probe = Node("builder_test_probe", context=ctx)
    events: list[dict[str, Any]] = []
    poses: list[PoseWithCovarianceStamped] = []
    probe.create_subscription(String, "/island_builder/events",
                              lambda m: events.append(json.loads(m.data)), QOS)
    probe.create_subscription(PoseWithCovarianceStamped, "/island_pose", poses.append, QOS)
    nodes = [odo, sonar, follower, builder, localizer, server, probe]
    ex = SingleThreadedExecutor(context=ctx)
    for n in nodes:
        ex.add_node(n)

    def linked() -> bool:
        g = server.graph
        return len(g) >= 2 and any(str(e.strategy) for e in g.iter_edges())

    try:
        deadline = time.monotonic() + 85.0
        def done() -> bool:
            n_acc = sum(e["kind"] == "island_accepted" for e in events)
            return linked() and bool(poses) and n_acc >= 2

        while not done() and not odo.finished and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        t_sim = odo.sim_time_ns * 1e-9
        kinds = [e["kind"] for e in events]
        assert linked(), f"after {t_sim:.0f} s sim: events {kinds}"
        g = server.graph
        edge = next(e for e in g.iter_edges() if str(e.strategy))
        assert edge.strategy.steps[0].kind.value in ("Go", "Rot")
        assert edge.length_m > 1.0 and edge.weight > edge.length_m
        assert kinds.count("island_accepted") >= 2 and kinds[0] == "attempt_started"
        accepted = [e for e in events if e["kind"] == "island_accepted"]
        assert accepted[1]["edge"]["strategy"] == str(edge.strategy)
        assert accepted[1]["measure"] > accepted[1]["bound"]
        # Islands carry their true origin (evaluation only): island 0 is the start pose.
        start = g.get_island(0).origin_truth
        assert start is not None and math.hypot(start.x - 28.0, start.y - 9.0) < 0.05
        assert odo.robot.collisions == 0
        assert odo.lockstep_timeouts <= 2  # the builder kept the lockstep fed while driving
        # The localizer published poses in an island frame near that island's origin.
        assert poses, "no /island_pose"
        frames = {p.header.frame_id for p in poses}
        assert frames <= {f"island_{i}" for i in g.island_ids()}
        p = poses[-1].pose.pose.position
        assert math.hypot(p.x, p.y) < 8.0
        assert builder.bad_msg_count == 0 and localizer.bad_msg_count == 0
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()


def test_bad_messages_are_counted_and_never_kill_the_nodes(
    ros_context: Any, spin: Any
) -> None:
    ctx = ros_context
    # no follower nor graph server here: map at once
    builder = IslandBuilderNode(context=ctx, parameter_overrides=[_p("wait_for_services", False)])
    localizer = IslandLocalizerNode(context=ctx)
    probe = Node("builder_bad_input_probe", context=ctx)
    strat = probe.create_publisher(String, "/hall_follower/progress", QOS)
    scan_pub = probe.create_publisher(LaserScan, "/sonar/scan", QOS)
    odom_pub = probe.create_publisher(Odometry, "/odom", QOS)
    ev_pub = probe.create_publisher(String, "/island_builder/events", QOS)
    ex = SingleThreadedExecutor(context=ctx)
    for n in (builder, localizer, probe):
        ex.add_node(n)
    try:
        strat.publish(String(data="Go banana"))
        bad_scan = LaserScan()
        bad_scan.angle_increment = math.nan
        bad_scan.ranges = [1.0, 2.0]
        bad_odom = Odometry()
        bad_odom.pose.pose.orientation.w = math.nan
        ev_pub.publish(String(data='{"kind": "island_accepted", "island": {"id": -1}}'))
        ev_pub.publish(String(data="not json"))
        for _ in range(20):
            scan_pub.publish(bad_scan)
            odom_pub.publish(bad_odom)
            ex.spin_once(timeout_sec=0.01)
        assert spin(ex, lambda: builder.bad_msg_count >= 3 and localizer.bad_msg_count >= 4, 5.0)
        assert builder.builder.state == "waiting"  # nothing valid arrived
    finally:
        ex.shutdown()
        for n in (builder, localizer, probe):
            n.destroy_node()


def _flatten(obj: Any, prefix: str) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            out.update(_flatten(v, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = v.value if isinstance(v, Enum) else v
    return out


def _flatten_yaml(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten_yaml(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


@pytest.mark.parametrize(("node", "defaults"), [
    ("island_builder_node", {"": IslandBuilderNodeConfig(), "builder.": BuilderConfig(),
                             "explorer.": ExplorerConfig()}),
    ("explorer_node", {"": ExplorerNodeConfig()}),
    ("island_localizer_node", {"tracker.": TrackerConfig()}),
])
def test_yaml_repeats_the_config_defaults(node: str, defaults: dict[str, Any]) -> None:
    doc = yaml.safe_load((CONFIG_DIR / f"{node}.yaml").read_text())
    want: dict[str, Any] = {}
    for prefix, default in defaults.items():
        want.update(_flatten(default, prefix))
    assert _flatten_yaml(doc[node]["ros__parameters"]) == want
