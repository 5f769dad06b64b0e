"""`islands topic`: live topics on a machine without ros2cli.

  islands topic list [--wait S]                       names and types, like `ros2 topic list -t`
  islands topic echo T [--limit N] [--timeout S]      messages as YAML-like text (`---` between)

Both run a temporary node in their own rclpy context. `echo` waits for a publisher to learn the
type, then subscribes with QoS adapted to the publishers (latched topics deliver their last
message) and prints with the same function as `islands bag echo`.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from island_mapping.bag.errors import BagError
from island_mapping.cli import CliError
from island_mapping.cli.args import COUNT, SECONDS

DISCOVERY_WAIT_S = 2.0
"""Default wait for DDS discovery before listing (loopback: 0.02-0.25 s, up to ~3 s when the
first announcements are missed on a loaded machine) [s]."""
SPIN_STEP_S = 0.05


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="topic_command", required=True, metavar="ACTION")
    p = sub.add_parser("list", help="topic names and types")
    p.add_argument("--wait", type=SECONDS, default=DISCOVERY_WAIT_S,
                   help="seconds to wait for discovery [s]")
    p = sub.add_parser("echo", help="print messages of a topic")
    p.add_argument("topic", help="topic name, e.g. /odom")
    p.add_argument("--limit", type=COUNT, default=None, help="exit after N messages")
    p.add_argument("--timeout", type=SECONDS, default=None,
                   help="give up after S seconds (default: wait forever) [s]")
    p.add_argument("--max-array", type=COUNT, default=None,
                   help="array items shown before '...' (0: all)")


class _Session:
    """A context, a node and an executor that are torn down on exit."""

    def __init__(self, name: str) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        self.ctx = Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node(name, context=self.ctx, start_parameter_services=False)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=min(SPIN_STEP_S, max(0.0, end - time.monotonic())))

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.ctx.try_shutdown()


def _list(args: argparse.Namespace) -> int:
    if args.wait < 0:
        raise CliError(f"--wait must be >= 0, got {args.wait}")
    s = _Session("islands_topic_list")
    try:
        s.spin_for(args.wait)
        for name, types in sorted(s.node.get_topic_names_and_types()):
            print(f"{name} [{', '.join(types)}]")
    finally:
        s.close()
    return 0


def _echo(args: argparse.Namespace) -> int:
    from island_mapping.bag.qos import qos_from_rclpy, rclpy_qos
    from island_mapping.bag.schema import message_class
    from island_mapping.bag.text import DEFAULT_MAX_ARRAY, message_to_text

    topic = args.topic if args.topic.startswith("/") else "/" + args.topic
    if args.limit is not None and args.limit <= 0:
        raise CliError(f"--limit must be positive, got {args.limit}")
    if args.timeout is not None and args.timeout <= 0:
        raise CliError(f"--timeout must be positive, got {args.timeout}")
    max_array = DEFAULT_MAX_ARRAY if args.max_array is None else args.max_array
    deadline = None if args.timeout is None else time.monotonic() + args.timeout
    s = _Session("islands_topic_echo")
    received: list[Any] = []
    try:
        type_name = None
        warned = False
        while type_name is None:
            types = dict(s.node.get_topic_names_and_types()).get(topic)
            infos = s.node.get_publishers_info_by_topic(topic) if types else []
            if types and infos:
                if len(types) != 1:
                    raise CliError(f"{topic} is published with several types: {types}")
                type_name = types[0]
                break
            if deadline is not None and time.monotonic() > deadline:
                raise CliError(f"no publisher of {topic} appeared within {args.timeout} s")
            if not warned and deadline is None:
                print(f"waiting for a publisher of {topic} ...", file=sys.stderr, flush=True)
                warned = True
            s.spin_for(SPIN_STEP_S)
        try:
            cls = message_class(type_name)
        except BagError as exc:
            raise CliError(str(exc)) from None
        qos = rclpy_qos([qos_from_rclpy(i.qos_profile) for i in infos])

        def on_msg(msg: Any) -> None:
            if args.limit is not None and len(received) >= args.limit:
                return
            received.append(msg)
            print(message_to_text(msg, max_array=max_array))
            print("---", flush=True)

        s.node.create_subscription(cls, topic, on_msg, qos)
        while args.limit is None or len(received) < args.limit:
            if deadline is not None and time.monotonic() > deadline:
                if not received:
                    raise CliError(f"no message on {topic} within {args.timeout} s")
                break
            s.executor.spin_once(timeout_sec=SPIN_STEP_S)
    finally:
        s.close()
    return 0


def run(args: argparse.Namespace) -> int:
    if args.topic_command == "list":
        return _list(args)
    if args.topic_command == "echo":
        return _echo(args)
    raise CliError(f"unknown action {args.topic_command!r}")
