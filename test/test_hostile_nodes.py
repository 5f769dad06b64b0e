"""Every live node of an exploration, one hostile message of each class at a time: each is
counted and skipped, and every node still answers afterwards (issue 17).

The simulator (lockstep, sim time), the hall follower, the island builder, the localizer and the
graph server run on one executor in paper_fig4 while a probe node sends: stamps of 2^31 - 1 s on
/cmd_vel, /ground_truth, /odom and /sonar/scan; LaserScans of 10^6 ranges; a 5,000-digit
`Go` in the follower's progress; island events with a 400-digit
coordinate, nested 100,000 deep, or larger than the event limit.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import TwistStamped
from island_mapping.nodes.island_builder_node import IslandBuilderNode
from island_mapping.nodes.island_localizer_node import IslandLocalizerNode
from island_mapping.nodes.topo_graph_server_node import TopoGraphServerNode
from island_msgs_py.conversions import (
    command_to_twist_stamped,
    ns_to_time,
    pose_to_odometry,
)
from island_msgs_py.json_io import island_to_dict
from island_msgs_py.limits import MAX_EVENT_JSON_BYTES, MAX_SCAN_RANGES
from island_msgs_py.ros_params import spin_guarded
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D
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

QOS = QoSProfile(depth=100)
FAR_NS = (2**31 - 1) * 10**9  # the largest stamp a builtin_interfaces/Time holds [ns]
HUGE_SCAN_RANGES = 10**6
VALID_EVENT = {
    "kind": "island_accepted",
    "island": island_to_dict(Island(7, LineModel(np.array([[0.0, 1.0, 3.0, 1.0]])),
                                    ModelType.LINE, 1.5, 10.0)),
    "anchor_odom": {"x": 1.0, "y": 2.0, "theta": 0.0},
}


def _p(name: str, value: Any) -> Parameter:
    return Parameter(name, value=value)


@dataclass
class Run:
    odo: OdometryNode
    sonar: SonarNode
    follower: HallFollowerNode
    builder: IslandBuilderNode
    localizer: IslandLocalizerNode
    probe: Node
    executor: SingleThreadedExecutor
    others: list[Node] = field(default_factory=list)

    def spin_until(self, cond: Callable[[], bool], timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while not cond():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.02)
        return True

    def nodes(self) -> list[Node]:
        return [self.odo, self.sonar, self.follower, self.builder, self.localizer, self.probe,
                *self.others]


@pytest.fixture
def run(ros_context: Any) -> Iterator[Run]:
    ctx = ros_context
    lean: dict[str, Any] = {"start_parameter_services": False}
    sim_time = [_p("use_sim_time", True), _p("start_type_description_service", False)]
    odo = OdometryNode(context=ctx, parameter_overrides=[
        _p("world", "paper_fig4"), _p("seed", 3), _p("sim.real_time_factor", 0.0),
        _p("sim.lockstep", True), _p("sim.publish_rate_hz", 10.0)], **lean)
    sonar = SonarNode(context=ctx, parameter_overrides=[
        *sim_time, _p("world", "paper_fig4"), _p("seed", 4)], **lean)
    follower = HallFollowerNode(context=ctx, parameter_overrides=sim_time, **lean)
    builder = IslandBuilderNode(context=ctx, parameter_overrides=sim_time)
    localizer = IslandLocalizerNode(context=ctx, parameter_overrides=sim_time)
    server = TopoGraphServerNode(context=ctx)
    probe = Node("hostile_probe", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    r = Run(odo, sonar, follower, builder, localizer, probe, ex, [server])
    for n in r.nodes():
        ex.add_node(n)
    try:
        yield r
    finally:
        ex.shutdown()
        for n in r.nodes():
            n.destroy_node()


def _far_odometry() -> Odometry:
    return pose_to_odometry(Pose2D(5.0, 5.0, 0.0), None, FAR_NS, "odom")


def _scan(n_ranges: int, t_ns: int) -> LaserScan:
    msg = LaserScan(angle_increment=2 * math.pi / n_ranges, range_min=0.1, range_max=10.0)
    msg.header.stamp = ns_to_time(t_ns)
    msg.ranges = [1.0] * n_ranges
    return msg


def _hostile_events() -> list[str]:
    coord = dict(VALID_EVENT, anchor_odom={"x": int("9" * 400), "y": 0.0, "theta": 0.0})
    deep = "[" * 100_000 + "]" * 100_000
    big = json.dumps({"kind": "island_accepted", "pad": "x" * (MAX_EVENT_JSON_BYTES + 1)})
    return [json.dumps(coord), deep, big]


def test_each_hostile_message_is_counted_and_every_node_still_answers(run: Run) -> None:
    pub = run.probe.create_publisher
    cmd = pub(TwistStamped, "/cmd_vel", QOS)
    truth = pub(Odometry, "/ground_truth", QOS)
    odom = pub(Odometry, "/odom", QOS)
    scan = pub(LaserScan, "/sonar/scan", QOS)
    events = pub(String, "/island_builder/events", QOS)
    strategy = pub(String, "/hall_follower/progress", QOS)
    assert run.spin_until(lambda: run.odo.cmd_count > 5 and run.builder.builder.path_m > 0, 60.0)
    assert run.spin_until(lambda: min(p.get_subscription_count() for p in (cmd, truth, odom, scan,
                                                                           events)) > 0, 10.0)
    before = {n: n.bad_msg_count for n in (run.sonar, run.follower, run.builder, run.localizer)}
    bad_cmds = run.odo.bad_cmd_count

    cmd.publish(command_to_twist_stamped(0.3, 0.0, FAR_NS))
    truth.publish(_far_odometry())
    odom.publish(_far_odometry())
    scan.publish(_scan(16, FAR_NS))
    for _ in range(3):
        scan.publish(_scan(HUGE_SCAN_RANGES, 0))
    for text in _hostile_events():
        events.publish(String(data=text))
    strategy.publish(String(data="Go " + "9" * 5000))

    def counted() -> bool:
        return (run.odo.bad_cmd_count > bad_cmds
                and run.sonar.bad_msg_count > before[run.sonar]
                and run.follower.bad_msg_count >= before[run.follower] + 5  # odom + 4 scans
                and run.builder.bad_msg_count >= before[run.builder] + 6  # + strategy
                and run.localizer.bad_msg_count >= before[run.localizer] + 8)  # + 3 events

    assert run.spin_until(counted, 30.0), (
        run.odo.bad_cmd_count - bad_cmds, {type(n).__name__: n.bad_msg_count - c
                                           for n, c in before.items()})
    # every node still answers: time advances, scans are made and followed, the builder goes on
    # deciding, the localizer takes a valid island
    t0, scans0, followed0 = run.odo.sim_time_ns, run.sonar.scans_published, \
        run.follower.scans_processed
    path0, cmds0 = run.builder.builder.path_m, run.odo.cmd_count
    events.publish(String(data=json.dumps(VALID_EVENT)))
    assert run.spin_until(lambda: run.odo.sim_time_ns > t0 + 5 * 10**9
                          and run.sonar.scans_published > scans0 + 10
                          and run.follower.scans_processed > followed0 + 10
                          and run.odo.cmd_count > cmds0 + 10, 60.0)
    assert run.builder.builder.path_m > path0
    assert run.localizer.tracker.origin_odom(7) == Pose2D(1.0, 2.0, 0.0)
    assert math.isfinite(run.odo.robot.true_pose.x)


def test_a_scan_longer_than_the_limit_costs_no_work(ros_context: Any) -> None:
    """10^6 ranges are refused on their length, before any work (three such scans once wedged
    the localizer for over 10 minutes at 1.6 GB)."""
    localizer = IslandLocalizerNode(context=ros_context)
    probe = Node("hostile_scan_probe", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    for n in (localizer, probe):
        ex.add_node(n)
    try:
        scan = probe.create_publisher(LaserScan, "/sonar/scan", QOS)
        deadline = time.monotonic() + 10.0
        while scan.get_subscription_count() == 0 and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.02)
        for _ in range(3):
            scan.publish(_scan(HUGE_SCAN_RANGES, 10**9))
        scan.publish(_scan(MAX_SCAN_RANGES + 1, 10**9))
        deadline = time.monotonic() + 30.0
        while localizer.bad_msg_count < 4 and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.02)
        assert localizer.bad_msg_count == 4
    finally:
        ex.shutdown()
        for n in (localizer, probe):
            n.destroy_node()


def test_an_exception_escaping_a_callback_does_not_stop_the_node(ros_context: Any) -> None:
    """run_node's spin (spin_guarded) logs a callback that raised and spins on."""
    node = Node("hostile_raising_node", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ticks: list[int] = []

    def tick() -> None:
        ticks.append(1)
        if len(ticks) == 5:
            ros_context.shutdown()
        elif len(ticks) % 2:
            raise RuntimeError("a bug a message triggered")

    node.create_timer(0.01, tick)
    try:
        spin_guarded(ex, node)  # returns when the context shuts down
        assert len(ticks) == 5  # the callbacks that raised (1st, 3rd) did not end the spin
    finally:
        ex.shutdown()
        node.destroy_node()
