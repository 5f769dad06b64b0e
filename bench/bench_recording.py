"""Recording throughput (messages/s and MB/s) against serialization alone, in one run.

  python bench/bench_recording.py [--seconds S] [--compression zstd|lz4|none]

Workload: the project's run mix per simulated second: 10 sonar scans (LaserScan, 16 beams),
50 odometry messages (nav_msgs/Odometry with covariance), 50 /clock and 10 180-beam laser
scans (the CARMEN import), seeded random values. Measured side by side on the same messages:
- serialize: rclpy serialize_message only (the floor any recorder pays for typed messages);
- write typed: BagWriter.write (serialize + stamp + chunk + compress + write);
- write raw: BagWriter.write_raw of pre-serialized CDR (what RunRecorder does with raw=True
  subscriptions: no deserialization, no serialization);
- live: an in-process publisher -> RunRecorder raw subscription -> disk, one executor, the
  end-to-end rate of the library `islands explore` uses (DDS delivery included).
MB/s counts CDR payload bytes; the file size shows the compression.
"""

from __future__ import annotations

import argparse
import math
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

LIVE_BATCH = 200
"""Messages published before the recorder must catch up (below its queue depth of 1000)."""


def make_messages(sim_seconds: int, rng: np.random.Generator) -> list[tuple[str, Any]]:
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import LaserScan

    out: list[tuple[str, Any]] = []
    for k in range(sim_seconds * 50):
        t_ns = k * 20_000_000
        sec, nsec = divmod(t_ns, 10**9)
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = sec, nsec
        out.append(("/clock", clock))
        odom = Odometry()
        odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nsec
        odom.header.frame_id, odom.child_frame_id = "odom", "base_link"
        odom.pose.pose.position.x = float(rng.normal())
        odom.pose.covariance = rng.uniform(0, 1e-3, 36).tolist()
        out.append(("/odom", odom))
        if k % 5 == 0:
            for topic, beams in (("/sonar/scan", 16), ("/scan", 180)):
                scan = LaserScan()
                scan.header.stamp.sec, scan.header.stamp.nanosec = sec, nsec
                scan.header.frame_id = "base"
                scan.angle_increment = 2 * math.pi / beams
                scan.ranges = rng.uniform(0.2, 6.5, beams).astype(np.float32).tolist()
                out.append((topic, scan))
    return out


def _rate(n: int, nbytes: int, seconds: float) -> str:
    return f"{n / seconds:10.0f} msg/s  {nbytes / seconds / 1e6:8.1f} MB/s  ({seconds:.3f} s)"


def bench_offline(msgs: list[tuple[str, Any]], compression: str, tmp: Path) -> None:
    from island_mapping.bag.writer import BagWriter
    from rclpy.serialization import serialize_message

    t0 = time.perf_counter()
    raw = [(topic, serialize_message(m)) for topic, m in msgs]
    t_ser = time.perf_counter() - t0
    nbytes = sum(len(b) for _, b in raw)

    t0 = time.perf_counter()
    with BagWriter(tmp / "typed", compression=compression) as w:
        for topic, m in msgs:
            w.write(topic, m)
    t_typed = time.perf_counter() - t0

    t0 = time.perf_counter()
    with BagWriter(tmp / "raw", compression=compression) as w:
        for topic, m in msgs[:5]:
            w.add_topic(topic, type(m).__module__.split(".")[0] + "/msg/" + type(m).__name__)
        for topic, data in raw:
            if topic not in w.topics:
                continue
            w.write_raw(topic, data)
    t_raw = time.perf_counter() - t0
    size = (tmp / "raw" / "raw_0.mcap").stat().st_size

    n = len(msgs)
    print(f"messages: {n}, CDR payload {nbytes / 1e6:.2f} MB, file {size / 1e6:.2f} MB "
          f"({compression}, ratio {nbytes / size:.1f}x)")
    print(f"serialize only : {_rate(n, nbytes, t_ser)}")
    print(f"write typed    : {_rate(n, nbytes, t_typed)}   = {t_ser / t_typed:.2f} x serialize")
    print(f"write raw      : {_rate(n, nbytes, t_raw)}   = {t_ser / t_raw:.2f} x serialize")


def bench_live(msgs: list[tuple[str, Any]], compression: str, tmp: Path) -> None:
    import rclpy
    from island_mapping.bag.recorder import RecorderConfig, RunRecorder
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    ctx = Context()
    rclpy.init(context=ctx)
    pub_node = rclpy.create_node("bench_pub", context=ctx)
    rec_node = rclpy.create_node("bench_rec", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(pub_node)
    ex.add_node(rec_node)
    pubs = {}
    for topic, m in msgs[:5]:
        pubs.setdefault(topic, pub_node.create_publisher(type(m), topic, 1000))
    recorder = RunRecorder(rec_node, tmp / "live",
                           config=RecorderConfig(compression=compression, rescan_period_s=0.1))
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and (
        len(recorder.recorded_topics) < len(pubs)
        or min(recorder.matched_publishers().values(), default=0) == 0
    ):
        ex.spin_once(timeout_sec=0.05)
    from rclpy.serialization import serialize_message

    nbytes = sum(len(serialize_message(m)) for _, m in msgs)
    t0 = time.perf_counter()
    # Publish in batches smaller than the subscription queues and let the recorder catch up
    # after each: the sustained rate at which nothing is lost.
    for start in range(0, len(msgs), LIVE_BATCH):
        for topic, m in msgs[start : start + LIVE_BATCH]:
            pubs[topic].publish(m)
        target = min(start + LIVE_BATCH, len(msgs))
        stall = time.perf_counter() + 5.0
        while recorder.received < target and time.perf_counter() < stall:
            ex.spin_once(timeout_sec=0.01)
    elapsed = time.perf_counter() - t0
    got = recorder.received
    recorder.close()
    ex.shutdown()
    pub_node.destroy_node()
    rec_node.destroy_node()
    ctx.try_shutdown()
    print(f"live recorder  : {_rate(got, nbytes * got // len(msgs), elapsed)}   "
          f"{got}/{len(msgs)} recorded (publish + DDS + raw subscription + write)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=int, default=60, help="simulated seconds of traffic")
    parser.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"))
    args = parser.parse_args()
    msgs = make_messages(args.seconds, np.random.default_rng(1))
    tmp = Path(tempfile.mkdtemp(prefix="bench_recording_"))
    try:
        bench_offline(msgs, args.compression, tmp)
        bench_live(msgs, args.compression, tmp)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
