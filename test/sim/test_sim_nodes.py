"""The three simulator nodes in one process, on one executor, in sim time."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rclpy
import yaml
from geometry_msgs.msg import TwistStamped
from island_msgs_py.conversions import (
    command_to_twist_stamped,
    ns_to_time,
    odometry_to_pose,
    pose_to_odometry,
    time_to_ns,
)
from island_msgs_py.types import ControlStrategy, Pose2D
from island_sim.core.world_loader import load_world
from island_sim.nodes.hall_follower_node import LATCHED, HallFollowerNode
from island_sim.nodes.odometry_node import OdometryNode
from island_sim.nodes.sonar_node import SonarNode
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan, Range
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

CONFIG_DIR = Path(__file__).resolve().parents[2] / "src" / "island_sim" / "config"
QOS = QoSProfile(depth=100)
# Centres [m] of the junctions of paper_fig4's 2 m corridors (loop corners with their stubs,
# the T's and the + of the middle corridors); see island_sim.core.worlds_builtin.
FIG4_JUNCTIONS = [(9, 9), (61, 9), (9, 35), (61, 35), (35, 9), (35, 35), (9, 22), (35, 22)]
NO_SYSTEMATIC_DRIFT = [
    Parameter("odometry.wheel_radius_ratio_error", value=0.0),
    Parameter("odometry.wheelbase_error", value=0.0),
]


def _p(name: str, value: Any) -> Parameter:
    return Parameter(name, value=value)


@dataclass
class Sim:
    odo: OdometryNode
    sonar: SonarNode
    follower: HallFollowerNode
    executor: SingleThreadedExecutor
    extra: list[Node] = field(default_factory=list)

    def spin_until(self, cond: Callable[[], bool], timeout_s: float,
                   each: Callable[[], None] | None = None) -> bool:
        deadline = time.monotonic() + timeout_s
        while not cond():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.05)
            if each is not None:
                each()
        return True

    def close(self) -> None:
        self.executor.shutdown()
        for n in (self.odo, self.sonar, self.follower, *self.extra):
            n.destroy_node()


def make_sim(ctx: Any, seed: int, odo_params: list[Parameter],
             follower_params: list[Parameter] | None = None) -> Sim:
    # Fewer entities per wait set keep the single executor fast: no parameter services.
    lean: dict[str, Any] = {"start_parameter_services": False}
    no_desc = _p("start_type_description_service", False)
    sim_time = [_p("use_sim_time", True), no_desc]
    odo = OdometryNode(context=ctx, parameter_overrides=[
        _p("world", "paper_fig4"), _p("seed", seed), _p("sim.real_time_factor", 0.0), no_desc,
        *odo_params,
    ], **lean)
    sonar = SonarNode(context=ctx, parameter_overrides=[
        *sim_time, _p("world", "paper_fig4"), _p("seed", seed + 1)], **lean)
    # autostart: no mapper claims the robot here, so the follower drives at once
    follower = HallFollowerNode(context=ctx, parameter_overrides=[
        *sim_time, _p("autostart", True), *(follower_params or [])], **lean)
    ex = SingleThreadedExecutor(context=ctx)
    for n in (odo, sonar, follower):
        ex.add_node(n)
    return Sim(odo, sonar, follower, ex)


@dataclass
class Trace:
    truth: list[np.ndarray] = field(default_factory=list)
    errors: list[tuple[float, float]] = field(default_factory=list)  # (t_s, |odom - truth| m)
    min_clearance_m: float = math.inf
    at_120: tuple[np.ndarray, np.ndarray] | None = None


def run_lockstep(ctx: Any, seed: int, duration_s: float, timeout_s: float) -> tuple[Sim, Trace]:
    # /odom, /ground_truth and /clock at the 10 Hz sensor rate (physics still at 50 Hz): the
    # 600 s run then needs about a third of the callbacks (the bench measures 50 Hz).
    sim = make_sim(ctx, seed, [_p("sim.lockstep", True), _p("sim.stop_after_s", duration_s),
                               _p("sim.publish_rate_hz", 10.0), *NO_SYSTEMATIC_DRIFT])
    trace = Trace()

    last_step = [-1]

    def sample() -> None:
        if sim.odo.step_count == last_step[0]:
            return
        last_step[0] = sim.odo.step_count
        r = sim.odo.robot
        trace.truth.append(r.true_pose.as_array())
        trace.min_clearance_m = min(trace.min_clearance_m, r.clearance_m)
        t = sim.odo.sim_time_ns * 1e-9
        if not trace.errors or t - trace.errors[-1][0] >= 10.0:
            d = r.odom_pose.as_array() - r.true_pose.as_array()
            trace.errors.append((t, math.hypot(d[0], d[1])))
        if trace.at_120 is None and sim.odo.step_count == 6000:
            trace.at_120 = (r.true_pose.as_array(), r.odom_pose.as_array())

    assert sim.spin_until(lambda: sim.odo.finished, timeout_s, sample), (
        f"simulation stalled at {sim.odo.sim_time_ns * 1e-9:.1f} s sim time"
    )
    last_scan = round(duration_s * 10) + 1  # the scan of the final instant, too
    assert sim.spin_until(lambda: sim.follower.scans_processed >= last_scan, 10.0)
    return sim, trace


@pytest.mark.slow
def test_three_nodes_follow_halls_for_600_s_deterministically(ros_context: Any) -> None:
    sim, trace = run_lockstep(ros_context, seed=11, duration_s=600.0, timeout_s=150.0)
    try:
        odo, sonar, follower = sim.odo, sim.sonar, sim.follower
        # lockstep: one scan per 0.1 s, one command per scan, no fallback timeouts
        assert odo.sim_time_ns == 600 * 10**9
        assert sonar.scans_published == 6001  # t = 0, 0.1, ..., 600 s
        assert follower.scans_processed == sonar.scans_published
        assert odo.cmd_count >= 6000 and odo.lockstep_timeouts == 0
        # never touched a wall
        assert odo.robot.collisions == 0
        assert trace.min_clearance_m > 0.2
        # followed halls: travelled far and passed at least three distinct junctions
        truth = np.array(trace.truth)
        assert odo.robot.distance_m > 200.0
        visited = [
            j for j in FIG4_JUNCTIONS
            if np.min(np.hypot(truth[:, 0] - j[0], truth[:, 1] - j[1])) < 0.75
        ]
        assert len(visited) >= 3, visited
        # the gap between odometry and ground truth grows as configured (random drift only)
        errs = np.array(trace.errors)
        assert errs[-1, 1] > errs[len(errs) // 4, 1] > 0.0
        d = odo.robot.odom_pose.as_array() - odo.robot.true_pose.as_array()
        cov = odo.robot.odom_covariance[:2, :2]
        mahalanobis2 = float(d[:2] @ np.linalg.solve(cov, d[:2]))
        assert mahalanobis2 < 13.8  # chi-square, 2 dof, 99.9 %
        assert odo.robot.epsilon_m > 1.0  # hundreds of metres of random drift: clearly lost
        # the executed strategy is published (latched) in Table 1 form, up to its last
        # completed step; the whole record is as long as the robot drove
        got: list[str] = []
        probe = Node("strategy_probe", context=ros_context)
        sim.extra.append(probe)
        probe.create_subscription(String, "/hall_follower/strategy",
                                  lambda m: got.append(m.data), LATCHED)
        sim.executor.add_node(probe)
        assert sim.spin_until(lambda: bool(got), 5.0)
        record = follower.follower.strategy()
        assert ControlStrategy.parse(got[-1]).steps == record.steps[:-1]
        assert len(record.steps) > 5
        assert record.length_m == pytest.approx(odo.robot.distance_m, rel=0.05)
        first = trace.at_120
        assert first is not None
        decisions_120 = [d for d in follower.follower.decisions if d.t_s <= 120.0]
    finally:
        sim.close()

    # same seed, same trajectory (compared over the first 120 s)
    again, _ = run_lockstep(ros_context, seed=11, duration_s=120.0, timeout_s=60.0)
    try:
        assert np.array_equal(again.odo.robot.true_pose.as_array(), first[0])
        assert np.array_equal(again.odo.robot.odom_pose.as_array(), first[1])
        assert again.follower.follower.decisions == decisions_120
    finally:
        again.close()


def test_bad_messages_are_counted_and_nodes_keep_running(ros_context: Any) -> None:
    sim = make_sim(ros_context, 0, [_p("sim.lockstep", True)])
    pub_node = Node("bad_publisher", context=ros_context)
    sim.extra.append(pub_node)
    sim.executor.add_node(pub_node)
    cmd = pub_node.create_publisher(TwistStamped, "/cmd_vel", QOS)
    scan = pub_node.create_publisher(LaserScan, "/sonar/scan", QOS)
    truth = pub_node.create_publisher(Odometry, "/ground_truth", QOS)
    try:
        assert sim.spin_until(lambda: sim.odo.cmd_count > 5, 20.0)  # the follower drives
        assert sim.spin_until(lambda: min(p.get_subscription_count() for p in (cmd, scan, truth))
                              > 0, 5.0)
        before = sim.odo.cmd_count
        for v, w in ((math.nan, 0.0), (0.1, math.inf)):
            cmd.publish(command_to_twist_stamped(v, w, 0))
        scan.publish(LaserScan())  # no ranges
        bad_truth = pose_to_odometry(Pose2D(1.0, 1.0, 0.0), None, 0, "map")
        bad_truth.pose.pose.orientation.w = math.nan
        bad_truth.pose.pose.orientation.z = math.nan
        truth.publish(bad_truth)
        ok = sim.spin_until(
            lambda: sim.odo.bad_cmd_count == 2 and sim.follower.bad_msg_count >= 1
            and sim.sonar.bad_msg_count == 1, 10.0)
        counts = (sim.odo.bad_cmd_count, sim.follower.bad_msg_count, sim.sonar.bad_msg_count)
        assert ok, counts
        # all three are alive: the robot still receives good commands and time advances
        t_before = sim.odo.sim_time_ns
        assert sim.spin_until(lambda: sim.odo.cmd_count > before + 5, 10.0)
        assert sim.odo.sim_time_ns > t_before
        assert math.isfinite(sim.odo.robot.true_pose.x)
    finally:
        sim.close()


def test_lockstep_waits_by_stamp_when_two_controllers_answer_one_scan(ros_context: Any) -> None:
    """At a hand-over the builder and the hall follower both answer one scan. The robot must
    still wait at every later boundary for a command answering that boundary's scan: were extra
    commands counted toward later periods, the robot would run ahead and every command would
    act on an old scan (the follower then weaves: found in paper_fig4 runs)."""
    sim = make_sim(ros_context, 3, [_p("sim.lockstep", True)])
    probe = Node("second_controller", context=ros_context)
    sim.extra.append(probe)
    sim.executor.add_node(probe)
    cmd = probe.create_publisher(TwistStamped, "/cmd_vel", QOS)
    newest_cmd_ns = [-1]
    duplicates = [0]

    def on_scan(msg: LaserScan) -> None:
        if duplicates[0] < 20:  # answer the same scan as the follower does
            duplicates[0] += 1
            cmd.publish(command_to_twist_stamped(0.0, 0.0, time_to_ns(msg.header.stamp)))

    def on_cmd(msg: TwistStamped) -> None:
        newest_cmd_ns[0] = max(newest_cmd_ns[0], time_to_ns(msg.header.stamp))

    probe.create_subscription(LaserScan, "/sonar/scan", on_scan, QOS)
    probe.create_subscription(TwistStamped, "/cmd_vel", on_cmd, QOS)
    period_ns = 10**8  # 10 Hz sonar
    worst = [0]

    def check() -> None:
        if duplicates[0] >= 20 and newest_cmd_ns[0] >= 0:
            worst[0] = max(worst[0], sim.odo.sim_time_ns - newest_cmd_ns[0])

    try:
        assert sim.spin_until(lambda: duplicates[0] >= 20, 30.0)
        t_dup = sim.odo.sim_time_ns
        assert sim.spin_until(lambda: sim.odo.sim_time_ns > t_dup + 10 * 10**9, 60.0, each=check)
        # never more than a sensor period ahead of the newest command, plus one period for the
        # probe's own copy of /cmd_vel arriving after the robot's (the old count-based lockstep
        # ran 21 periods ahead here)
        assert 0 < worst[0] <= 2 * period_ns, worst[0]
        assert sim.odo.lockstep_timeouts == 0
    finally:
        sim.close()


def test_ground_truth_and_clock_at_their_own_rates_odometry_at_every_step(
        ros_context: Any) -> None:
    """What `islands explore` runs: /odom at every 50 Hz step (the builder integrates each),
    /ground_truth and /clock at the 10 Hz sensor instants only; the serialized /odom the node
    publishes reads back as the robot's pose and covariance."""
    odo = OdometryNode(context=ros_context, parameter_overrides=[
        _p("world", "paper_fig4"), _p("sim.real_time_factor", 0.0), _p("sim.stop_after_s", 1.0),
        _p("sim.truth_rate_hz", 10.0), _p("sim.clock_rate_hz", 10.0)])
    probe = Node("rate_probe", context=ros_context)
    got: dict[str, list[int]] = {"odom": [], "truth": [], "clock": []}
    last: list[Odometry] = []

    def on_odom(msg: Odometry) -> None:
        got["odom"].append(time_to_ns(msg.header.stamp))
        last[:] = [msg]

    deep = QoSProfile(depth=1000)
    probe.create_subscription(Odometry, "/odom", on_odom, deep)
    probe.create_subscription(Odometry, "/ground_truth",
                              lambda m: got["truth"].append(time_to_ns(m.header.stamp)), deep)
    probe.create_subscription(Clock, "/clock", lambda m: got["clock"].append(
        time_to_ns(m.clock)), deep)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    try:
        deadline = time.monotonic() + 5.0
        while odo.odom_pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        ex.add_node(odo)
        deadline = time.monotonic() + 20.0
        while (len(got["odom"]) < 50 or len(got["clock"]) < 10) and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        assert got["odom"] == [k * 20_000_000 for k in range(1, 51)]  # not locked: from step 1
        assert got["truth"] == got["clock"] == [k * 100_000_000 for k in range(1, 11)]
        assert odo.finished_future.done() and odo.finished_future.result() == 10**9
        pose, cov, _ = odometry_to_pose(last[0])
        assert pose == odo.robot.odom_pose
        assert np.array_equal(cov, odo.robot.odom_covariance)
        assert last[0].header.frame_id == "odom" and last[0].child_frame_id == "base_link"
    finally:
        ex.shutdown()
        odo.destroy_node()
        probe.destroy_node()


def test_sonar_scans_once_per_period_at_the_ground_truth_stamp(ros_context: Any) -> None:
    sonar = SonarNode(context=ros_context, parameter_overrides=[
        _p("world", "corridor"), _p("sonar.ideal", True), _p("publish_ranges", True)])
    probe = Node("scan_probe", context=ros_context)
    scans: list[LaserScan] = []
    ranges: list[Range] = []
    probe.create_subscription(LaserScan, "/sonar/scan", scans.append, QOS)
    for i in range(16):
        probe.create_subscription(Range, f"/sonar/range_{i}", ranges.append, QOS)
    truth = probe.create_publisher(Odometry, "/ground_truth", QOS)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(sonar)
    ex.add_node(probe)
    try:
        deadline = time.monotonic() + 5.0
        while truth.get_subscription_count() == 0 and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        pose = Pose2D(5.0, 1.0, 0.0)  # middle of the 20 x 2 m corridor, heading +x
        for k in range(11):  # 50 Hz stamps over 0.2 s: boundaries at 0, 0.1 and 0.2 s
            truth.publish(pose_to_odometry(pose, None, k * 20_000_000, "map"))
        deadline = time.monotonic() + 5.0
        while (len(scans) < 3 or len(ranges) < 48) and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        assert [s.header.stamp for s in scans] == [ns_to_time(t) for t in
                                                   (0, 100_000_000, 200_000_000)]
        s = scans[0]
        lo, hi = sonar.model.scan_limits_m()
        assert s.range_min == pytest.approx(lo) and s.range_max == pytest.approx(hi)
        assert s.angle_min == pytest.approx(0.0)
        assert s.angle_increment == pytest.approx(2 * math.pi / 16)
        assert len(s.ranges) == 16 and s.header.frame_id == "base_link"
        # ideal ranges are the ray cast from the transducers (+ ring radius) of the world
        world = load_world("corridor")
        ring = sonar.cfg.sonar.ring_radius_m
        ang = np.arange(16) * 2 * math.pi / 16
        origins = np.stack([5.0 + ring * np.cos(ang), 1.0 + ring * np.sin(ang)], axis=1)
        expect = world.raycast(origins, ang).distance_m + ring
        expect = np.where((expect >= lo) & (expect <= hi), expect, np.inf)
        got = np.array(s.ranges)
        assert np.array_equal(np.isinf(got), np.isinf(expect))
        assert np.allclose(got[np.isfinite(got)], expect[np.isfinite(expect)], atol=1e-3)
        assert math.isinf(got[0]) and got[4] == pytest.approx(1.0, abs=1e-3)  # 15 m ahead, 1 m left
        r4 = next(r for r in ranges if r.header.frame_id == "sonar_4")
        assert r4.radiation_type == Range.ULTRASOUND and r4.range == pytest.approx(1.0, abs=1e-3)
        assert r4.field_of_view == pytest.approx(math.radians(25.0))
    finally:
        ex.shutdown()
        sonar.destroy_node()
        probe.destroy_node()


def _call(sim: Sim, client: Any, request: Any) -> Any:
    assert client.wait_for_service(timeout_sec=5.0)
    fut = client.call_async(request)
    assert sim.spin_until(fut.done, 5.0)
    return fut.result()


def test_reset_is_refused_while_following_and_pause_stops_commands(ros_context: Any) -> None:
    sim = make_sim(ros_context, 3, [_p("sim.real_time_factor", 10.0)],
                   [_p("follower.policy", "right_hand")])
    probe = Node("service_probe", context=ros_context)
    sim.extra.append(probe)
    sim.executor.add_node(probe)
    strategies: list[str] = []
    progress: list[str] = []
    probe.create_subscription(String, "/hall_follower/strategy",
                              lambda m: strategies.append(m.data), LATCHED)
    probe.create_subscription(String, "/hall_follower/progress",
                              lambda m: progress.append(m.data), QOS)
    reset = probe.create_client(Trigger, "/hall_follower/reset")
    enable = probe.create_client(SetBool, "/hall_follower/enable")
    try:
        # Without lockstep a loaded machine drops commands (they time out), so wait for the
        # distance, not for sim time.
        assert sim.spin_until(lambda: sim.follower.follower.strategy().length_m > 0.3, 60.0)
        # while following, the record is the strategy of the edge being driven: not reset
        resp = _call(sim, reset, Trigger.Request())
        assert not resp.success and "pause it first" in resp.message
        assert sim.follower.follower.strategy().length_m > 0.3
        resp = _call(sim, enable, SetBool.Request(data=False))
        assert resp.success and "paused" in resp.message
        # at the pause the whole record is latched
        paused_at = str(sim.follower.follower.strategy())
        assert sim.spin_until(lambda: bool(strategies) and strategies[-1] == paused_at, 5.0)
        assert ControlStrategy.parse(paused_at).length_m > 0.3
        assert _call(sim, reset, Trigger.Request()).success
        assert sim.spin_until(lambda: strategies[-1] == "", 5.0)  # the record restarts
        # A command published just before the pause may still be in flight: let it land first.
        before = sim.follower.scans_processed
        assert sim.spin_until(lambda: sim.follower.scans_processed > before + 2, 20.0)
        processed, cmds = sim.follower.scans_processed, sim.odo.cmd_count
        assert sim.spin_until(lambda: sim.follower.scans_processed > processed + 20, 20.0)
        assert sim.odo.cmd_count == cmds  # paused: nothing on /cmd_vel
        assert sim.odo.robot.velocity == (0.0, 0.0)  # the robot stopped (command timeout)
        assert _call(sim, enable, SetBool.Request(data=True)).success
        assert sim.spin_until(lambda: sim.odo.cmd_count > cmds + 10, 20.0)
        # the progress stream shows the record growing again from the reset
        assert sim.spin_until(
            lambda: bool(progress) and 0 < ControlStrategy.parse(progress[-1]).length_m < 0.5,
            10.0)
    finally:
        sim.close()


def test_follower_holds_until_claimed_and_latches_each_completed_step(ros_context: Any) -> None:
    sim = make_sim(ros_context, 4, [_p("sim.lockstep", True)], [_p("autostart", False)])
    probe = Node("claim_probe", context=ros_context)
    sim.extra.append(probe)
    sim.executor.add_node(probe)
    strategies: list[str] = []
    progress: list[str] = []
    probe.create_subscription(String, "/hall_follower/strategy",
                              lambda m: strategies.append(m.data), LATCHED)
    probe.create_subscription(String, "/hall_follower/progress",
                              lambda m: progress.append(m.data), QOS)
    enable = probe.create_client(SetBool, "/hall_follower/enable")
    try:
        # unclaimed: a zero command per scan keeps the lockstep going, the robot stays put
        assert sim.spin_until(lambda: sim.odo.sim_time_ns >= 5 * 10**9, 30.0)
        assert sim.odo.robot.distance_m == 0.0 and sim.odo.lockstep_timeouts == 0
        assert sim.follower.scans_processed >= 50 and not sim.follower.claimed
        assert _call(sim, enable, SetBool.Request(data=True)).success
        assert sim.spin_until(lambda: sim.odo.sim_time_ns >= 120 * 10**9, 90.0)
        record = sim.follower.follower.strategy()
        assert sim.odo.robot.distance_m > 20.0 and len(record.steps) >= 3
        # latched on change of its steps only: one message per completed step (and the
        # empty record at start), each a prefix of the record; the progress on every change
        assert sim.spin_until(lambda: strategies[-1:] == [str(ControlStrategy(
            record.steps[:-1]))], 5.0), (strategies[-3:], str(record))
        assert len(strategies) <= len(record.steps) + 1
        for text in strategies:
            steps = ControlStrategy.parse(text).steps
            assert steps == record.steps[:len(steps)]
        assert len(progress) > 10 * len(strategies)
    finally:
        sim.close()


@pytest.mark.parametrize("cls", [OdometryNode, SonarNode, HallFollowerNode])
def test_config_yaml_lists_every_parameter_with_its_default(ros_context: Any, cls: type) -> None:
    node = cls(context=ros_context)
    try:
        data = yaml.safe_load((CONFIG_DIR / f"{node.get_name()}.yaml").read_text())
        params = data[node.get_name()]["ros__parameters"]

        def flat(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
            out: dict[str, Any] = {}
            for k, v in d.items():
                if isinstance(v, dict):
                    out.update(flat(v, f"{prefix}{k}."))
                else:
                    out[f"{prefix}{k}"] = v
            return out

        declared = {
            name: p.value for name, p in node._parameters.items()
            if name not in ("use_sim_time", "start_type_description_service")
        }
        assert flat(params) == declared
        assert all(node.describe_parameter(n).description for n in declared)
    finally:
        node.destroy_node()


def test_bad_parameters_fail_with_the_name(ros_context: Any) -> None:
    from island_sim.core.robot import RobotError
    from island_sim.core.world import WorldError
    from island_sim.nodes.odometry_node import OdometryNodeError

    with pytest.raises(WorldError, match="no_such_world"):
        OdometryNode(context=ros_context, parameter_overrides=[_p("world", "no_such_world")])
    with pytest.raises(OdometryNodeError, match="start_pose"):
        OdometryNode(context=ros_context, parameter_overrides=[_p("start_pose", "1,2")])
    with pytest.raises(RobotError, match="sensor_rate_hz"):
        OdometryNode(context=ros_context, parameter_overrides=[_p("sim.sensor_rate_hz", 7.0)])
    assert rclpy.ok(context=ros_context)
