"""`islands bag info` and `islands bag echo` output on a small known bag."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml


@pytest.fixture
def small_bag(tmp_path: Path) -> Path:
    from island_mapping.bag.writer import BagWriter
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import String

    path = tmp_path / "small"
    with BagWriter(path) as w:
        for i in range(5):
            scan = LaserScan()
            scan.header.stamp.sec = 10 + i
            scan.header.frame_id = "sonar_ring"
            scan.ranges = [0.1 * k for k in range(50)]
            scan.range_max = float("inf")
            w.write("/sonar/scan", scan)
            odom = Odometry()
            odom.header.stamp.sec, odom.header.stamp.nanosec = 10 + i, 500_000_000
            odom.pose.pose.position.x = 1.5 * i
            w.write("/odom", odom)
        w.write("/note", String(data="it's done: yes"))
    return path


def test_info_lists_topics_types_counts_and_times(small_bag: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    from island_mapping.cli import main

    assert main(["bag", "info", str(small_bag)]) == 0
    out = capsys.readouterr().out
    assert "Messages:          11" in out
    assert "Duration:          4.500000000 s" in out
    assert "Start:             10.000000000 s" in out
    assert "End:               14.500000000 s" in out
    lines = {line.split()[0]: line.split() for line in out.splitlines() if line.startswith("  /")}
    assert lines["/sonar/scan"][1:3] == ["sensor_msgs/msg/LaserScan", "5"]
    assert lines["/odom"][1:3] == ["nav_msgs/msg/Odometry", "5"]
    assert lines["/note"][1:3] == ["std_msgs/msg/String", "1"]
    # The bare file gives the same answer.
    assert main(["bag", "info", str(small_bag / "small_0.mcap")]) == 0
    assert "Messages:          11" in capsys.readouterr().out


def test_echo_prints_yaml_like_text_with_limit(small_bag: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    from island_mapping.cli import main

    assert main(["bag", "echo", str(small_bag), "--topic", "/odom", "--limit", "2"]) == 0
    docs = [d for d in capsys.readouterr().out.split("---\n") if d.strip()]
    assert len(docs) == 2
    parsed = [yaml.safe_load(d) for d in docs]
    assert parsed[1]["pose"]["pose"]["position"]["x"] == 1.5
    assert parsed[1]["header"]["stamp"] == {"sec": 11, "nanosec": 500000000}
    assert len(parsed[0]["pose"]["covariance"]) == 36
    assert main(["bag", "echo", str(small_bag), "--topic", "/sonar/scan", "--limit", "1"]) == 0
    out = capsys.readouterr().out
    assert "range_max: .inf" in out and "# 50 items, first 36 shown" in out
    scan = yaml.safe_load(out.split("---")[0])
    assert scan["ranges"][:3] == [0.0, 0.1, 0.2] and scan["ranges"][-1] == "..."
    assert scan["header"]["frame_id"] == "sonar_ring"
    assert main(["bag", "echo", str(small_bag), "--topic", "/note"]) == 0
    assert yaml.safe_load(capsys.readouterr().out.split("---")[0]) == {"data": "it's done: yes"}


def test_bad_topic_and_path_exit_2(small_bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from island_mapping.cli import main

    assert main(["bag", "echo", str(small_bag), "--topic", "/missing"]) == 2
    err = capsys.readouterr().err
    assert "no topic /missing" in err and "/odom" in err
    assert main(["bag", "info", str(small_bag.parent / "nothing_here")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_play_subprocess_publishes_with_clock(
    small_bag: Path, ros_context: object, spin: object
) -> None:
    import subprocess
    import sys

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan

    node = rclpy.create_node("play_listener", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    scans: list[int] = []
    clocks: list[int] = []
    node.create_subscription(LaserScan, "/sonar/scan",
                             lambda m: scans.append(m.header.stamp.sec), 50)
    node.create_subscription(Clock, "/clock", lambda m: clocks.append(m.clock.sec), 50)
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys; from island_mapping.cli import main; sys.exit(main())",
         "bag", "play", str(small_bag),
         "--rate", "4", "--wait-for", "/sonar/scan", "/clock"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        assert spin(ex, lambda: proc.poll() is not None, 60.0)  # type: ignore[operator]
        spin(ex, lambda: len(scans) == 5, 2.0)  # type: ignore[operator]
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
        ex.shutdown()
        node.destroy_node()
    assert proc.returncode == 0, err
    assert "published 11 messages" in out
    # The player waited for our subscriptions: every scan arrives, in recorded order, with /clock.
    assert scans == [10, 11, 12, 13, 14]
    assert clocks and clocks == sorted(clocks)
