"""The three simulator nodes as separate processes (as `ros2 run` starts them) with their YAMLs."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from island_msgs_py.types import ControlStrategy
from island_sim.nodes.hall_follower_node import LATCHED
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import String

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "src" / "island_sim" / "config"
NODES = ("odometry_node", "sonar_node", "hall_follower_node")


def _exe(name: str) -> str:
    exe = Path(sys.executable).parent / name
    if not exe.exists():
        pytest.skip(f"console script {name} is not installed (run scripts/setup.sh)")
    return str(exe)


def test_nodes_in_separate_processes_drive_the_robot(ros_context: Any) -> None:
    sim_time = ["-p", "use_sim_time:=true"]
    extra = {
        "odometry_node": ["-p", "sim.real_time_factor:=4.0", "-p", "seed:=5"],
        "sonar_node": sim_time,
        "hall_follower_node": [*sim_time, "-p", "autostart:=true"],
    }
    procs = [
        subprocess.Popen(
            [_exe(n), "--ros-args", "--params-file", str(CONFIG / f"{n}.yaml"), *extra[n]],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=os.environ.copy(),
        )
        for n in NODES
    ]
    probe = Node("process_probe", context=ros_context)
    odom: list[Odometry] = []
    strategy: list[str] = []
    probe.create_subscription(Odometry, "/odom", odom.append, QoSProfile(depth=100))
    probe.create_subscription(String, "/hall_follower/strategy",
                              lambda m: strategy.append(m.data), LATCHED)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(probe)
    try:
        deadline = time.monotonic() + 40.0
        moved = False
        while time.monotonic() < deadline and not (moved and odom):
            ex.spin_once(timeout_sec=0.1)
            moved = bool(strategy) and ControlStrategy.parse(strategy[-1]).length_m > 2.0
            assert all(p.poll() is None for p in procs), "a node exited early"
        assert moved, f"robot did not drive 2 m; strategy {strategy[-1:]}"
        assert odom and odom[-1].header.frame_id == "odom"
        assert odom[-1].pose.covariance[0] > 0.0  # the propagated covariance is on the wire
    finally:
        ex.shutdown()
        probe.destroy_node()
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        outputs = []
        for p in procs:
            try:
                out, _ = p.communicate(timeout=10.0)
            except subprocess.TimeoutExpired:  # hung: have it print its stacks, then kill it
                p.send_signal(signal.SIGUSR1)
                time.sleep(1.0)
                p.kill()
                out, _ = p.communicate()
            outputs.append(out)
    for name, p, out in zip(NODES, procs, outputs, strict=True):
        assert p.returncode == 0, f"{name} exited with {p.returncode}:\n{out[-2000:]}"
        assert "Traceback" not in out, f"{name}:\n{out[-2000:]}"
