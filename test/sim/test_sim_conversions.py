"""Simulator message conversions (clock, sonar Range): round trips on messages built in memory."""

from __future__ import annotations

import math

import pytest
from island_msgs_py.conversions import time_to_ns
from island_sim.conversions import clock_msg, range_msg
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Range


def test_clock_carries_the_exact_stamp() -> None:
    assert time_to_ns(clock_msg(42).clock) == 42


def test_range_message_is_ultrasound() -> None:
    msg = deserialize_message(
        serialize_message(range_msg(math.inf, math.radians(25), (0.15, 6.5), 7, "sonar_3")), Range
    )
    assert msg.radiation_type == Range.ULTRASOUND
    assert msg.field_of_view == pytest.approx(math.radians(25))
    assert math.isinf(msg.range) and msg.header.frame_id == "sonar_3"
