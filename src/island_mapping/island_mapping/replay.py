"""Replay a recorded run into a fresh island builder and graph server.

The maps are compared with the recording by island_mapping.bag.compare.

`replay_run(bag_path)` creates, on one in-process executor with `use_sim_time`, a new
island_builder_node and topo_graph_server_node (memory only) and a player node that publishes
the recorded /clock, /odom, /ground_truth, /sonar/scan and /hall_follower/progress messages in
the order they were recorded (see `recorded_order`: the order the run's nodes received them,
not log-time order; a recording made before the follower had a progress topic carries the same
record, on every change, on /hall_follower/strategy, which is then replayed as the progress).
Delivery is made deterministic: every subscription callback of the two
nodes is wrapped with a counter, and the executor is spun until each subscription has run its
callback for every message published so far before anything else is published. Each scan goes
alone; the messages between two scans (odometry, ground truth, strategy: the builder only
accumulates them, each topic in its own order) go as one batch, of which only the newest /clock
and the newest strategy are published (their subscribers keep only the newest anyway: depth
1). So no message is lost, none overtakes another where it matters, and the builder sees the
recorded sequence whatever the machine load.

The builder also drives (/cmd_vel) and calls /hall_follower/enable and /hall_follower/reset.
Nobody answers in a replay: its calls are asynchronous (`call_async`), the futures simply stay
pending, and its decisions (island_mapping.core.builder) do not depend on the answers, only on
odometry, scans, ground truth and the recorded strategy. /topo_graph/add is answered by the
in-process graph server; the replay waits for the service before the first message and, at the
end, until the server holds every island and edge the builder accepted.

A truncated or corrupted recording is an error by default (`ReplayError` naming the file and
byte offset, from the bag reader); with `allow_damaged=True` the intact part is replayed and
the damage is listed in `ReplayResult.warnings`.

The builder's parameters are not in the recording: the replay uses the defaults (as
`islands explore` does) unless `builder_params` overrides them; a run made with other builder
parameters must be replayed with the same overrides. Nor is the code: the replay runs the
installed builder, so a recording made before the builder's logic changed replays into the
new logic's graph (the comparison then shows where the two part).
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import rclpy
from island_msgs_py.ros_params import destroy_nodes, ensure_ros_env
from mcap.reader import make_reader
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from island_mapping.bag.errors import BagError
from island_mapping.bag.reader import BagMessage, BagReader, open_bag
from island_mapping.bag.recover import scan_mcap
from island_mapping.bag.schema import full_type_name
from island_mapping.core.graph import TopoGraph
from island_mapping.nodes.island_builder_node import STREAM_QOS, IslandBuilderNode
from island_mapping.nodes.topo_graph_server_node import TopoGraphServerNode

CLOCK_TOPIC = "/clock"
ODOM_TOPIC = "/odom"
TRUTH_TOPIC = "/ground_truth"
SCAN_TOPIC = "/sonar/scan"
PROGRESS_TOPIC = "/hall_follower/progress"
STRATEGY_TOPIC = "/hall_follower/strategy"
"""Before the progress topic existed, the follower published its record on every change here."""
EVENTS_TOPIC = "/island_builder/events"
REPLAYED_TOPICS = (CLOCK_TOPIC, ODOM_TOPIC, TRUTH_TOPIC, SCAN_TOPIC, PROGRESS_TOPIC,
                   STRATEGY_TOPIC)
"""What the builder (and the graph server's clock) consume in a run (STRATEGY_TOPIC only from a
recording without PROGRESS_TOPIC, replayed as the progress)."""
LATEST_ONLY_TOPICS = (CLOCK_TOPIC, PROGRESS_TOPIC, STRATEGY_TOPIC)
"""Topics whose subscribers keep only the newest message (depth 1: the time sources' /clock,
the builder's follower record, which `set_strategy` overwrites)."""
REQUIRED_TOPICS = (ODOM_TOPIC, SCAN_TOPIC)
"""Without these the builder decides nothing; the others are optional (warned when missing)."""
EVENTS_QOS = QoSProfile(depth=1000)
"""Deep enough to keep every builder event between two spins (a few per scan at most)."""
MAX_BATCH = 50
"""Most messages published before awaiting their delivery: well below the depth (100) of the
builder's subscriptions and the player's publishers, so a batch is never cut short."""
PROGRESS_EVERY = 500
"""Report progress about this often [messages]."""
SPIN_STEP_S = 0.01
"""Longest single executor wait while waiting for a delivery [s] (returns at once when ready)."""


class ReplayError(RuntimeError):
    """The recording cannot be replayed (the message names the file or topic and the problem)."""


@dataclass(frozen=True)
class ReplayConfig:
    """How a recording is replayed (the single source of the replay's defaults)."""

    allow_damaged: bool = field(
        default=False,
        metadata={"help": "replay the intact part of a truncated/corrupted bag instead of "
                          "failing [bool]"},
    )
    delivery_timeout_s: float = field(
        default=10.0,
        metadata={"help": "wall time to wait for the nodes to take one replayed message [s]"},
    )
    setup_timeout_s: float = field(
        default=10.0,
        metadata={"help": "wall time to wait for topic matching and the /topo_graph/add "
                          "service before replaying, and for the last graph updates after [s]"},
    )
    discovery_settle_s: float = field(
        default=1.0,
        metadata={"help": "wall time given to discovering other processes in the ROS domain "
                          "before checking that none publishes a replayed topic (also checked "
                          "at the end) [s]"},
    )

    def __post_init__(self) -> None:
        if not (math.isfinite(self.discovery_settle_s) and self.discovery_settle_s >= 0):
            raise ReplayError("ReplayConfig.discovery_settle_s must be a number of seconds "
                              f">= 0, got {self.discovery_settle_s!r}")
        for name in ("delivery_timeout_s", "setup_timeout_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ReplayError(f"ReplayConfig.{name} must be a positive number of seconds, "
                                  f"got {value!r}")


@dataclass
class ReplayResult:
    """What a replay produced: the graph, the builder's events and what was replayed."""

    graph: TopoGraph
    events: list[dict[str, Any]]
    """The replayed builder's events (parsed /island_builder/events JSON), in order."""
    recorded_events: list[dict[str, Any]] | None
    """The recording's /island_builder/events, or None when it has none."""
    messages: dict[str, int]
    """Per replayed topic, how many messages were published."""
    superseded: dict[str, int]
    """Per LATEST_ONLY_TOPICS topic, recorded messages not published because a newer one on
    the same topic followed before the next scan (the nodes keep only the newest)."""
    warnings: list[str]
    bag_path: Path
    wall_seconds: float

    @property
    def message_count(self) -> int:
        return sum(self.messages.values())


# ---- the replay ------------------------------------------------------------------------------


class _DeliveryCounter:
    """Counts, per topic, the subscription callbacks the watched nodes have run.

    Each subscription's callback is wrapped (the executor reads `sub.callback` when it runs
    it), so a count goes up only after the node's own callback returned.
    """

    def __init__(self, nodes: Iterable[Node]) -> None:
        self.count: dict[str, int] = {}
        self.subscriptions: dict[str, int] = {}
        for node in nodes:
            for sub in node.subscriptions:
                topic = sub.topic_name
                self.subscriptions[topic] = self.subscriptions.get(topic, 0) + 1
                self.count.setdefault(topic, 0)
                sub.callback = self._wrap(topic, sub.callback)

    def _wrap(self, topic: str, callback: Callable[..., Any]) -> Callable[..., Any]:
        def counted(*args: Any) -> Any:
            try:
                return callback(*args)
            finally:
                self.count[topic] += 1

        return counted


class _Replayer:
    """The nodes, the player's publishers and the delivery-checked publishing loop."""

    def __init__(
        self,
        ctx: Context,
        reader: BagReader,
        config: ReplayConfig,
        builder_params: Mapping[str, Any] | None,
    ) -> None:
        self.ctx = ctx
        self.reader = reader
        self.config = config
        sim_time = Parameter("use_sim_time", value=True)
        # Nobody answers the follower calls in a replay: map at once.
        overrides = [sim_time, Parameter("wait_for_services", value=False)] + [
            Parameter(k, value=v) for k, v in (builder_params or {}).items()]
        # No parameter services: nobody can reach them in a replay, and fewer entities make
        # every executor wait cheaper (one per replayed message).
        try:
            self.builder = IslandBuilderNode(context=ctx, parameter_overrides=overrides,
                                             start_parameter_services=False)
        except Exception as exc:  # a bad value: rclpy and the config raise various types
            raise ReplayError(f"island_builder_node rejected the builder parameters "
                              f"{dict(builder_params or {})}: {exc}") from None
        unknown = sorted(k for k in (builder_params or {}) if not self.builder.has_parameter(k))
        if unknown:
            self.builder.destroy_node()
            raise ReplayError(f"island_builder_node has no parameter {', '.join(unknown)} "
                              "(e.g. builder.e_min_m, builder.star.leg_length_m)")
        self.server = TopoGraphServerNode(
            context=ctx, parameter_overrides=[sim_time, Parameter("storage_path", value="")]
        )
        self.player = Node("islands_replay_player", context=ctx,
                           start_parameter_services=False)
        self.events: list[dict[str, Any]] = []
        self.bad_events = 0
        self.player.create_subscription(String, EVENTS_TOPIC, self._on_event, EVENTS_QOS)
        self.topics = [t for t in REPLAYED_TOPICS if t in reader.topics]
        if PROGRESS_TOPIC in self.topics and STRATEGY_TOPIC in self.topics:
            self.topics.remove(STRATEGY_TOPIC)  # the sparse latched record: the builder reads none
        self.target = {t: PROGRESS_TOPIC if t == STRATEGY_TOPIC else t for t in self.topics}
        """Recorded topic -> the topic it is replayed on."""
        self.publishers: dict[str, Any] = {}
        for topic in self.topics:
            type_name = reader.topics[topic].type_name
            cls = _message_class(topic, type_name)
            self.publishers[topic] = self.player.create_publisher(cls, self.target[topic],
                                                                  STREAM_QOS)
        self.counter = _DeliveryCounter([self.builder, self.server])
        # Scans the builder core has processed (the node holds a scan back until odometry of
        # its stamp or later has come): wrapped like the callbacks, the method is unchanged.
        self.scans_processed = 0
        core_on_scan = self.builder.builder.on_scan

        def on_scan(*args: Any, **kwargs: Any) -> None:
            self.scans_processed += 1
            core_on_scan(*args, **kwargs)

        self.builder.builder.on_scan = on_scan  # type: ignore[method-assign]
        self.executor = SingleThreadedExecutor(context=ctx)
        for n in (self.player, self.builder, self.server):
            self.executor.add_node(n)
        self.published: dict[str, int] = {t: 0 for t in self.topics}
        self.superseded: dict[str, int] = {t: 0 for t in LATEST_ONLY_TOPICS}

    def _on_event(self, msg: String) -> None:
        try:
            event = json.loads(msg.data)
        except json.JSONDecodeError:
            self.bad_events += 1
            return
        self.events.append(event)

    def _spin_until(self, done: Callable[[], bool], timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while not done():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=SPIN_STEP_S)
        return True

    def wait_ready(self) -> None:
        """Every replayed topic matched by the nodes, and /topo_graph/add available."""
        def ready() -> bool:
            return self.builder.add_cli.service_is_ready() and all(
                p.get_subscription_count() >= self.counter.subscriptions.get(self.target[t], 0)
                for t, p in self.publishers.items()
            )

        if not self._spin_until(ready, self.config.setup_timeout_s):
            matched = {t: p.get_subscription_count() for t, p in self.publishers.items()}
            raise ReplayError(
                f"replay nodes not connected within {self.config.setup_timeout_s:g} s: "
                f"/topo_graph/add ready={self.builder.add_cli.service_is_ready()}, "
                f"subscriptions matched per topic {matched}"
            )
        settle = time.monotonic() + self.config.discovery_settle_s
        self._spin_until(lambda: time.monotonic() >= settle, self.config.discovery_settle_s + 1)
        self.check_isolated()

    def check_isolated(self) -> None:
        """No other process may publish what the builder consumes (it would change the map)."""
        foreign = {t: self.player.count_publishers(self.target[t]) - 1 for t in self.publishers}
        foreign = {t: n for t, n in foreign.items() if n > 0}
        if foreign:
            domain = os.environ.get("ROS_DOMAIN_ID", "0")
            raise ReplayError(
                f"other publishers on the replayed topics in ROS domain {domain} "
                f"({', '.join(f'{t}: {n}' for t, n in sorted(foreign.items()))}): a running "
                "simulation would feed the replayed builder; set ROS_DOMAIN_ID to a free domain"
            )

    def publish(self, batch: list[BagMessage]) -> None:
        """Publish recorded messages and spin until every node subscribed took each of them.

        A batch never holds a scan next to other topics (see `replay`), so the only order that
        matters, each topic's own, is kept by the reliable in-order delivery of one topic.
        """
        expected = dict(self.counter.count)
        for m in batch:
            target = self.target[m.topic]
            n_subs = self.counter.subscriptions.get(target, 0)
            expected[target] = expected.get(target, 0) + n_subs
            self.publishers[m.topic].publish(m.data)
            self.published[m.topic] += 1

        def delivered() -> bool:
            return all(self.counter.count.get(t, 0) >= n for t, n in expected.items())

        if not self._spin_until(delivered, self.config.delivery_timeout_s):
            late = sorted(t for t, n in expected.items() if self.counter.count.get(t, 0) < n)
            m = batch[-1]
            raise ReplayError(
                f"{self.reader.path}: recorded messages on {', '.join(late)} (up to log time "
                f"{m.log_time_ns} ns) were not delivered to the replay nodes within "
                f"{self.config.delivery_timeout_s:g} s"
            )
        extra = sorted(t for t, n in expected.items() if self.counter.count.get(t, 0) > n)
        if extra:
            self.check_isolated()
            raise ReplayError(f"the replay nodes received more {', '.join(extra)} messages than "
                              "were replayed: another publisher is feeding them")

    def replay(self, messages: Iterable[BagMessage],
               progress: Callable[[int], None] | None = None) -> None:
        """Publish `messages` in their order, one scan at a time (see the module docstring).

        Between two scans the builder only accumulates (odometry in order, the latest ground
        truth and strategy), so the messages between two scans go out as one batch and are
        awaited together; a scan goes alone. While the builder holds a scan back (its
        odometry has not come yet, so the next odometry message will process it), every
        message goes alone, as the order of that odometry and the other topics then matters.
        """
        batch: list[BagMessage] = []
        done = 0
        report_at = PROGRESS_EVERY
        for m in messages:
            alone = m.topic == SCAN_TOPIC or self.scans_held_back()
            if batch and (alone or len(batch) >= MAX_BATCH):
                self.publish(batch)
                done += len(batch)
                batch = []
            if alone:
                self.publish([m])
                done += 1
            elif m.topic in LATEST_ONLY_TOPICS and any(b.topic == m.topic for b in batch):
                # Its subscriptions keep only the newest message (depth 1) and nothing reads it
                # before the next scan: the older one in the batch is not published at all.
                batch = [b for b in batch if b.topic != m.topic] + [m]
                self.superseded[m.topic] += 1
                done += 1
            else:
                batch.append(m)
            if progress is not None and done >= report_at:
                report_at = done + PROGRESS_EVERY
                progress(done)
        if batch:
            self.publish(batch)
            done += len(batch)
        if progress is not None:
            progress(done)

    def scans_held_back(self) -> bool:
        """Has the builder taken a scan that it has not processed yet?"""
        return self.scans_processed < self.counter.count.get(SCAN_TOPIC, 0)

    def finish(self) -> None:
        """Spin until the server holds what the builder accepted and every event arrived."""
        core = self.builder.builder

        def settled() -> bool:
            return (
                len(self.server.graph) >= len(core.islands)
                and self.server.graph.num_edges >= len(core.edges)
                and len(self.events) + self.bad_events >= sum(core.counts.values())
            )

        if not self._spin_until(settled, self.config.setup_timeout_s):
            raise ReplayError(
                f"after the replay the graph server holds {len(self.server.graph)} islands and "
                f"{self.server.graph.num_edges} edges but the builder accepted "
                f"{len(core.islands)} and {len(core.edges)} (not settled within "
                f"{self.config.setup_timeout_s:g} s)"
            )
        self.check_isolated()

    def close(self) -> None:
        self.executor.shutdown()
        destroy_nodes([self.player, self.builder, self.server])


def _message_class(topic: str, type_name: str) -> Any:
    from island_mapping.bag.schema import message_class

    try:
        return message_class(type_name)
    except BagError as exc:
        raise ReplayError(f"{topic}: cannot load message type {type_name}: {exc}") from None


def recorded_order(reader: BagReader, topics: Iterable[str]) -> Iterator[BagMessage]:
    """The messages of `topics` in the order they were recorded (file order, file by file).

    This is the order in which the recorder received them during the run, and the order the
    run's builder received them in too: the simulator publishes /odom one physics step past
    the scan it is sensing (e.g. /odom at t + 20 ms arrives before /sonar/scan at t), so the
    builder processes each scan with that later odometry; log-time order would hand the
    builder a different interleaving from the one it saw. Files the reader found damaged
    (only opened with allow_damaged) yield their intact messages, from a sequential scan.
    """
    wanted = set(topics)
    damaged = {Path(d.path) for d in reader.damage}
    for path in reader.files:
        if path in damaged:
            yield from _scanned(path, wanted)
            continue
        with path.open("rb") as fh:
            it = make_reader(fh, validate_crcs=True).iter_messages(
                topics=sorted(wanted), log_time_order=False)
            while True:
                try:
                    schema, channel, msg = next(it)
                except StopIteration:
                    break
                except Exception as exc:  # a damaged chunk that the summary did not reveal
                    err = scan_mcap(path).first_error()
                    if err is None:
                        raise BagError(f"{path}: cannot read messages: {exc}") from None
                    if not reader.allow_damaged:
                        raise err from None
                    reader.damage.append(err)
                    break
                if schema is not None:
                    yield BagMessage(channel.topic, full_type_name(schema.name), msg.log_time,
                                     msg.data)


def _scanned(path: Path, wanted: set[str]) -> Iterator[BagMessage]:
    scan = scan_mcap(path)
    for m in scan.messages:
        ch = scan.channels.get(m.channel_id)
        if ch is None or ch.topic not in wanted:
            continue
        schema = scan.schemas.get(ch.schema_id)
        if schema is not None:
            yield BagMessage(ch.topic, full_type_name(schema.name), m.log_time, m.data)


def _recorded_events(reader: BagReader) -> list[dict[str, Any]] | None:
    if EVENTS_TOPIC not in reader.topics:
        return None
    out: list[dict[str, Any]] = []
    for m in reader.messages([EVENTS_TOPIC]):
        try:
            out.append(json.loads(m.deserialize().data))
        except (BagError, json.JSONDecodeError):
            continue
    return out


def open_recording(
    bag_path: str | os.PathLike[str], allow_damaged: bool = False
) -> tuple[BagReader, list[str]]:
    """Open a bag for replay: (reader, warnings). Damage is a ReplayError unless allowed."""
    try:
        reader = open_bag(bag_path, allow_damaged=allow_damaged)
    except BagError as exc:
        raise ReplayError(f"cannot replay {bag_path}: {exc}") from None
    warnings: list[str] = []
    missing = [t for t in REQUIRED_TOPICS if t not in reader.topics]
    if missing:
        raise ReplayError(
            f"{reader.path} has no {', '.join(missing)}: nothing for the island builder "
            f"(topics: {', '.join(sorted(reader.topics)) or 'none'})"
        )
    for t in REPLAYED_TOPICS:
        if t == STRATEGY_TOPIC or (t == PROGRESS_TOPIC and STRATEGY_TOPIC in reader.topics):
            continue  # an older recording's strategy topic carries the progress
        if t not in reader.topics and t not in REQUIRED_TOPICS:
            warnings.append(f"{reader.path} has no {t}; replaying without it")
    return reader, warnings


def replay_run(
    bag_path: str | os.PathLike[str],
    config: ReplayConfig | None = None,
    builder_params: Mapping[str, Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> ReplayResult:
    """Replay a recording into a fresh builder and graph server (see the module docstring).

    `builder_params`: island_builder_node parameter overrides (dotted names, e.g.
    {"builder.e_min_m": 0.5}). `progress(done, total)` is called every few hundred messages.
    Raises ReplayError for an unreadable, damaged (unless allowed) or unsuitable recording.
    """
    cfg = config if config is not None else ReplayConfig()
    reader, warnings = open_recording(bag_path, cfg.allow_damaged)
    ensure_ros_env()
    wall0 = time.monotonic()
    ctx = Context()
    rclpy.init(context=ctx)
    rep: _Replayer | None = None
    try:
        rep = _Replayer(ctx, reader, cfg, builder_params)
        rep.wait_ready()
        total = sum(reader.topics[t].message_count for t in rep.topics)
        try:
            rep.replay(recorded_order(reader, rep.topics),
                       None if progress is None else (lambda done: progress(done, total)))
        except BagError as exc:
            raise ReplayError(f"cannot replay {reader.path}: {exc}") from None
        rep.finish()
        if rep.builder.bad_msg_count:
            warnings.append(f"the builder ignored {rep.builder.bad_msg_count} bad messages")
        if rep.bad_events:
            warnings.append(f"{rep.bad_events} builder events were not JSON")
        graph = TopoGraph.from_parts(rep.server.graph.islands(), rep.server.graph.edges())
        recorded_events = _recorded_events(reader)
        damage = dict.fromkeys(str(d) for d in reader.damage)  # unique, in order
        warnings[:0] = [f"damaged recording, replayed only its intact part: {d}" for d in damage]
        return ReplayResult(
            graph=graph,
            events=list(rep.events),
            recorded_events=recorded_events,
            messages=dict(rep.published),
            superseded=dict(rep.superseded),
            warnings=warnings,
            bag_path=reader.path,
            wall_seconds=time.monotonic() - wall0,
        )
    finally:
        if rep is not None:
            rep.close()
        ctx.try_shutdown()


def replay_into_builder(
    bag_path: str | os.PathLike[str],
    config: ReplayConfig | None = None,
    builder_params: Mapping[str, Any] | None = None,
) -> TopoGraph:
    """The graph a fresh builder and graph server build from the recording (see replay_run)."""
    return replay_run(bag_path, config, builder_params).graph
