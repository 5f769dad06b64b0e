"""Parameters declared from a config dataclass mean what `ros2 param set` says: a live field
takes effect (or is refused with the reason), any other is read-only; ranges and choices are in
the descriptors; empty arrays have a value. Set through the parameter services, as ros2cli does.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

import pytest
from island_msgs_py.ros_params import BadMessageLog, ConfigParameters, ready_line
from rcl_interfaces.msg import ParameterType, SetParametersResult
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import String


class Mode(StrEnum):
    SLOW = "slow"
    FAST = "fast"


class ToyError(ValueError):
    """What the toy config's own check raises."""


@dataclass(frozen=True)
class Inner:
    speed_mps: float = field(default=0.5, metadata={"help": "speed [m/s]", "live": True,
                                                    "range": (0.0, 2.0)})
    mode: Mode = field(default=Mode.SLOW, metadata={"help": "mode", "live": True})
    count: int = field(default=3, metadata={"help": "count [-]", "range": (1, math.inf)})

    def __post_init__(self) -> None:
        if self.mode is Mode.FAST and self.speed_mps < 1.0:
            raise ToyError(f"Inner.speed_mps: fast mode needs >= 1.0, got {self.speed_mps}")


@dataclass(frozen=True)
class Toy:
    names: tuple[str, ...] = field(default=(), metadata={"help": "names"})
    inner: Inner = field(default_factory=Inner)


@dataclass
class Harness:
    node: Node
    client: Node
    executor: SingleThreadedExecutor
    params: ConfigParameters[Toy]
    applied: list[Toy]

    def call(self, srv_type: Any, service: str, request: Any) -> Any:
        cli = self.client.create_client(srv_type, f"/toy/{service}")
        assert cli.wait_for_service(timeout_sec=5.0)
        fut = cli.call_async(request)
        while not fut.done():
            self.executor.spin_once(timeout_sec=0.05)
        return fut.result()

    def set(self, name: str, value: Any) -> SetParametersResult:
        req = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        return self.call(SetParameters, "set_parameters", req).results[0]


@pytest.fixture
def toy(ros_context: Any) -> Iterator[Harness]:
    node = Node("toy", context=ros_context)
    client = Node("toy_client", context=ros_context)
    applied: list[Toy] = []
    params = ConfigParameters(node, "", Toy(), on_change=applied.append)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    ex.add_node(client)
    try:
        yield Harness(node, client, ex, params, applied)
    finally:
        ex.shutdown()
        client.destroy_node()
        node.destroy_node()


def test_a_live_parameter_takes_effect_and_a_bad_value_is_refused_with_the_reason(
        toy: Harness) -> None:
    assert toy.params.live_names == {"inner.speed_mps", "inner.mode"}
    ok = toy.set("inner.speed_mps", 1.5)
    assert ok.successful
    assert toy.params.value.inner.speed_mps == 1.5 and toy.applied[-1] == toy.params.value
    bogus = toy.set("inner.mode", "bogus")
    assert not bogus.successful and "'bogus' is not one of slow, fast" in bogus.reason
    assert toy.set("inner.mode", "fast").successful
    assert toy.params.value.inner.mode is Mode.FAST
    # the dataclass's own validation refuses, naming why; nothing changes
    refused = toy.set("inner.speed_mps", 0.5)
    assert not refused.successful and "fast mode needs >= 1.0" in refused.reason
    assert toy.params.value.inner.speed_mps == 1.5
    assert toy.node.get_parameter("inner.speed_mps").value == 1.5
    # the descriptor's range, enforced by rclpy
    out = toy.set("inner.speed_mps", 2.5)
    assert not out.successful and "out of range" in out.reason
    assert len(toy.applied) == 2


def test_other_parameters_are_read_only_and_descriptors_say_so(toy: Harness) -> None:
    for name, value in (("inner.count", 4), ("names", ["a"])):
        res = toy.set(name, value)
        assert not res.successful and "read-only" in res.reason
    desc = toy.call(DescribeParameters, "describe_parameters", DescribeParameters.Request(
        names=["inner.count", "inner.speed_mps", "inner.mode", "names"])).descriptors
    by_name = {d.name: d for d in desc}
    assert by_name["inner.count"].read_only and not by_name["inner.speed_mps"].read_only
    assert by_name["inner.count"].integer_range[0].from_value == 1
    assert by_name["inner.speed_mps"].floating_point_range[0].to_value == 2.0
    assert by_name["inner.mode"].additional_constraints == "one of: slow, fast"
    assert by_name["names"].description == "names"


def test_an_empty_array_is_declared_with_its_type_and_a_value(toy: Harness) -> None:
    """`ros2 param dump` prints only parameters with values: an empty tuple is an empty array."""
    got = toy.call(GetParameters, "get_parameters", GetParameters.Request(names=["names"]))
    (value,) = got.values
    assert value.type == ParameterType.PARAMETER_STRING_ARRAY
    assert list(value.string_array_value) == []


def test_without_on_change_every_parameter_is_read_only(ros_context: Any) -> None:
    node = Node("fixed", context=ros_context, parameter_overrides=[
        Parameter("inner.speed_mps", value=1.25), Parameter("names", value=["x", "y"])])
    try:
        params = ConfigParameters(node, "", Toy())
        assert params.live_names == set()
        assert params.value == Toy(names=("x", "y"), inner=Inner(speed_mps=1.25))
        res = node.set_parameters([Parameter("inner.speed_mps", value=1.0)])[0]
        assert not res.successful and "read-only" in res.reason
    finally:
        node.destroy_node()


def test_the_ready_line_names_what_the_node_uses(ros_context: Any) -> None:
    node = Node("ready_probe", namespace="/robot7", context=ros_context)
    try:
        node.create_subscription(String, "in_topic", lambda _m: None, 1)
        node.create_publisher(String, "out_topic", 1)
        node.create_service(SetParameters, "do_it", lambda _r, s: s)
        node.create_client(SetParameters, "other/do_it")
        line = ready_line(node)
        assert line == ("ready: subscribes /robot7/in_topic [std_msgs/String]; publishes "
                        "/robot7/out_topic [std_msgs/String]; services /robot7/do_it "
                        "[rcl_interfaces/SetParameters]; calls /robot7/other/do_it "
                        "[rcl_interfaces/SetParameters]; system time")
    finally:
        node.destroy_node()


def test_a_bad_message_warning_names_the_topic_in_the_robots_namespace(ros_context: Any) -> None:
    node = Node("warn_probe", namespace="/robot3", context=ros_context,
                cli_args=["--ros-args", "-r", "cmd_vel:=drive"])
    try:
        warn = BadMessageLog(node)
        assert warn.resolved("odom") == "/robot3/odom"
        assert warn.resolved("cmd_vel") == "/robot3/drive"  # remappings apply too
        assert warn.resolved("/clock") == "/clock"
        assert warn.resolved("scan of 3 ranges") == "scan of 3 ranges"  # a description
        warn("odom", ValueError("range NaN"))
        warn("odom", ValueError("range NaN"))
        assert warn.count == 2
    finally:
        node.destroy_node()
