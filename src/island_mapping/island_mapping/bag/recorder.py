"""RunRecorder: record the topics of a running ROS graph into a rosbag2 MCAP directory.

Library use (what `islands explore` does with its in-process executor):

    recorder = RunRecorder(node, out_dir, topics=None)   # None: every topic
    ... spin the executor ...
    recorder.close()                                      # summary + metadata.yaml

Topics are discovered with `node.get_topic_names_and_types()` at start and then every
`rescan_period_s` (wall clock, so it works before sim time runs); `rescan()` may also be called
right after creating publishers. Subscriptions are raw (CDR bytes are recorded as they arrive,
no deserialization) with QoS adapted to the publishers (transient local when all publishers are,
so latched topics are recorded), and the publishers' QoS go into the bag. Messages are stamped
with their header/clock stamp, or the latest /clock (see writer.py), or sim time 0 before the
first /clock on a sim-time graph (wall time only without any clock); a wall-clock timer finishes
the open chunk every `flush_period_s` so a killed recorder loses at most that much.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from island_mapping.bag.errors import BagError
from island_mapping.bag.qos import QosDict, qos_from_rclpy, rclpy_qos
from island_mapping.bag.schema import message_class, stamp_ns_from_cdr
from island_mapping.bag.writer import CLOCK_TOPIC, BagWriter, Compression, WriterConfig

DEFAULT_EXCLUDED = ("/rosout", "/parameter_events")
"""Infrastructure topics every node publishes: noise in a run recording."""
WARN_THROTTLE_S = 5.0


@dataclass(frozen=True)
class RecorderConfig:
    """What and how a RunRecorder records (the single source of the recorder's defaults)."""

    topics: tuple[str, ...] = field(
        default=(), metadata={"help": "topics to record; empty: every topic"}
    )
    exclude: tuple[str, ...] = field(
        default=DEFAULT_EXCLUDED, metadata={"help": "topics never recorded"}
    )
    compression: str = field(default="zstd", metadata={"help": "chunk compression: zstd|lz4|none"})
    chunk_size_bytes: int = field(
        default=WriterConfig().chunk_size_bytes,
        metadata={"help": "finish a chunk above this many uncompressed bytes [bytes]"},
    )
    max_chunk_duration_s: float = field(
        default=WriterConfig().max_chunk_duration_s,
        metadata={"help": "finish a chunk spanning this much log (sim) time [s]"},
    )
    queue_depth: int = field(
        default=1000,
        metadata={
            "help": "subscription history depth: messages kept while the executor is busy "
            "(a burst larger than this is lost) [messages]"
        },
    )
    rescan_period_s: float = field(
        default=1.0, metadata={"help": "look for new topics this often (wall clock) [s]"}
    )
    flush_period_s: float = field(
        default=1.0,
        metadata={"help": "write the open chunk to disk this often (wall clock) [s]"},
    )

    def __post_init__(self) -> None:
        try:
            Compression(self.compression)
        except ValueError:
            raise BagError(f"unknown compression {self.compression!r}") from None
        for name in ("rescan_period_s", "flush_period_s", "max_chunk_duration_s", "queue_depth"):
            if not getattr(self, name) > 0:
                raise BagError(f"{name} must be positive, got {getattr(self, name)}")
        bad = [t for t in (*self.topics, *self.exclude) if not t.startswith("/")]
        if bad:
            raise BagError(f"topic names must be absolute (start with '/'): {bad}")


class RunRecorder:
    """Records topics seen by `node` into `out_dir` (see the module docstring)."""

    def __init__(
        self,
        node: Node,
        out_dir: str | os.PathLike[str],
        topics: list[str] | tuple[str, ...] | None = None,
        config: RecorderConfig | None = None,
    ) -> None:
        cfg = config or RecorderConfig()
        if topics is not None:
            cfg = dataclasses.replace(cfg, topics=tuple(topics))
        self.config = cfg
        self.node = node
        self.writer = BagWriter(
            Path(out_dir),
            compression=cfg.compression,
            config=WriterConfig(
                compression=Compression(cfg.compression),
                chunk_size_bytes=cfg.chunk_size_bytes,
                max_chunk_duration_s=cfg.max_chunk_duration_s,
            ),
        )
        self.errors = 0
        self.received = 0
        self._subs: dict[str, Any] = {}
        self._skipped: set[str] = set()
        self._closed = False
        self._clock_sub: Any = None
        self._sim_time: bool | None = None
        wall = Clock(clock_type=ClockType.STEADY_TIME)
        self._rescan_timer = node.create_timer(cfg.rescan_period_s, self.rescan, clock=wall)
        self._flush_timer = node.create_timer(cfg.flush_period_s, self.flush, clock=wall)
        self.rescan()

    @property
    def path(self) -> Path:
        return self.writer.path

    @property
    def recorded_topics(self) -> list[str]:
        return sorted(self._subs)

    def matched_publishers(self) -> dict[str, int]:
        """Per recorded topic, how many publishers its subscription is matched with.

        Messages published before a match are not recorded (volatile topics), so callers that
        must not miss the first messages wait until their topics show a count > 0.
        """
        return {t: s.get_publisher_count() for t, s in self._subs.items()}

    def _wanted(self, topic: str) -> bool:
        if topic in self.config.exclude:
            return False
        return not self.config.topics or topic in self.config.topics

    def rescan(self) -> None:
        """Subscribe to every wanted topic that has publishers and is not recorded yet."""
        if self._closed:
            return
        for topic, types in self.node.get_topic_names_and_types():
            if topic in self._subs or not self._wanted(topic):
                continue
            if len(types) != 1:
                if topic not in self._skipped:
                    self.node.get_logger().warning(
                        f"not recording {topic}: published with several types {types}"
                    )
                    self._skipped.add(topic)
                continue
            infos = self.node.get_publishers_info_by_topic(topic)
            if not infos:
                continue  # only subscribers so far: wait for a publisher (and its QoS)
            qos: list[QosDict] = [qos_from_rclpy(i.qos_profile) for i in infos]
            try:
                self.writer.add_topic(topic, types[0], qos)
                cls = message_class(types[0])
            except BagError as exc:
                if topic not in self._skipped:
                    self.node.get_logger().warning(f"not recording {topic}: {exc}")
                    self._skipped.add(topic)
                continue
            if topic == CLOCK_TOPIC and self._clock_sub is not None:
                self.node.destroy_subscription(self._clock_sub)
                self._clock_sub = None
            self._subs[topic] = self.node.create_subscription(
                cls, topic, self._callback(topic), rclpy_qos(qos, self.config.queue_depth),
                raw=True,
            )
        if CLOCK_TOPIC not in self._subs and self._clock_sub is None:
            from rosgraph_msgs.msg import Clock as ClockMsg

            self._clock_sub = self.node.create_subscription(
                ClockMsg, CLOCK_TOPIC, self._on_clock, self.config.queue_depth, raw=True
            )

    def _on_clock(self, data: bytes) -> None:
        t = stamp_ns_from_cdr(data)
        if t is not None and not self._closed:
            self.writer.observe_clock(t)

    def _callback(self, topic: str) -> Any:
        def on_message(data: bytes) -> None:
            if self._closed:
                return
            try:
                log_time = None
                stamped = self.writer.topics[topic].stamp_first
                if self.writer.latest_clock_ns is None and not stamped:
                    log_time = self._time_before_first_clock_ns()
                self.writer.write_raw(topic, data, log_time)
                self.received += 1
            except BagError as exc:
                self.errors += 1
                self.node.get_logger().warning(
                    f"dropped a message on {topic}: {exc}", throttle_duration_sec=WARN_THROTTLE_S
                )

        return on_message

    def _time_before_first_clock_ns(self) -> int:
        """Log time of a stamp-less message that arrives before any /clock message.

        On sim time (the node uses it, or someone publishes /clock) that is sim time 0, as
        sim-time nodes read until the first clock; otherwise the node's (wall) clock.
        """
        if self._sim_time is None:
            use_sim = self.node.get_parameter("use_sim_time").value
            clock_published = self.node.count_publishers(CLOCK_TOPIC) > 0
            if use_sim or clock_published:
                self._sim_time = True  # settled: a graph with a clock stays on sim time
            else:
                return int(self.node.get_clock().now().nanoseconds)
        return 0

    def flush(self) -> None:
        """Write the open chunk to disk (recoverable after a crash)."""
        if not self._closed:
            self.writer.flush()

    def close(self) -> Path:
        """Stop recording; write the summary and metadata.yaml. Returns the bag directory."""
        if not self._closed:
            self._closed = True
            for sub in self._subs.values():
                self.node.destroy_subscription(sub)
            if self._clock_sub is not None:
                self.node.destroy_subscription(self._clock_sub)
            self.node.destroy_timer(self._rescan_timer)
            self.node.destroy_timer(self._flush_timer)
            self.writer.close()
        return self.writer.path
