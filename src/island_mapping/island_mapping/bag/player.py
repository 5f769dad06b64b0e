"""Replay a recording on ROS topics with the recorded timing (scaled by a rate) and /clock.

`BagPlayer(node, reader, rate, topics)` publishes the recorded CDR bytes through publishers of
the recorded types and QoS (latched topics replay latched). It never blocks an executor:
- `step_next()` publishes the next batch of messages (those sharing the next log time) at once,
  and `step_until(t_ns)` every message up to a bag time: deterministic replay for tests, driven
  by the caller between `executor.spin_once` calls;
- `tick()` publishes what is due by the wall clock and returns the seconds until the next
  message: usable from a caller's loop or a timer;
- `play_all(executor)` runs the timed loop, spinning the executor while it waits.
With `publish_clock`, each batch is preceded by a rosgraph_msgs/Clock of its bag time and a
recorded /clock topic is not replayed (the player owns /clock).
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Iterator
from typing import Any

from island_mapping.bag.errors import BagError
from island_mapping.bag.qos import rclpy_qos
from island_mapping.bag.reader import BagMessage, BagReader
from island_mapping.bag.schema import message_class
from island_mapping.bag.writer import CLOCK_TOPIC

MAX_SPIN_S = 0.05
"""Longest single executor wait while playing, so Ctrl-C and loop ends stay responsive [s]."""
SPIN_MARGIN_S = 0.003
"""Stop spinning this long before a message is due and sleep the rest: an executor wake-up
is late by about a millisecond, a sleep by tens of microseconds [s]."""


class BagPlayer:
    """Publishes a BagReader's messages from `node` (see the module docstring)."""

    def __init__(
        self,
        node: Any,
        reader: BagReader,
        rate: float = 1.0,
        topics: Iterable[str] | None = None,
        publish_clock: bool = True,
        loop: bool = False,
    ) -> None:
        if not rate > 0:
            raise BagError(f"rate must be positive, got {rate}")
        self.node = node
        self.reader = reader
        self.rate = float(rate)
        self.loop = loop
        self.publish_clock = publish_clock
        chosen = list(topics) if topics is not None else sorted(reader.topics)
        unknown = sorted(set(chosen) - set(reader.topics))
        if unknown:
            raise BagError(
                f"{reader.path} has no topic {', '.join(unknown)} "
                f"(topics: {', '.join(sorted(reader.topics))})"
            )
        if publish_clock:
            chosen = [t for t in chosen if t != CLOCK_TOPIC]
        self.topics = chosen
        self._publishers: dict[str, Any] = {}
        for name in chosen:
            info = reader.topics[name]
            self._publishers[name] = node.create_publisher(
                message_class(info.type_name), name, rclpy_qos(info.qos_profiles)
            )
        self._clock_pub: Any = None
        self._clock_cls: Any = None
        if publish_clock:
            from rclpy.qos import QoSProfile
            from rosgraph_msgs.msg import Clock

            self._clock_cls = Clock
            self._clock_pub = node.create_publisher(Clock, CLOCK_TOPIC, QoSProfile(depth=10))
        self.published = 0
        self.loops_done = 0
        self.bag_time_ns: int | None = None
        self.lateness_s: list[float] = []
        """Per batch in timed playback: publish wall time minus target wall time [s]."""
        self._restart()

    def subscriber_counts(self) -> dict[str, int]:
        """Per replayed topic, how many subscriptions its publisher has matched.

        Volatile messages published before a subscriber is matched are lost: deterministic
        replays wait until the topics they need show a count > 0 before stepping.
        """
        return {t: p.get_subscription_count() for t, p in self._publishers.items()}

    # -- iteration ------------------------------------------------------------------------------
    def _restart(self) -> None:
        self._it: Iterator[BagMessage] = (
            self.reader.messages(self.topics) if self.topics else iter(())
        )
        self._pending: BagMessage | None = next(self._it, None)
        self._wall0: float | None = None

    @property
    def done(self) -> bool:
        """True when every message was published (and not looping)."""
        return self._pending is None

    @property
    def next_time_ns(self) -> int | None:
        return None if self._pending is None else self._pending.log_time_ns

    @property
    def wall_start_s(self) -> float | None:
        """`time.monotonic()` [s] at which timed playback of the current pass began: the bag's
        first log time is due then (a later one `(t - start) / rate` after); None before the
        first `tick` (and after `step_next` began a new pass of a looping player)."""
        return self._wall0

    def _publish_clock(self, t_ns: int) -> None:
        msg = self._clock_cls()
        msg.clock.sec, msg.clock.nanosec = divmod(t_ns, 1_000_000_000)
        self._clock_pub.publish(msg)

    def step_next(self) -> int | None:
        """Publish the next batch (all messages of the next log time); its time [ns] or None."""
        if self._pending is None:
            if not self.loop or self.published == 0:
                return None
            self.loops_done += 1
            self._restart()
            if self._pending is None:
                return None
        t = self._pending.log_time_ns
        if self.publish_clock:
            self._publish_clock(t)
        while self._pending is not None and self._pending.log_time_ns == t:
            m = self._pending
            self._publishers[m.topic].publish(m.data)
            self.published += 1
            self._pending = next(self._it, None)
        self.bag_time_ns = t
        return t

    def step_until(self, t_ns: int) -> int:
        """Publish every remaining message with log time <= t_ns; how many were published."""
        before = self.published
        while self._pending is not None and self._pending.log_time_ns <= t_ns:
            self.step_next()
        return self.published - before

    # -- timed playback -------------------------------------------------------------------------
    def _target_wall(self, t_ns: int) -> float:
        assert self._wall0 is not None
        return self._wall0 + (t_ns - self.reader.start_ns) / 1e9 / self.rate

    def tick(self) -> float | None:
        """Publish what is due by the wall clock; seconds until the next message, None when done."""
        now = time.monotonic()
        if self._wall0 is None:
            self._wall0 = now
        while True:
            t = self.next_time_ns
            if t is None:
                if self.loop and self.published:
                    self.loops_done += 1
                    self._restart()
                    self._wall0 = time.monotonic()
                    continue
                return None
            target = self._target_wall(t)
            now = time.monotonic()
            if target > now:
                return target - now
            self.step_next()
            self.lateness_s.append(time.monotonic() - target)

    def play_all(self, executor: Any, should_stop: Any = None) -> None:
        """Timed playback to the end (forever with loop), spinning `executor` while waiting.

        `should_stop()` (optional) is checked between batches to end early.
        """
        while should_stop is None or not should_stop():
            wait = self.tick()
            if wait is None:
                return
            if wait > SPIN_MARGIN_S:
                executor.spin_once(timeout_sec=min(wait - SPIN_MARGIN_S, MAX_SPIN_S))
            elif wait > 0:
                time.sleep(wait)
