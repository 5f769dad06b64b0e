"""`islands bag`: MCAP run recordings without rosbag2.

  islands bag info DIR_OR_FILE
  islands bag echo DIR_OR_FILE --topic T [--limit N] [--max-array N]
  islands bag play DIR_OR_FILE [--rate R] [--loop] [--topics T ...] [--no-clock] [--delay S]
                   [--wait-for TOPIC ...]
  islands bag recover BROKEN.mcap [--out FIXED_DIR]
  islands bag import-carmen LOG --out DIR [--beams 16|24]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from island_mapping.bag.errors import BagError
from island_mapping.cli import CliError
from island_mapping.cli.args import COUNT, SECONDS, number

RATE = number(0.0, 1e6, exclusive_minimum=True)
"""A playback speed factor (> 0, at most a million)."""

SUBSCRIBER_SETTLE_S = 0.3
"""After a subscriber is discovered, time for its match with our publisher to complete."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="bag_command", required=True, metavar="ACTION")
    p = sub.add_parser("info", help="topics, types, counts, duration, start/end")
    p.add_argument("bag", help="rosbag2 directory or .mcap file")

    p = sub.add_parser("echo", help="print messages of one topic as YAML-like text")
    p.add_argument("bag", help="rosbag2 directory or .mcap file")
    p.add_argument("--topic", required=True, help="topic to print")
    p.add_argument("--limit", type=COUNT, default=None, help="print at most N messages")
    p.add_argument("--max-array", type=COUNT, default=None,
                   help="array items shown before '...' (0: all)")

    p = sub.add_parser("play", help="publish the recording with its timing and /clock")
    p.add_argument("bag", help="rosbag2 directory or .mcap file")
    p.add_argument("--rate", type=RATE, default=1.0, help="playback speed factor")
    p.add_argument("--loop", action="store_true", help="start again at the end")
    p.add_argument("--topics", nargs="+", default=None, help="only these topics")
    p.add_argument("--clock", dest="clock", action="store_true", default=True,
                   help="publish /clock with the bag time (default)")
    p.add_argument("--no-clock", dest="clock", action="store_false",
                   help="replay a recorded /clock as a plain topic instead")
    p.add_argument("--delay", type=SECONDS, default=0.0,
                   help="wait this long before playing, so subscribers are discovered [s]")
    p.add_argument("--wait-for", nargs="+", default=(), metavar="TOPIC",
                   help="before playing, wait until each of these topics has a subscriber "
                        "(at most --wait-timeout)")
    p.add_argument("--wait-timeout", type=SECONDS, default=30.0,
                   help="longest wait for --wait-for subscribers [s]")

    p = sub.add_parser("recover", help="rescue the complete chunks of an interrupted recording")
    p.add_argument("broken", help="the damaged .mcap file (or its directory)")
    p.add_argument("--out", default=None, help="output bag directory (default: <name>_recovered)")

    p = sub.add_parser("import-carmen", help="CARMEN log (a laser's or sonar ring's lines and "
                       "ODOM) -> rosbag2 MCAP")
    p.add_argument("log", help="CARMEN log file")
    p.add_argument("--out", required=True, help="output bag directory (must not exist)")
    p.add_argument("--beams", type=int, default=None, choices=(16, 24),
                   help="sonar-like mode: keep this many evenly spaced beams")
    from island_mapping.cli.eval_relations import add_geometry_arguments, add_scan_lines_argument

    add_geometry_arguments(p)
    add_scan_lines_argument(p)


def _fmt_time(ns: int) -> str:
    return f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d} s"


def _size(paths: list[Path]) -> str:
    total = float(sum(p.stat().st_size for p in paths))
    for unit in ("B", "KiB", "MiB", "GiB"):
        if total < 1024 or unit == "GiB":
            return f"{total:.1f} {unit}"
        total /= 1024
    return f"{total:.1f} GiB"


def info_text(path: str) -> str:
    """What `islands bag info` prints (raises BagError on a bad or damaged bag)."""
    from island_mapping.bag.reader import open_bag

    r = open_bag(path)
    lines = [
        f"Files:             {', '.join(p.name for p in r.files)}",
        f"Bag size:          {_size(r.files)}",
        "Storage id:        mcap",
        f"Duration:          {_fmt_time(r.duration_ns)}",
        f"Start:             {_fmt_time(r.start_ns)}",
        f"End:               {_fmt_time(r.end_ns)}",
        f"Messages:          {r.message_count}",
        f"Topics:            {len(r.topics)}",
    ]
    width = max((len(t) for t in r.topics), default=0)
    twidth = max((len(i.type_name) for i in r.topics.values()), default=0)
    for name in sorted(r.topics):
        i = r.topics[name]
        lines.append(
            f"  {name:<{width}}  {i.type_name:<{twidth}}  {i.message_count:>8} msgs  cdr"
        )
    return "\n".join(lines)


def _echo(args: argparse.Namespace) -> int:
    from island_mapping.bag.reader import open_bag
    from island_mapping.bag.text import DEFAULT_MAX_ARRAY, message_to_text

    if args.limit is not None and args.limit < 0:
        raise CliError(f"--limit must be >= 0, got {args.limit}")
    r = open_bag(args.bag)
    max_array = DEFAULT_MAX_ARRAY if args.max_array is None else args.max_array
    n = 0
    for m in r.messages([args.topic]):
        if args.limit is not None and n >= args.limit:
            break
        print(message_to_text(m.deserialize(), max_array=max_array))
        print("---", flush=True)
        n += 1
    return 0


def _play(args: argparse.Namespace) -> int:
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    from island_mapping.bag.player import BagPlayer
    from island_mapping.bag.reader import open_bag

    if not args.rate > 0:
        raise CliError(f"--rate must be positive, got {args.rate}")
    if args.delay < 0:
        raise CliError(f"--delay must be >= 0, got {args.delay}")
    reader = open_bag(args.bag)
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("islands_bag_player", context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    try:
        player = BagPlayer(node, reader, rate=args.rate, topics=args.topics,
                           publish_clock=args.clock, loop=args.loop)
        end = time.monotonic() + args.delay
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=min(0.05, max(0.0, end - time.monotonic())))
        _wait_for_subscribers(node, executor, args.wait_for, args.wait_timeout)
        print(f"playing {reader.message_count} messages of {len(player.topics)} topics, "
              f"{reader.duration_ns / 1e9:.3f} s at rate {args.rate}", flush=True)
        player.play_all(executor)
        print(f"published {player.published} messages", flush=True)
    finally:
        executor.shutdown()
        node.destroy_node()
        ctx.try_shutdown()
    return 0


def _wait_for_subscribers(node: Any, executor: Any, topics: Sequence[str],
                          timeout_s: float) -> None:
    """Spin until every topic in `topics` has a subscriber, or raise CliError after timeout_s."""
    deadline = time.monotonic() + timeout_s
    missing = list(topics)
    while missing:
        missing = [t for t in topics if node.count_subscribers(t) == 0]
        if not missing:
            break
        if time.monotonic() > deadline:
            raise CliError(f"no subscriber on {', '.join(missing)} after {timeout_s:.0f} s")
        executor.spin_once(timeout_sec=0.05)
    if topics:  # discovery seen: give the publisher-subscription match a moment
        settle = time.monotonic() + SUBSCRIBER_SETTLE_S
        while time.monotonic() < settle:
            executor.spin_once(timeout_sec=0.05)


def _recover(args: argparse.Namespace) -> int:
    from island_mapping.bag.recover import recover_bag

    rep = recover_bag(args.broken, args.out)
    for d in rep.damages:
        print(f"damage at byte offset {d.offset}: {d.reason}")
    if not rep.complete:
        print("the file ended without its summary (interrupted recording)")
    print(f"recovered {rep.messages} messages into {rep.out_dir}")
    for topic, count in sorted(rep.topics.items()):
        print(f"  {topic}: {count}")
    return 0


def _import_carmen(args: argparse.Namespace) -> int:
    from island_mapping.bag.carmen import import_carmen
    from island_mapping.cli.eval_relations import geometry_override

    rep = import_carmen(args.log, args.out, beams=args.beams, override=geometry_override(args),
                        scan_lines=args.scan_lines)
    print(f"wrote {rep.scans} scans ({rep.beams} beams) and {rep.odometry} odometry messages "
          f"to {rep.out_dir}")
    return 0


def run(args: argparse.Namespace) -> int:
    try:
        if args.bag_command == "info":
            print(info_text(args.bag))
            return 0
        if args.bag_command == "echo":
            return _echo(args)
        if args.bag_command == "play":
            return _play(args)
        if args.bag_command == "recover":
            return _recover(args)
        if args.bag_command == "import-carmen":
            return _import_carmen(args)
    except BagError as exc:
        raise CliError(str(exc)) from None
    raise CliError(f"unknown action {args.bag_command!r}")
