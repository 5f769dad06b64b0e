"""The simulator nodes as a ROS 2 user runs them: moved by `-r __ns:=...` with prefixed frames,
and parameters set at run time through the parameter services (as `ros2 param set` does) that
take effect or are refused with the reason."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest
import rclpy
from geometry_msgs.msg import TwistStamped
from island_msgs_py.conversions import time_to_ns
from island_sim.core.hall_follower import TurnPolicy
from island_sim.nodes.hall_follower_node import HallFollowerNode
from island_sim.nodes.odometry_node import OdometryNode
from island_sim.nodes.sonar_node import SonarNode
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.exceptions import ParameterException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from sensor_msgs.msg import LaserScan

QOS = QoSProfile(depth=100)


def _p(name: str, value: Any) -> Parameter:
    return Parameter(name, value=value)


def _ns(name: str) -> list[str]:
    """What `ros2 run ... --ros-args -r __ns:=/<name>` passes."""
    return ["--ros-args", "-r", f"__ns:=/{name}"]


def _spin(ex: SingleThreadedExecutor, cond: Callable[[], bool], timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while not cond():
        if time.monotonic() > deadline:
            return False
        ex.spin_once(timeout_sec=0.02)
    return True


def _set(ex: SingleThreadedExecutor, client: Node, node: str, name: str,
         value: Any) -> SetParametersResult:
    """`ros2 param set <node> <name> <value>`: rcl_interfaces/srv/SetParameters."""
    cli = client.create_client(SetParameters, f"{node}/set_parameters")
    try:
        assert cli.wait_for_service(timeout_sec=5.0)
        fut = cli.call_async(SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()]))
        assert _spin(ex, fut.done, 10.0)
        return fut.result().results[0]
    finally:
        client.destroy_client(cli)


def test_two_namespaced_robots_in_one_process_do_not_hear_each_other(ros_context: Any) -> None:
    ctx = ros_context
    nodes: list[Node] = []
    robots: dict[str, tuple[OdometryNode, HallFollowerNode]] = {}
    for name, claimed in (("robot1", True), ("robot2", False)):
        prefix = _p("frame_prefix", f"{name}/")
        odo = OdometryNode(context=ctx, cli_args=_ns(name), parameter_overrides=[
            _p("world", "paper_fig4"), _p("seed", 1), _p("sim.real_time_factor", 0.0),
            _p("sim.lockstep", True), _p("sim.own_clock", name == "robot1"), prefix])
        sonar = SonarNode(context=ctx, cli_args=_ns(name), parameter_overrides=[
            _p("world", "paper_fig4"), prefix])
        # robot1's follower drives at once; robot2's waits for a claim that never comes
        follower = HallFollowerNode(context=ctx, cli_args=_ns(name), parameter_overrides=[
            _p("autostart", claimed), prefix])
        robots[name] = (odo, follower)
        nodes += [odo, sonar, follower]
    probe = Node("namespace_probe", context=ctx)
    nodes.append(probe)
    cmds: dict[str, list[TwistStamped]] = {"robot1": [], "robot2": []}
    odoms: list[Odometry] = []
    scans: list[LaserScan] = []
    for name, got in cmds.items():
        probe.create_subscription(TwistStamped, f"/{name}/cmd_vel", got.append, QOS)
    probe.create_subscription(Odometry, "/robot1/odom", odoms.append, QOS)
    probe.create_subscription(LaserScan, "/robot1/sonar/scan", scans.append, QOS)
    ex = SingleThreadedExecutor(context=ctx)
    for n in nodes:
        ex.add_node(n)
    try:
        odo1, odo2 = robots["robot1"][0], robots["robot2"][0]
        assert _spin(ex, lambda: odo1.robot.distance_m > 2.0 and odo2.sim_time_ns > 5 * 10**9,
                     60.0), (odo1.robot.distance_m, odo2.sim_time_ns)
        # robot1 drove on its own commands; robot2 heard none of them and stood still
        assert odo2.robot.distance_m == 0.0 and robots["robot2"][1].scans_processed > 0
        assert any(c.twist.linear.x > 0.1 for c in cmds["robot1"])
        assert cmds["robot2"] and all(c.twist.linear.x == 0.0 for c in cmds["robot2"])
        # a command stamped with robot2's scans, not robot1's: its own lockstep answered it
        assert odo2.lockstep_timeouts == 0 and odo1.lockstep_timeouts == 0
        assert {c.header.frame_id for c in cmds["robot1"]} == {"robot1/base_link"}
        assert {c.header.frame_id for c in cmds["robot2"]} == {"robot2/base_link"}
        assert (odoms[-1].header.frame_id, odoms[-1].child_frame_id) == (
            "robot1/odom", "robot1/base_link")
        assert scans[-1].header.frame_id == "robot1/base_link"
        topics = {t for t, _ in probe.get_topic_names_and_types()}
        assert {"/robot1/cmd_vel", "/robot2/cmd_vel", "/robot1/hall_follower/strategy"} <= topics
        assert not topics & {"/cmd_vel", "/odom", "/sonar/scan", "/hall_follower/strategy"}
        assert max(time_to_ns(c.header.stamp) for c in cmds["robot2"]) <= odo2.sim_time_ns
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()


def test_the_real_time_factor_set_at_run_time_paces_the_simulation(ros_context: Any) -> None:
    odo = OdometryNode(context=ros_context, parameter_overrides=[
        _p("world", "corridor"), _p("sim.real_time_factor", 0.5)])
    client = Node("rtf_client", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(odo)
    ex.add_node(client)
    try:
        _spin(ex, lambda: odo.sim_time_ns > 0, 10.0)
        t0, w0 = odo.sim_time_ns, time.monotonic()
        _spin(ex, lambda: time.monotonic() - w0 > 2.0, 5.0)
        slow = (odo.sim_time_ns - t0) * 1e-9
        assert slow <= 0.5 * (time.monotonic() - w0) + 0.1  # never ahead of 0.5x wall time
        res = _set(ex, client, "/odometry_node", "sim.real_time_factor", 8.0)
        assert res.successful, res.reason
        t1, w1 = odo.sim_time_ns, time.monotonic()
        _spin(ex, lambda: time.monotonic() - w1 > 2.0, 5.0)
        fast = (odo.sim_time_ns - t1) * 1e-9
        assert fast > 2.0, fast  # more than 1x wall: the new factor took effect
        # a value outside the descriptor's range, and a read-only parameter, are refused
        neg = _set(ex, client, "/odometry_node", "sim.real_time_factor", -1.0)
        assert not neg.successful and "out of range" in neg.reason
        world = _set(ex, client, "/odometry_node", "world", "t_junction")
        assert not world.successful and "read-only" in world.reason
        assert odo.cfg.sim.real_time_factor == 8.0 and odo.world.name == "corridor"
    finally:
        ex.shutdown()
        client.destroy_node()
        odo.destroy_node()


def test_follower_parameters_set_at_run_time_take_effect_or_are_refused(
        ros_context: Any) -> None:
    ctx = ros_context
    odo = OdometryNode(context=ctx, parameter_overrides=[
        _p("world", "paper_fig4"), _p("seed", 2), _p("sim.real_time_factor", 0.0),
        _p("sim.lockstep", True)])
    sonar = SonarNode(context=ctx, parameter_overrides=[_p("world", "paper_fig4")])
    follower = HallFollowerNode(context=ctx, parameter_overrides=[_p("autostart", True)])
    client = Node("follower_param_client", context=ctx)
    cmds: list[TwistStamped] = []
    client.create_subscription(TwistStamped, "/cmd_vel", cmds.append, QOS)
    ex = SingleThreadedExecutor(context=ctx)
    for n in (odo, sonar, follower, client):
        ex.add_node(n)
    try:
        assert _spin(ex, lambda: any(c.twist.linear.x > 0.45 for c in cmds), 30.0)
        res = _set(ex, client, "/hall_follower_node", "follower.cruise_speed_mps", 0.2)
        assert res.successful, res.reason
        changed_at = odo.sim_time_ns
        assert _spin(ex, lambda: odo.sim_time_ns > changed_at + 20 * 10**9, 60.0)
        later = [c.twist.linear.x for c in cmds if time_to_ns(c.header.stamp) > changed_at]
        assert len(later) > 100 and max(later) <= 0.2 + 1e-9
        assert odo.robot.velocity[0] <= 0.2 + 1e-6
        bogus = _set(ex, client, "/hall_follower_node", "follower.policy", "bogus")
        assert not bogus.successful
        assert "'bogus' is not one of left_hand, right_hand, scripted, random" in bogus.reason
        assert follower.follower.config.policy is TurnPolicy.LEFT_HAND
        assert _set(ex, client, "/hall_follower_node", "follower.policy", "right_hand").successful
        assert follower.follower.config.policy is TurnPolicy.RIGHT_HAND
        # a value the follower's own config refuses (the stop distance inside the robot)
        inside = _set(ex, client, "/hall_follower_node", "follower.stop_distance_m", 0.1)
        assert not inside.successful and "must exceed robot_radius_m" in inside.reason
        seed = _set(ex, client, "/hall_follower_node", "seed", 7)
        assert not seed.successful and "read-only" in seed.reason
    finally:
        ex.shutdown()
        for n in (odo, sonar, follower, client):
            n.destroy_node()
        assert rclpy.ok(context=ctx)


def test_out_of_range_values_are_refused_at_start_and_ranges_are_described(
        ros_context: Any) -> None:
    """`ros2 param describe` shows each range; a value outside it never starts the node."""
    with pytest.raises(ParameterException, match=r"sonar\.reflect_deg"):
        SonarNode(context=ros_context, parameter_overrides=[_p("sonar.reflect_deg", 120.0)])
    odo = OdometryNode(context=ros_context, parameter_overrides=[_p("world", "corridor")])
    try:
        desc = {d.name: d for d in odo.describe_parameters(
            ["odometry.dist_heading_correlation", "robot.max_linear_speed_mps", "seed"])}
        corr = desc["odometry.dist_heading_correlation"].floating_point_range[0]
        assert (corr.from_value, corr.to_value) == (-1.0, 1.0)
        assert desc["robot.max_linear_speed_mps"].floating_point_range[0].from_value == 0.0
        assert all(d.read_only for d in desc.values())
    finally:
        odo.destroy_node()
