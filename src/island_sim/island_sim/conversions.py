"""Simulator messages: the simulator's /clock and the sonar ring's per-transducer Range.

The generic conversions (stamps, LaserScan, Odometry, Twist) are in `island_msgs_py.conversions`.
"""

from __future__ import annotations

import math

from island_msgs_py.conversions import ns_to_time
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Range


def clock_msg(t_ns: int) -> Clock:
    """rosgraph_msgs/Clock for sim time `t_ns` [ns]."""
    return Clock(clock=ns_to_time(t_ns))


def range_msg(
    range_m: float, fov_rad: float, limits_m: tuple[float, float], t_ns: int, frame_id: str
) -> Range:
    """sensor_msgs/Range of one ultrasonic transducer (inf = no echo)."""
    msg = Range()
    msg.header.stamp = ns_to_time(t_ns)
    msg.header.frame_id = frame_id
    msg.radiation_type = Range.ULTRASOUND
    msg.field_of_view = float(fov_rad)
    msg.min_range = float(limits_m[0])
    msg.max_range = float(limits_m[1])
    msg.range = float(range_m) if math.isfinite(range_m) else math.inf
    return msg
