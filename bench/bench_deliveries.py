"""What one message delivery costs in-process on rclpy's events executor (issue 16, speed).

  python bench/bench_deliveries.py [--messages 5000]

One publisher node and 1 or 5 subscriber nodes on one events executor, as `islands explore`
runs them; each message is published and the executor spun until every subscriber has it, as
in lockstep. Variants side by side: nav_msgs/Odometry delivered typed (rclpy builds the message
objects) or raw (the serialized bytes, which `island_msgs_py.cdr` reads), and
rosgraph_msgs/Clock typed (what every sim-time node's time source subscribes). Printed: wall
microseconds per delivery and per publication, and the 1-minute load average.
"""

from __future__ import annotations

import argparse
import os
import random
import time
from typing import Any

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock

QOS = QoSProfile(depth=100)
MATCH_WAIT_S = 5.0


def per_delivery_us(cls: Any, subscribers: int, raw: bool, messages: int) -> tuple[float, float]:
    """(wall us per delivery, wall us per publication)."""
    ctx = Context()
    rclpy.init(context=ctx, domain_id=random.SystemRandom().randint(120, 200))
    pub_node = Node("bench_pub", context=ctx)
    pub = pub_node.create_publisher(cls, "bench_topic", QOS)
    got = [0]

    def on_message(_msg: Any) -> None:
        got[0] += 1

    subs = [Node(f"bench_sub{i}", context=ctx) for i in range(subscribers)]
    for s in subs:
        s.create_subscription(cls, "bench_topic", on_message, QOS, raw=raw)
    ex = EventsExecutor(context=ctx)
    for n in (pub_node, *subs):
        ex.add_node(n)
    deadline = time.monotonic() + MATCH_WAIT_S
    while time.monotonic() < deadline and pub.get_subscription_count() < subscribers:
        ex.spin_once(timeout_sec=0.05)
    msg = cls()
    t0 = time.monotonic()
    for sent in range(1, messages + 1):
        pub.publish(msg)
        while got[0] < sent * subscribers:
            ex.spin_once(timeout_sec=0.1)
    wall = time.monotonic() - t0
    ex.shutdown()
    for n in (pub_node, *subs):
        n.destroy_node()
    ctx.try_shutdown()
    return wall / (messages * subscribers) * 1e6, wall / messages * 1e6


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--messages", type=int, default=5000)
    a = p.parse_args()
    print(f"one delivery on the events executor, {a.messages} messages, {os.cpu_count()} cores")
    print(f"{'message':10s} {'delivered':9s} {'subs':>4s} {'us/delivery':>12s} "
          f"{'us/publish':>11s} {'load':>5s}")
    for cls, raw in ((Odometry, False), (Odometry, True), (Clock, False)):
        for n in (1, 5):
            each, per_pub = per_delivery_us(cls, n, raw, a.messages)
            print(f"{cls.__name__:10s} {'raw' if raw else 'typed':9s} {n:4d} {each:12.1f} "
                  f"{per_pub:11.1f} {os.getloadavg()[0]:5.2f}", flush=True)


if __name__ == "__main__":
    main()
