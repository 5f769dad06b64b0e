"""ROS parameters from the core's frozen config dataclasses (the single source of defaults), and
what every node shares: its `main()` (`run_node`), its bad-message log, its "ready" line.

A config dataclass field `beam_width_deg: float = field(default=25.0, metadata={"help": "..."})`
becomes the parameter `<prefix>.beam_width_deg` with that default and description. Nested
dataclass fields become nested dotted names; enum fields are declared as their string value (the
descriptor lists the choices); tuples as arrays of their element type (an empty tuple too).

Parameters mean what `ros2 param set` says. Every parameter is either
- **live** (`metadata={"live": True}` AND the node passes `on_change`): a new value is checked
  when it is set (the dataclass is rebuilt, so its `__post_init__` validates it, then the node's
  own check) and refused with the reason when bad; once set, the node gets the new config
  through `on_change` and uses it from then on; or
- **read-only** (`ParameterDescriptor(read_only=True)`): fixed when the node starts (from its
  defaults, a parameters file or `-p` overrides); `ros2 param set` answers that it is read-only.
A field's `"range": (lowest, highest)` metadata (inclusive; `math.inf` = unbounded) becomes a
`FloatingPointRange`/`IntegerRange` in the descriptor, which rclpy enforces at start and on set.
"""

from __future__ import annotations

import dataclasses
import faulthandler
import math
import os
import signal
import sys
import time
import traceback
import typing
from collections.abc import Callable, Iterable, Sequence
from enum import Enum
from typing import Any, Generic, TypeVar

import rclpy
from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    SetParametersResult,
)
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter

T = TypeVar("T")

HELP = "help"
"""Field metadata key: what the parameter does [unit]."""
LIVE = "live"
"""Field metadata key: True when a node that passes `on_change` applies a new value at run
time; otherwise the parameter is read-only."""
RANGE = "range"
"""Field metadata key: (lowest, highest) allowed value, inclusive; math.inf for no bound."""

BAD_MESSAGE_THROTTLE_S = 2.0
"""A flood of bad messages logs at most one warning per this many seconds (per node)."""
_INT64_MAX = 2**63 - 1
"""IntegerRange bounds are int64: an unbounded side is the int64 limit."""
_ARRAY_TYPES = {
    str: Parameter.Type.STRING_ARRAY, float: Parameter.Type.DOUBLE_ARRAY,
    int: Parameter.Type.INTEGER_ARRAY, bool: Parameter.Type.BOOL_ARRAY,
}


class BadMessageLog:
    """Counts the messages a node ignored as bad and logs each, throttled: a node never dies on a
    bad message. Call it with what was bad (a topic) and the error that says why."""

    def __init__(self, node: Node, throttle_s: float = BAD_MESSAGE_THROTTLE_S) -> None:
        self._node = node
        self._logger = node.get_logger()
        self._throttle_s = throttle_s
        self.count = 0

    def __call__(self, what: str, exc: Exception) -> None:
        self.count += 1
        self._logger.warn(f"ignored bad {self.resolved(what)} ({self.count} so far): {exc}",
                          throttle_duration_sec=self._throttle_s)

    def resolved(self, what: str) -> str:
        """A topic name as the node resolves it (its namespace and remappings applied: a robot's
        warning names its own topic); any other description as it is."""
        if not what or any(c.isspace() for c in what):
            return what
        try:
            return str(self._node.resolve_topic_name(what))
        except Exception:  # not a valid topic name: a description after all
            return what


def clock_ns(node: Node) -> int:
    """The node's clock now [ns] (sim time when use_sim_time: 0 before the first /clock)."""
    return int(node.get_clock().now().nanoseconds)


SHUTDOWN_SETTLE_S = 0.5
"""A callback that fails while a signal shuts the context down is told from a bug by waiting
this long for the context to report the shutdown [s]."""


def _shutting_down(context: Any) -> bool:
    deadline = time.monotonic() + SHUTDOWN_SETTLE_S
    while context.ok():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.01)
    return True


SPIN_WAKE_S = 0.5
"""The node's spin loop wakes at least this often to see whether its context was shut down [s]."""


def spin_guarded(executor: Any, node: Node) -> None:
    """`executor.spin()`, except that an exception escaping a callback (a bug some message
    triggered: the callbacks turn bad input into counted warnings themselves) is logged with its
    traceback and the node spins on: one message never kills a node."""
    logger = node.get_logger()
    failures = 0
    while executor.context.ok():
        try:
            executor.spin_once(timeout_sec=SPIN_WAKE_S)
        except Exception:  # the node survives; the traceback goes to its log
            if _shutting_down(executor.context):
                raise  # what failed was the shut-down context (Ctrl-C, SIGTERM)
            failures += 1
            logger.error(f"a callback failed ({failures} so far), the node goes on:\n"
                         f"{traceback.format_exc()}", throttle_duration_sec=BAD_MESSAGE_THROTTLE_S)


def ensure_ros_env() -> None:
    """Keep DDS discovery on this machine unless the user set otherwise (call before rclpy.init)."""
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)


DISCOVERY_SETTLE_S = 0.2
"""Wall time given to DDS discovery traffic before nodes of one context are destroyed, and
again before the last one (which takes the context's DDS participant with it) [s]."""


def destroy_nodes(nodes: Sequence[Node], settle_s: float = DISCOVERY_SETTLE_S) -> None:
    """Destroy `nodes` (all of one context, its executor already shut down), letting the
    discovery announcements of their endpoints drain first and again before the last node."""
    if not nodes:
        return
    time.sleep(settle_s)
    for n in nodes[:-1]:
        n.destroy_node()
    time.sleep(settle_s)
    nodes[-1].destroy_node()


# --- parameters from config dataclasses ----------------------------------------------------------

def _ros_value(value: Any) -> Any:
    if isinstance(value, Enum):
        return value.value
    if isinstance(value, tuple):
        return list(value)
    return value


def _from_ros(current: Any, got: Any, name: str) -> Any:
    """A parameter value as the dataclass field `name` (currently `current`) holds it."""
    if isinstance(current, Enum):
        try:
            return type(current)(got)
        except ValueError:
            choices = ", ".join(str(m.value) for m in type(current))
            raise ValueError(f"{name}: {got!r} is not one of {choices}") from None
    if isinstance(current, tuple):
        return tuple(got)
    if isinstance(current, float) and isinstance(got, int) and not isinstance(got, bool):
        return float(got)
    return got


def _array_type(owner: type, field_name: str) -> Parameter.Type | None:
    """The parameter type of a `tuple[X, ...]` field (needed to declare an empty default)."""
    hint = typing.get_type_hints(owner).get(field_name)
    args = typing.get_args(hint)
    return _ARRAY_TYPES.get(args[0]) if args else None


def _descriptor(f: dataclasses.Field[Any], current: Any, read_only: bool) -> ParameterDescriptor:
    desc = ParameterDescriptor(description=str(f.metadata.get(HELP, "")), read_only=read_only)
    if isinstance(current, Enum):
        desc.additional_constraints = "one of: " + ", ".join(str(m.value) for m in type(current))
    bounds = f.metadata.get(RANGE)
    if bounds is not None and not isinstance(current, bool):
        lo, hi = bounds
        if isinstance(current, int):
            desc.integer_range = [IntegerRange(
                from_value=int(lo) if math.isfinite(lo) else -_INT64_MAX,
                to_value=int(hi) if math.isfinite(hi) else _INT64_MAX, step=0)]
        elif isinstance(current, float):
            desc.floating_point_range = [
                FloatingPointRange(from_value=float(lo), to_value=float(hi), step=0.0)]
    return desc


def _declare_field(node: Node, name: str, f: dataclasses.Field[Any], owner: type, current: Any,
                   read_only: bool) -> Any:
    """Declare one parameter; returns its value as the node was given it (or the default)."""
    desc = _descriptor(f, current, read_only)
    array = _array_type(owner, f.name) if isinstance(current, tuple) else None
    if array is None or current:
        return node.declare_parameter(name, _ros_value(current), desc).value
    # An empty list would be inferred as a byte array: declare the type, then give it its empty
    # value (so `ros2 param dump` prints it), then make it read-only if it is.
    desc.read_only = False
    got = node.declare_parameter(name, array, desc).value
    if got is None:
        node.set_parameters([Parameter(name, array, [])])
        got = []
    if read_only:
        final = _descriptor(f, current, read_only=True)
        final.type = array.value
        node.set_descriptor(name, final)
    return got


class ConfigParameters(Generic[T]):
    """A config dataclass declared as parameters `<prefix>.<field>` of a node.

    `value` is the config the node runs with: the defaults with its overrides at start, then
    every accepted `ros2 param set` of a live field. Live fields (metadata `live`) are writable
    only when `on_change` is given; `on_change(new)` is called after a successful set and must
    apply the new config. `check(new)` (optional) may refuse a candidate config by raising
    ValueError with the reason, before anything changes.
    """

    def __init__(self, node: Node, prefix: str, default: T,
                 on_change: Callable[[T], None] | None = None,
                 check: Callable[[T], None] | None = None) -> None:
        if not dataclasses.is_dataclass(default) or isinstance(default, type):
            raise TypeError("ConfigParameters needs a dataclass instance")
        self._node = node
        self._prefix = prefix
        self._on_change = on_change
        self._check = check
        self.live_names: set[str] = set()
        """The parameters of this config that may be set at run time."""
        self.names: set[str] = set()
        """Every parameter of this config."""
        self.value: T = self._declare(prefix, default)
        if on_change is not None:
            node.add_on_set_parameters_callback(self._on_set)
            node.add_post_set_parameters_callback(self._after_set)

    def _declare(self, prefix: str, default: Any) -> Any:
        values: dict[str, Any] = {}
        for f in dataclasses.fields(default):
            current = getattr(default, f.name)
            name = f"{prefix}.{f.name}" if prefix else f.name
            if dataclasses.is_dataclass(current) and not isinstance(current, type):
                values[f.name] = self._declare(name, current)
                continue
            live = bool(f.metadata.get(LIVE, False)) and self._on_change is not None
            got = _declare_field(self._node, name, f, type(default), current, not live)
            self.names.add(name)
            if live:
                self.live_names.add(name)
            values[f.name] = _from_ros(current, got, name)
        return dataclasses.replace(default, **values)

    def _candidate(self, params: Iterable[Parameter]) -> T | None:
        """The config with the given parameters of this config set; None if none is ours."""
        ours = {p.name: p.value for p in params if p.name in self.names}
        if not ours:
            return None
        return typing.cast(T, _replaced(self.value, self._prefix, ours))

    def _on_set(self, params: list[Parameter]) -> SetParametersResult:
        try:
            new = self._candidate(params)
            if new is not None and self._check is not None:
                self._check(new)
        except (ValueError, TypeError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _after_set(self, params: list[Parameter]) -> None:
        try:
            new = self._candidate(params)
        except (ValueError, TypeError) as exc:  # cannot happen: _on_set checked the same values
            self._node.get_logger().error(f"parameters set but not applied: {exc}")
            return
        if new is None:
            return
        self.value = new
        assert self._on_change is not None
        self._on_change(new)
        changed = ", ".join(f"{p.name}={p.value!r}" for p in params if p.name in self.names)
        self._node.get_logger().info(f"parameters changed: {changed}")


def _replaced(cfg: Any, prefix: str, values: dict[str, Any]) -> Any:
    """`cfg` with the dotted `values` set (nested dataclasses rebuilt, so each validates)."""
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(cfg):
        name = f"{prefix}.{f.name}" if prefix else f.name
        current = getattr(cfg, f.name)
        if dataclasses.is_dataclass(current) and not isinstance(current, type):
            sub = _replaced(current, name, values)
            if sub is not current:
                changes[f.name] = sub
        elif name in values:
            changes[f.name] = _from_ros(current, values[name], name)
    return dataclasses.replace(cfg, **changes) if changes else cfg


def declare_config(node: Node, prefix: str, default: T,
                   on_change: Callable[[T], None] | None = None,
                   check: Callable[[T], None] | None = None) -> T:
    """Declare `<prefix>.<field>` for every field of the dataclass instance `default`.

    Returns a new instance holding the values the node was given (overrides, YAML files) or the
    defaults, validated by the dataclass's own __post_init__. Without `on_change` every
    parameter is read-only; with it, the fields marked live may be set at run time (see
    ConfigParameters).
    """
    return ConfigParameters(node, prefix, default, on_change, check).value


# --- start-up ------------------------------------------------------------------------------------

_PARAMETER_SERVICES = ("describe_parameters", "get_parameter_types", "get_parameters",
                       "get_type_description", "list_parameters", "set_parameters",
                       "set_parameters_atomically")
_INFRASTRUCTURE_TOPICS = ("/rosout", "/parameter_events")


def _type_name(cls: Any) -> str:
    """`nav_msgs/Odometry` for a message or service class."""
    module = getattr(cls, "__module__", "").split(".")[0]
    return f"{module}/{cls.__name__}" if module else cls.__name__


def ready_line(node: Node) -> str:
    """One line: what `node` subscribes to, publishes, serves and calls (resolved names with
    types, the node's own parameter services and /rosout left out) and which clock it runs on."""
    own = {node.resolve_service_name(f"~/{s}") for s in _PARAMETER_SERVICES}

    def listing(items: Iterable[tuple[str, Any]]) -> str:
        return ", ".join(f"{name} [{_type_name(t)}]" for name, t in sorted(items)) or "-"

    subs = [(s.topic_name, s.msg_type) for s in node.subscriptions]
    pubs = [(p.topic_name, p.msg_type) for p in node.publishers
            if p.topic_name not in _INFRASTRUCTURE_TOPICS]
    srvs = [(s.service_name, s.srv_type) for s in node.services if s.service_name not in own]
    clis = [(c.service_name, c.srv_type) for c in node.clients]
    sim = node.get_parameter("use_sim_time").value
    clock = "sim time (/clock)" if sim else "system time"
    return (f"ready: subscribes {listing(subs)}; publishes {listing(pubs)}; "
            f"services {listing(srvs)}; calls {listing(clis)}; {clock}")


def log_ready(node: Node) -> None:
    """Log the node's one "ready" line (`ready_line`)."""
    node.get_logger().info(ready_line(node))


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
    or graph store), or a value rclpy refuses (out of a descriptor's range, of the wrong type),
    is printed as `<name>: error: ...` and gives exit code 2.
    """
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    ensure_ros_env()
    if hasattr(signal, "SIGUSR1"):  # `kill -USR1 <pid>` prints every thread's stack: a hung node
        faulthandler.register(signal.SIGUSR1, all_threads=True)
    rclpy.init(args=list(args) if args is not None else None)
    bad_config: tuple[type[BaseException], ...] = (*config_errors, ParameterException)
    node: Node | None = None
    executor: SingleThreadedExecutor | None = None
    try:
        try:
            node = factory()
        except bad_config as exc:
            if not rclpy.ok():
                return 0  # stopped while starting
            print(f"{name}: error: {exc}", file=sys.stderr)
            return EXIT_BAD_CONFIG
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        spin_guarded(executor, node)
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
