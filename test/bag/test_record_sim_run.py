"""Record the three simulator nodes in-process with RunRecorder; read back with rosbags.

Also the recipe of the committed example run when `islands explore` is not used (see
docs/recording.md): sim nodes in lockstep on sim time, the recorder subscribed before the
first step so that nothing is missed.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

SIM_S = 12.0
SENSOR_HZ = 10
PUBLISH_HZ = 50
RECORDED = ("/sonar/scan", "/odom", "/ground_truth", "/clock", "/cmd_vel",
            "/hall_follower/strategy")


def record_sim_run(ctx: Any, out_dir: Path, sim_s: float, seed: int = 0,
                   world: str = "paper_fig4", timeout_s: float = 120.0) -> Path:
    """Run odometry, sonar and hall follower nodes for `sim_s` and record every topic."""
    import rclpy
    from island_mapping.bag.recorder import RecorderConfig, RunRecorder
    from island_sim.nodes.hall_follower_node import HallFollowerNode
    from island_sim.nodes.odometry_node import OdometryNode
    from island_sim.nodes.sonar_node import SonarNode
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    def p(name: str, value: Any) -> Parameter:
        return Parameter(name, value=value)

    sim_time = [p("use_sim_time", True)]
    odo = OdometryNode(context=ctx, parameter_overrides=[
        p("world", world), p("seed", seed), p("sim.real_time_factor", 0.0),
        p("sim.lockstep", True), p("sim.stop_after_s", sim_s)])
    sonar = SonarNode(context=ctx, parameter_overrides=[
        *sim_time, p("world", world), p("seed", seed + 1)])
    # no mapper claims the robot here: the follower drives at once
    follower = HallFollowerNode(context=ctx,
                                parameter_overrides=[*sim_time, p("autostart", True)])
    rec_node = rclpy.create_node("recorder", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(rec_node)
    recorder = RunRecorder(rec_node, out_dir, config=RecorderConfig(rescan_period_s=0.1))
    try:
        # Subscribe before the simulation takes its first step (its nodes are not spun yet).
        deadline = time.monotonic() + 20.0
        while any(recorder.matched_publishers().get(t, 0) == 0 for t in RECORDED):
            assert time.monotonic() < deadline, recorder.matched_publishers()
            ex.spin_once(timeout_sec=0.05)
        for n in (odo, sonar, follower):
            ex.add_node(n)
        last_scan = round(sim_s * SENSOR_HZ) + 1
        deadline = time.monotonic() + timeout_s
        while not (odo.finished and follower.scans_processed >= last_scan):
            assert time.monotonic() < deadline, "simulation stalled"
            ex.spin_once(timeout_sec=0.05)
        end = time.monotonic() + 0.5  # let the recorder drain its queues
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.01)
    finally:
        path = recorder.close()
        ex.shutdown()
        for n in (odo, sonar, follower, rec_node):
            n.destroy_node()
    return path


@pytest.mark.slow
def test_recorded_sim_run_is_complete_and_readable(ros_context: Any, tmp_path: Path) -> None:
    from island_mapping.bag.reader import open_bag
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    pytest.importorskip("island_sim.nodes.odometry_node")
    path = record_sim_run(ros_context, tmp_path / "sim_run", SIM_S)
    bag = open_bag(path)
    for topic in RECORDED:
        assert topic in bag.topics, sorted(bag.topics)
    n_scans = round(SIM_S * SENSOR_HZ) + 1
    assert bag.topics["/sonar/scan"].message_count == n_scans
    assert bag.topics["/odom"].message_count == round(SIM_S * PUBLISH_HZ) + 1
    assert bag.topics["/clock"].message_count == bag.topics["/odom"].message_count
    scans = list(bag.messages(["/sonar/scan"]))
    assert [m.log_time_ns for m in scans] == [k * 10**9 // SENSOR_HZ for k in range(n_scans)]
    first = scans[0].deserialize()
    assert len(first.ranges) == 16 and first.header.frame_id
    # Stamp-less /cmd_vel carries sim time (never wall time), within the run.
    cmd_times = [m.log_time_ns for m in bag.messages(["/cmd_vel"])]
    assert cmd_times and max(cmd_times) <= SIM_S * 1e9
    # The strategy topic is latched and a standard type.
    assert bag.topics["/hall_follower/strategy"].type_name == "std_msgs/msg/String"
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(path) as reader:
        counts: dict[str, int] = {}
        for conn, _, raw in reader.messages():
            store.deserialize_cdr(raw, conn.msgtype)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
    assert counts == {t: i.message_count for t, i in bag.topics.items()}
