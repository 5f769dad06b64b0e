"""RunRecorder in-process, recorder_node killed with SIGKILL, truncated and corrupted files."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

N_MSGS = 60


def _odom(i: int) -> Any:
    from nav_msgs.msg import Odometry

    m = Odometry()
    m.header.stamp.sec, m.header.stamp.nanosec = 100 + i // 10, (i % 10) * 100_000_000
    m.header.frame_id = "odom"
    m.pose.pose.position.x = 0.25 * i
    return m


def test_run_recorder_records_latched_typed_and_stampless_topics(
    ros_context: Any, spin: Callable[..., bool], tmp_path: Path
) -> None:
    import rclpy
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.recorder import RecorderConfig, RunRecorder
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String

    pub_node = rclpy.create_node("pubs", context=ros_context)
    # On sim time, with no /clock yet: the recorder's rescan timer runs on the steady clock.
    rec_node = rclpy.create_node("rec", context=ros_context,
                                 parameter_overrides=[Parameter("use_sim_time", value=True)])
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(pub_node)
    ex.add_node(rec_node)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                         reliability=ReliabilityPolicy.RELIABLE)
    graph_pub = pub_node.create_publisher(String, "/graph_json", latched)
    odom_pub = pub_node.create_publisher(Odometry, "/odom", 50)
    clock_pub = pub_node.create_publisher(Clock, "/clock", 10)
    chat_pub = pub_node.create_publisher(String, "/chatter", 50)
    graph_pub.publish(String(data='{"islands": []}'))  # before the recorder exists: latched
    recorder = RunRecorder(rec_node, tmp_path / "run",
                           config=RecorderConfig(rescan_period_s=0.1, flush_period_s=0.1))
    pub_node.create_publisher(String, "/late", 10)  # created after the recorder first scanned
    try:
        assert spin(ex, lambda: len(recorder.recorded_topics) >= 5, 10.0), \
            recorder.recorded_topics
        assert "/late" in recorder.recorded_topics
        assert spin(ex, lambda: min(recorder.matched_publishers().values()) > 0, 10.0)
        for i in range(N_MSGS):
            clock = Clock()
            clock.clock.sec, clock.clock.nanosec = 100 + i // 10, (i % 10) * 100_000_000
            clock_pub.publish(clock)
            ex.spin_once(timeout_sec=0)
            odom_pub.publish(_odom(i))
            chat_pub.publish(String(data=f"m{i}"))
            ex.spin_once(timeout_sec=0)
        assert spin(ex, lambda: recorder.received >= 3 * N_MSGS + 1, 10.0), {
            t: r.message_count for t, r in recorder.writer.topics.items()}
    finally:
        path = recorder.close()
        ex.shutdown()
        pub_node.destroy_node()
        rec_node.destroy_node()
    bag = open_bag(path)
    assert "/rosout" not in bag.topics and "/parameter_events" not in bag.topics
    assert bag.topics["/graph_json"].message_count == 1
    assert bag.topics["/graph_json"].qos_profiles[0]["durability"] == "transient_local"
    assert bag.topics["/odom"].message_count == N_MSGS
    odoms = [m for m in bag.messages(["/odom"])]
    assert [m.deserialize().pose.pose.position.x for m in odoms] == [
        0.25 * i for i in range(N_MSGS)
    ]
    assert odoms[3].log_time_ns == 100 * 10**9 + 300_000_000  # header stamp = log time
    # Stamp-less messages carry the sim time of the latest /clock (never wall time).
    chats = list(bag.messages(["/chatter"]))
    assert len(chats) == N_MSGS
    assert all(100 * 10**9 <= m.log_time_ns <= 106 * 10**9 for m in chats)


def _recorder_cmd(out: Path) -> list[str]:
    return [
        sys.executable, "-m", "island_mapping.nodes.recorder_node", "--ros-args",
        "-p", f"output_dir:={out}", "-p", "recorder.flush_period_s:=0.1",
        "-p", "recorder.rescan_period_s:=0.1", "-p", "recorder.topics:=['/odom']",
    ]


def test_recover_after_sigkill_of_recorder_node(
    ros_context: Any, spin: Callable[..., bool], tmp_path: Path
) -> None:
    import rclpy
    from island_mapping.bag.errors import BagCorruptError
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.recover import scan_mcap
    from island_mapping.cli import main
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor

    out = tmp_path / "killed"
    proc = subprocess.Popen(_recorder_cmd(out), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    node = rclpy.create_node("odom_pub", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    pub = node.create_publisher(Odometry, "/odom", 100)
    try:
        assert spin(ex, lambda: pub.get_subscription_count() > 0, 30.0), "recorder not seen"
        for i in range(N_MSGS):
            pub.publish(_odom(i))
            ex.spin_once(timeout_sec=0.001)
        mcap_file = out / "killed_0.mcap"

        def all_on_disk() -> bool:
            return mcap_file.is_file() and len(scan_mcap(mcap_file).messages) >= N_MSGS

        assert spin(ex, all_on_disk, 20.0), "recorder never flushed the messages"
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        ex.shutdown()
        node.destroy_node()
    assert not (out / "metadata.yaml").exists()  # killed: no metadata, no summary
    with pytest.raises(BagCorruptError, match=r"killed_0\.mcap.*interrupted recording"):
        open_bag(mcap_file)
    fixed = tmp_path / "fixed"
    assert main(["bag", "recover", str(mcap_file), "--out", str(fixed)]) == 0
    bag = open_bag(fixed)
    assert (fixed / "metadata.yaml").is_file()
    xs = [m.deserialize().pose.pose.position.x for m in bag.messages(["/odom"])]
    assert xs == [0.25 * i for i in range(N_MSGS)]


def _make_bag(path: Path, n: int = 400) -> None:
    from island_mapping.bag.writer import BagWriter, WriterConfig

    with BagWriter(path, config=WriterConfig(chunk_size_bytes=8192)) as w:
        for i in range(n):
            w.write("/odom", _odom(i))


def test_truncated_file_clear_error_and_intact_part_readable(tmp_path: Path,
                                                             capsys: Any) -> None:
    from island_mapping.bag.errors import BagCorruptError
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.recover import recover_bag
    from island_mapping.cli import main

    _make_bag(tmp_path / "ok")
    src = tmp_path / "ok" / "ok_0.mcap"
    data = src.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])  # mid-chunk, no summary
    with pytest.raises(BagCorruptError) as info:
        open_bag(cut)
    err = info.value
    assert err.path == str(cut) and 0 < err.offset < len(data) // 2
    assert "truncated" in str(err) and str(err.offset) in str(err)
    assert main(["bag", "info", str(cut)]) == 2
    assert f"byte offset {err.offset}" in capsys.readouterr().err
    intact = open_bag(cut, allow_damaged=True)
    xs = [m.deserialize().pose.pose.position.x for m in intact.messages()]
    assert len(xs) == err.intact_messages > 50
    assert xs == [0.25 * i for i in range(len(xs))]  # a prefix of what was written
    rep = recover_bag(cut, tmp_path / "rec")
    assert rep.messages == len(xs) and not rep.complete
    assert open_bag(tmp_path / "rec").message_count == len(xs)


def test_corrupted_chunk_is_located_and_skipped(tmp_path: Path) -> None:
    from island_mapping.bag.errors import BagCorruptError
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.recover import recover_bag, scan_mcap
    from mcap.reader import make_reader

    _make_bag(tmp_path / "ok")
    src = tmp_path / "ok" / "ok_0.mcap"
    with src.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and len(summary.chunk_indexes) >= 4
    victim = summary.chunk_indexes[1]
    data = bytearray(src.read_bytes())
    for k in range(40):  # scribble over the compressed payload of the second chunk
        data[victim.chunk_start_offset + victim.chunk_length - 60 + k] ^= 0xA5
    bad_dir = tmp_path / "bad"
    shutil.copytree(tmp_path / "ok", bad_dir)
    (bad_dir / "ok_0.mcap").write_bytes(bytes(data))
    with pytest.raises(BagCorruptError) as info:
        list(open_bag(bad_dir).messages())
    assert info.value.offset == victim.chunk_start_offset
    assert "corrupted Chunk" in str(info.value)
    scan = scan_mcap(bad_dir / "ok_0.mcap")
    assert scan.complete and [d.offset for d in scan.damages] == [victim.chunk_start_offset]
    lost = {i for i in range(400)}
    got = [m.deserialize().pose.pose.position.x for m in
           open_bag(bad_dir, allow_damaged=True).messages()]
    assert 0 < len(got) < 400
    first_chunk = [round(x / 0.25) for x in got]
    assert first_chunk == sorted(first_chunk) and first_chunk[0] == 0
    rep = recover_bag(bad_dir, tmp_path / "rec")
    assert 0 < rep.messages < 400 and rep.complete
    lost -= {round(m.deserialize().pose.pose.position.x / 0.25)
             for m in open_bag(tmp_path / "rec").messages()}
    # Exactly the messages of the damaged chunk are lost, and they are contiguous.
    assert lost and max(lost) - min(lost) + 1 == len(lost)


def test_not_an_mcap_file(tmp_path: Path) -> None:
    from island_mapping.bag.errors import BagCorruptError, BagError
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.recover import recover_bag

    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"hello world, not mcap at all")
    with pytest.raises(BagCorruptError, match="bad magic"):
        open_bag(junk)
    with pytest.raises(BagError, match="nothing to recover"):
        recover_bag(junk, tmp_path / "o")


@pytest.mark.parametrize("clock_publisher", [True, False])
def test_stampless_message_before_first_clock(
    ros_context: Any, spin: Callable[..., bool], tmp_path: Path, clock_publisher: bool
) -> None:
    import rclpy
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.recorder import RecorderConfig, RunRecorder
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from std_msgs.msg import String

    pubs = rclpy.create_node("pubs", context=ros_context)
    rec = rclpy.create_node("rec", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(pubs)
    ex.add_node(rec)
    if clock_publisher:
        pubs.create_publisher(Clock, "/clock", 10)  # a sim-time graph whose clock has not ticked
    note = pubs.create_publisher(String, "/note", 10)
    recorder = RunRecorder(rec, tmp_path / "b", topics=["/note"],
                           config=RecorderConfig(rescan_period_s=0.1))
    wall_before = time.time_ns()
    try:
        assert spin(ex, lambda: recorder.matched_publishers().get("/note", 0) > 0, 10.0)
        note.publish(String(data="early"))
        assert spin(ex, lambda: recorder.received == 1, 10.0)
    finally:
        recorder.close()
        ex.shutdown()
        pubs.destroy_node()
        rec.destroy_node()
    (msg,) = list(open_bag(tmp_path / "b").messages())
    if clock_publisher:
        assert msg.log_time_ns == 0  # sim time before the first clock, never wall time
    else:
        assert msg.log_time_ns >= wall_before  # no clock anywhere: wall time
