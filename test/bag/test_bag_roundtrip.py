"""BagWriter output read back by two independent readers (rosbags, mcap) with equal values."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

N_STEPS = 20
SCAN_BEAMS = 16


def _messages(rng: np.random.Generator) -> list[tuple[str, Any]]:
    """A deterministic mixed stream: /clock, /scan, /odom, /chatter, /markers."""
    from geometry_msgs.msg import Point
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import String
    from visualization_msgs.msg import Marker, MarkerArray

    out: list[tuple[str, Any]] = []
    for i in range(N_STEPS):
        sec, nsec = 10 + i // 10, (i % 10) * 100_000_000
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = sec, nsec
        out.append(("/clock", clock))
        scan = LaserScan()
        scan.header.stamp.sec, scan.header.stamp.nanosec = sec, nsec + 1000
        scan.header.frame_id = "sonar_ring"
        scan.angle_min, scan.angle_increment = -math.pi, 2 * math.pi / SCAN_BEAMS
        scan.range_min, scan.range_max = 0.15, 6.5
        ranges = rng.uniform(0.2, 6.0, SCAN_BEAMS)
        ranges[i % SCAN_BEAMS] = math.inf
        scan.ranges = ranges.tolist()
        out.append(("/sonar/scan", scan))
        odom = Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nsec + 2000
        odom.header.frame_id, odom.child_frame_id = "odom", "base_link"
        odom.pose.pose.position.x = float(rng.normal())
        odom.pose.pose.orientation.z = float(rng.uniform(-1, 1))
        odom.pose.covariance = rng.uniform(0, 1, 36).tolist()
        out.append(("/odom", odom))
        out.append(("/chatter", String(data=f"step {i} 'quoted' é")))
        if i % 5 == 0:
            arr = MarkerArray()
            for k in range(3):
                mk = Marker()
                mk.ns, mk.id, mk.type = "islands", k, Marker.LINE_LIST
                mk.points = [Point(x=float(k), y=float(j), z=0.0) for j in range(4)]
                mk.scale.x = 0.05
                arr.markers.append(mk)
            out.append(("/islands/markers", arr))
    return out


def _write(path: Path, compression: str) -> list[tuple[str, Any]]:
    from island_mapping.bag.writer import BagWriter

    msgs = _messages(np.random.default_rng(7))
    with BagWriter(path, compression=compression, chunk_size=4096) as w:
        for topic, msg in msgs:
            w.write(topic, msg)
    return msgs


def _stamp_ns(topic: str, msg: Any, clock_ns: int) -> int:
    if topic == "/clock":
        return msg.clock.sec * 10**9 + msg.clock.nanosec
    if hasattr(msg, "header"):
        return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
    return clock_ns


def _expected(msgs: list[tuple[str, Any]]) -> list[tuple[str, int, Any]]:
    clock = 0
    out = []
    for topic, msg in msgs:
        t = _stamp_ns(topic, msg, clock)
        if topic == "/clock":
            clock = t
        out.append((topic, t, msg))
    return out


def _assert_same(topic: str, got: Any, want: Any) -> None:
    if topic == "/sonar/scan":
        np.testing.assert_allclose(np.asarray(got.ranges), np.asarray(want.ranges), rtol=1e-6)
        assert got.header.frame_id == want.header.frame_id
        assert got.range_max == pytest.approx(want.range_max, rel=1e-6)
        assert got.angle_increment == pytest.approx(want.angle_increment, rel=1e-6)
    elif topic == "/odom":
        assert got.pose.pose.position.x == want.pose.pose.position.x  # float64: exact
        np.testing.assert_array_equal(np.asarray(got.pose.covariance),
                                      np.asarray(want.pose.covariance))
        assert got.child_frame_id == want.child_frame_id
    elif topic == "/chatter":
        assert got.data == want.data
    elif topic == "/islands/markers":
        assert len(got.markers) == len(want.markers)
        for g, w in zip(got.markers, want.markers, strict=True):
            assert (g.ns, g.id, g.type) == (w.ns, w.id, w.type)
            assert [(p.x, p.y) for p in g.points] == [(p.x, p.y) for p in w.points]
    elif topic == "/clock":
        assert (got.clock.sec, got.clock.nanosec) == (want.clock.sec, want.clock.nanosec)


def _sort_key(item: tuple[str, int, Any]) -> tuple[int, str]:
    return item[1], item[0]


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_rosbags_reads_every_message_back_equal(tmp_path: Path, compression: str) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "run"
    want = sorted(_expected(_write(bag, compression)), key=_sort_key)
    store = get_typestore(Stores.ROS2_JAZZY)
    got: list[tuple[str, int, Any]] = []
    with Reader(bag) as reader:
        assert {c.topic for c in reader.connections} == {t for t, _, _ in want}
        for conn, t, raw in reader.messages():
            got.append((conn.topic, t, store.deserialize_cdr(raw, conn.msgtype)))
    got.sort(key=_sort_key)
    assert len(got) == len(want)
    for (gt, gtime, gmsg), (wt, wtime, wmsg) in zip(got, want, strict=True):
        assert (gt, gtime) == (wt, wtime)
        _assert_same(gt, gmsg, wmsg)
    # The bare .mcap (profile ros2) is readable by rosbags as well.
    with Reader(bag / "run_0.mcap") as reader:
        assert sum(1 for _ in reader.messages()) == len(want)


def test_mcap_reader_and_own_reader_agree(tmp_path: Path) -> None:
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.schema import message_class
    from mcap.reader import make_reader
    from rclpy.serialization import deserialize_message

    bag = tmp_path / "run"
    want = sorted(_expected(_write(bag, "zstd")), key=_sort_key)
    with (bag / "run_0.mcap").open("rb") as fh:
        reader = make_reader(fh)
        assert reader.get_header().profile == "ros2"
        got = []
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            assert schema.encoding == "ros2msg" and channel.message_encoding == "cdr"
            assert message.publish_time == message.log_time
            cls = message_class(schema.name)
            got.append((channel.topic, message.log_time, deserialize_message(message.data, cls)))
    got.sort(key=_sort_key)
    own = sorted(
        ((m.topic, m.log_time_ns, m.deserialize()) for m in open_bag(bag).messages()),
        key=_sort_key,
    )
    assert len(got) == len(own) == len(want)
    for g, o, w in zip(got, own, want, strict=True):
        assert g[:2] == o[:2] == w[:2]
        _assert_same(g[0], g[2], w[2])
        _assert_same(o[0], o[2], w[2])


def test_metadata_yaml_agrees_with_channels(tmp_path: Path) -> None:
    from island_mapping.bag.qos import qos_from_yaml
    from mcap.reader import make_reader

    bag = tmp_path / "run"
    msgs = _write(bag, "zstd")
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    assert (bag / "metadata.yaml").stat().st_mode & 0o777 == 0o644
    assert meta["relative_file_paths"] == ["run_0.mcap"]
    assert meta["message_count"] == len(msgs)
    with (bag / "run_0.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics is not None
    st = summary.statistics
    assert meta["starting_time"]["nanoseconds_since_epoch"] == st.message_start_time
    assert meta["duration"]["nanoseconds"] == st.message_end_time - st.message_start_time
    by_topic = {c.topic: (cid, c) for cid, c in summary.channels.items()}
    for entry in meta["topics_with_message_count"]:
        tm = entry["topic_metadata"]
        cid, channel = by_topic[tm["name"]]
        assert entry["message_count"] == st.channel_message_counts[cid]
        assert summary.schemas[channel.schema_id].name == tm["type"]
        assert qos_from_yaml(channel.metadata["offered_qos_profiles"]) == qos_from_yaml(
            tm["offered_qos_profiles"]
        )
        assert tm["type_description_hash"].startswith("RIHS01_")
        assert channel.metadata["topic_type_hash"] == tm["type_description_hash"]
    assert st.chunk_count > 1  # chunk_size 4096 forces several chunks


def test_schema_text_follows_rosbag2_concatenation() -> None:
    from island_mapping.bag.schema import SCHEMA_SEPARATOR, schema_text
    from rosbags.typesys import get_types_from_msg

    text = schema_text("nav_msgs/msg/Odometry")
    blocks = text.split(f"\n{SCHEMA_SEPARATOR}\nMSG: ")
    names = [b.split("\n", 1)[0] for b in blocks[1:]]
    assert len(names) == len(set(names))  # each dependency once
    assert "std_msgs/Header" in names and "builtin_interfaces/Time" in names
    assert "geometry_msgs/PoseWithCovariance" in names
    assert blocks[0].startswith("# This represents an estimate of a position and velocity")
    # An independent parser understands it.
    types = get_types_from_msg(text, "nav_msgs/msg/Odometry")
    assert "nav_msgs/msg/Odometry" in types
    assert "geometry_msgs/msg/TwistWithCovariance" in types


def test_bad_inputs_give_clear_errors(tmp_path: Path) -> None:
    from island_mapping.bag.errors import BagError, MessageTypeError
    from island_mapping.bag.schema import schema_text
    from island_mapping.bag.writer import BagWriter
    from std_msgs.msg import String

    with pytest.raises(MessageTypeError, match="no_such_pkg"):
        schema_text("no_such_pkg/msg/Foo")
    with pytest.raises(MessageTypeError, match="not of the form"):
        schema_text("LaserScan")
    with pytest.raises(BagError, match="compression"):
        BagWriter(tmp_path / "a", compression="gzip")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    with pytest.raises(BagError, match="not an empty directory"):
        BagWriter(tmp_path / "full")
    w = BagWriter(tmp_path / "b")
    w.write("/a", String(data="x"))
    with pytest.raises(BagError, match="recorded as std_msgs/msg/String"):
        w.add_topic("/a", "sensor_msgs/msg/LaserScan")
    with pytest.raises(BagError, match="must be absolute"):
        w.add_topic("relative", "std_msgs/msg/String")
    with pytest.raises(BagError, match="was not added"):
        w.write_raw("/nope", b"\x00\x01\x00\x00")
    w.close()
    with pytest.raises(BagError, match="closed"):
        w.write("/a", String(data="y"))


def test_importing_bag_readers_does_not_load_rclpy() -> None:
    code = (
        "import sys\n"
        "import island_mapping.bag.reader, island_mapping.bag.writer, "
        "island_mapping.bag.recover, island_mapping.bag.carmen, island_mapping.bag.text\n"
        "assert 'rclpy' not in sys.modules, 'rclpy was imported'\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True)
