"""recorder_node: parameters from RecorderConfig, the YAML config in sync, bad values rejected."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest
import yaml

CONFIG = Path(__file__).resolve().parents[2] / "src/island_mapping/config/recorder_node.yaml"


def test_config_yaml_lists_every_field_with_its_default() -> None:
    from island_mapping.bag.recorder import RecorderConfig

    params = yaml.safe_load(CONFIG.read_text())["recorder"]["ros__parameters"]["recorder"]
    default = RecorderConfig()
    fields = {f.name for f in dataclasses.fields(RecorderConfig)}
    assert set(params) == fields
    for name in fields:
        want = getattr(default, name)
        assert (tuple(params[name]) if isinstance(want, tuple) else params[name]) == want, name


def test_node_declares_parameters_and_records_chosen_topics(
    ros_context: Any, spin: Any, tmp_path: Path
) -> None:
    import rclpy
    from island_mapping.bag.reader import open_bag
    from island_mapping.nodes.recorder_node import RecorderNode
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from std_msgs.msg import String

    out = tmp_path / "chosen"
    node = RecorderNode(context=ros_context, parameter_overrides=[
        Parameter("output_dir", value=str(out)),
        Parameter("recorder.topics", value=["/wanted"]),
        Parameter("recorder.compression", value="lz4"),
        Parameter("recorder.rescan_period_s", value=0.1),
    ])
    assert node.config.topics == ("/wanted",) and node.config.compression == "lz4"
    assert node.describe_parameter("recorder.queue_depth").description.endswith("[messages]")
    pubs = rclpy.create_node("pubs", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex.add_node(pubs)
    wanted = pubs.create_publisher(String, "/wanted", 10)
    other = pubs.create_publisher(String, "/other", 10)
    try:
        assert spin(ex, lambda: node.recorder.matched_publishers().get("/wanted", 0) > 0, 10.0)
        wanted.publish(String(data="yes"))
        other.publish(String(data="no"))
        assert spin(ex, lambda: node.recorder.received == 1, 10.0)
    finally:
        node.close()
        ex.shutdown()
        pubs.destroy_node()
        node.destroy_node()
    bag = open_bag(out)
    assert list(bag.topics) == ["/wanted"]
    assert [m.deserialize().data for m in bag.messages()] == ["yes"]


def test_bad_parameters_fail_clearly(ros_context: Any, tmp_path: Path) -> None:
    from island_mapping.bag.errors import BagError
    from island_mapping.nodes.recorder_node import RecorderNode
    from rclpy.parameter import Parameter

    with pytest.raises(BagError, match="unknown compression 'gzip'"):
        RecorderNode(context=ros_context, parameter_overrides=[
            Parameter("output_dir", value=str(tmp_path / "a")),
            Parameter("recorder.compression", value="gzip")])
    with pytest.raises(BagError, match="must be absolute"):
        RecorderNode(context=ros_context, parameter_overrides=[
            Parameter("output_dir", value=str(tmp_path / "b")),
            Parameter("recorder.topics", value=["odom"])])
    (tmp_path / "taken").mkdir()
    (tmp_path / "taken" / "x").write_text("x")
    with pytest.raises(BagError, match="already exists"):
        RecorderNode(context=ros_context, parameter_overrides=[
            Parameter("output_dir", value=str(tmp_path / "taken"))])


def test_sigterm_closes_the_bag_cleanly(tmp_path: Path) -> None:
    import signal
    import subprocess
    import sys
    import threading

    out = tmp_path / "term"
    proc = subprocess.Popen(
        [sys.executable, "-m", "island_mapping.nodes.recorder_node", "--ros-args",
         "-p", f"output_dir:={out}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    ready = threading.Event()

    def read_stderr() -> None:
        assert proc.stderr is not None
        for line in proc.stderr:
            lines.append(line)
            if "recording" in line:  # logged when the node is fully built
                ready.set()

    reader = threading.Thread(target=read_stderr, daemon=True)
    reader.start()
    try:
        assert ready.wait(30), f"recorder did not start: {''.join(lines)}"
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)
        reader.join(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    err = "".join(lines)
    assert proc.returncode == 0, err
    assert "closed" in err
    meta = yaml.safe_load((out / "metadata.yaml").read_text())
    assert meta["rosbag2_bagfile_information"]["relative_file_paths"] == ["term_0.mcap"]
