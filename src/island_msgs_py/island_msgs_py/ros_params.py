"""Declare ROS parameters from the core's frozen config dataclasses (the single source of defaults).

A config dataclass field `beam_width_deg: float = field(default=25.0, metadata={"help": "..."})`
becomes the parameter `<prefix>.beam_width_deg` with that default and description.
Nested dataclass fields become nested dotted names; enum fields are declared as their string value.
"""

from __future__ import annotations

import dataclasses
import faulthandler
import os
import signal
import sys
from collections.abc import Callable, Sequence
from enum import Enum
from typing import Any, TypeVar

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.node import Node

T = TypeVar("T")

BAD_MESSAGE_THROTTLE_S = 2.0
"""A flood of bad messages logs at most one warning per this many seconds (per node)."""


class BadMessageLog:
    """Counts the messages a node ignored as bad and logs each, throttled: a node never dies on a
    bad message. Call it with what was bad (a topic) and the error that says why."""

    def __init__(self, node: Node, throttle_s: float = BAD_MESSAGE_THROTTLE_S) -> None:
        self._logger = node.get_logger()
        self._throttle_s = throttle_s
        self.count = 0

    def __call__(self, what: str, exc: Exception) -> None:
        self.count += 1
        self._logger.warn(f"ignored bad {what} ({self.count} so far): {exc}",
                          throttle_duration_sec=self._throttle_s)


def ensure_ros_env() -> None:
    """Keep DDS discovery on this machine unless the user set otherwise (call before rclpy.init)."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


def _ros_value(value: Any) -> Any:
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, tuple):
        return list(value)
    return value


def declare_config(node: Node, prefix: str, default: T) -> T:
    """Declare `<prefix>.<field>` for every field of the dataclass instance `default`.

    Returns a new instance holding the values the node was given (overrides, YAML files) or the
    defaults. Values are validated by the dataclass's own __post_init__, if it has one.
    """
    if not dataclasses.is_dataclass(default) or isinstance(default, type):
        raise TypeError("declare_config needs a dataclass instance")
    values: dict[str, Any] = {}
    for f in dataclasses.fields(default):
        current = getattr(default, f.name)
        name = f"{prefix}.{f.name}" if prefix else f.name
        if dataclasses.is_dataclass(current) and not isinstance(current, type):
            values[f.name] = declare_config(node, name, current)
            continue
        desc = ParameterDescriptor(description=str(f.metadata.get("help", "")))
        got = node.declare_parameter(name, _ros_value(current), desc).value
        if isinstance(current, Enum):
            got = type(current)(got)
        elif isinstance(current, tuple):
            got = tuple(got)
        elif isinstance(current, float) and isinstance(got, int):
            got = float(got)
        values[f.name] = got
    return dataclasses.replace(default, **values)


EXIT_BAD_CONFIG = 2
"""Exit code of a node whose parameters or stored state are unusable (like the CLI's bad input)."""


def run_node(
    factory: Callable[[], Node],
    name: str,
    args: Sequence[str] | None = None,
    config_errors: tuple[type[BaseException], ...] = (ValueError,),
) -> int:
    """The whole `main()` of a node: init, build it, spin until Ctrl-C, SIGTERM or shutdown, then
    destroy it (so a node that holds a file closes it) and shut down.

    rclpy turns SIGINT and SIGTERM into a shutdown of the context; one that arrives while the
    node is still being built makes the construction fail, which is a clean exit, not an error.
    An exception of `config_errors` while building the node (a bad parameter, an unreadable world
    or graph store) is printed as `<name>: error: ...` and gives exit code 2.
    """
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    ensure_ros_env()
    if hasattr(signal, "SIGUSR1"):  # `kill -USR1 <pid>` prints every thread's stack: a hung node
        faulthandler.register(signal.SIGUSR1, all_threads=True)
    rclpy.init(args=list(args) if args is not None else None)
    node: Node | None = None
    executor: SingleThreadedExecutor | None = None
    try:
        try:
            node = factory()
        except config_errors as exc:
            if not rclpy.ok():
                return 0  # stopped while starting
            print(f"{name}: error: {exc}", file=sys.stderr)
            return EXIT_BAD_CONFIG
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():
            raise
        # stopped while starting: what failed was the shut-down context
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
