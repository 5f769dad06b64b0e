"""The committed example run in bags/example_run: listed, complete, readable by rosbags."""

from __future__ import annotations

from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[2] / "bags" / "example_run"
MAX_BYTES = 3 * 1024 * 1024  # keep the repository small


def test_bag_info_lists_sonar_and_odom(capsys: pytest.CaptureFixture[str]) -> None:
    from island_mapping.cli import main

    assert main(["bag", "info", str(EXAMPLE)]) == 0
    out = capsys.readouterr().out
    topics = {line.split()[0]: line.split()[1] for line in out.splitlines()
              if line.startswith("  /")}
    assert topics["/sonar/scan"] == "sensor_msgs/msg/LaserScan"
    assert topics["/odom"] == "nav_msgs/msg/Odometry"
    assert "/clock" in topics and "/topo_graph/json" in topics
    assert sum(f.stat().st_size for f in EXAMPLE.iterdir()) < MAX_BYTES


def test_example_run_is_complete_sim_time_and_rosbags_readable() -> None:
    from island_mapping.bag.reader import open_bag
    from rosbags.rosbag2 import Reader

    bag = open_bag(EXAMPLE)
    seconds = bag.duration_ns / 1e9
    assert 60 <= seconds <= 300 and bag.start_ns == 0  # sim time from 0, not wall time
    # Every sim instant is there: /clock and /odom at 50 Hz, sonar at 10 Hz.
    assert bag.topics["/clock"].message_count == round(seconds * 50) + 1
    assert bag.topics["/odom"].message_count == round(seconds * 50) + 1
    assert bag.topics["/sonar/scan"].message_count == round(seconds * 10) + 1
    with Reader(EXAMPLE) as reader:
        assert sum(1 for _ in reader.messages()) == bag.message_count
