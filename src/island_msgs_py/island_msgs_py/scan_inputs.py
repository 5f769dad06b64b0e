"""sonar/scan and odom for a node that acts on each scan with the odometry of its stamp.

The message side of `island_msgs_py.stamps.ScanOdomPairer`, shared by the hall follower and the
island localizer nodes: converts both topics, feeds the pairer and hands every released scan
(stamp, (ranges, angles), pose) to the node; a bad message, or a scan that can never be paired,
goes to the node's bad-message log instead.
"""

from __future__ import annotations

from collections.abc import Callable

from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

from island_msgs_py.conversions import ConversionError, check_stamp
from island_msgs_py.qos import STREAM_QOS
from island_msgs_py.ros_params import clock_ns
from island_msgs_py.serialized import odometry_cdr_to_pose, scan_cdr_to_arrays
from island_msgs_py.stamps import Paired, ScanOdomPairer, paired_only
from island_msgs_py.types import FloatArray

ScanArrays = tuple[FloatArray, FloatArray]
"""(ranges [m], angles [rad]) of one scan."""


def subscribe_paired_scans(
    node: Node,
    max_buffer: int,
    handle: Callable[[list[Paired[ScanArrays]]], None],
    warn: Callable[[str, Exception], None],
) -> ScanOdomPairer[ScanArrays]:
    """Subscribe `node` to odom and sonar/scan (relative: in its namespace); returns the pairer
    (for its counters)."""
    pairer: ScanOdomPairer[ScanArrays] = ScanOdomPairer(max_buffer)

    def on_odom(data: bytes) -> None:
        try:
            pose, _, t_ns = odometry_cdr_to_pose(data)
            check_stamp(t_ns, clock_ns(node), "/odom")
        except ConversionError as exc:
            warn("odom", exc)
            return
        handle(paired_only(pairer.odometry(t_ns, pose)))

    def on_scan(data: bytes) -> None:
        try:
            ranges, angles, t_ns = scan_cdr_to_arrays(data)
            scan = (ranges, angles)
            check_stamp(t_ns, clock_ns(node), "/sonar/scan")
        except ConversionError as exc:
            warn("sonar/scan", exc)
            return
        dropped = pairer.dropped_scans
        handle(paired_only(pairer.scan(t_ns, scan)))
        if pairer.dropped_scans > dropped:
            warn("sonar/scan", ValueError("no odometry at or after a scan's stamp"))

    # raw: both read from the bytes (island_msgs_py.serialized), without building the messages
    node.create_subscription(Odometry, "odom", on_odom, STREAM_QOS, raw=True)
    node.create_subscription(LaserScan, "sonar/scan", on_scan, STREAM_QOS, raw=True)
    return pairer
