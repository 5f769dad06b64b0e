"""island_localizer_node: while the robot is near an island, localizes it in the island's frame.

Subscribes  island_builder/events   std_msgs/String (JSON): `island_accepted` events give the
                                    island (its line model) and its origin in the odometry frame
            odom                    nav_msgs/Odometry
            sonar/scan              sensor_msgs/LaserScan
Publishes   island_pose             geometry_msgs/PoseWithCovarianceStamped, frame_id = the
                                    island's frame (`island_<id>`), stamped with the scan time
Each scan is paired with the odometry of the same stamp (island_msgs_py.stamps). The logic is
island_mapping.core.tracker.IslandTracker. Names are relative to the node's namespace; island
frames are the map's (shared by every robot), so they carry no prefix. The events are not
latched: start the localizer before the builder, or it tracks only the islands accepted after
it started. Every `tracker.*` parameter is read-only.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from geometry_msgs.msg import PoseWithCovarianceStamped
from island_msgs_py.conversions import ns_to_time
from island_msgs_py.inputs import load_json
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.limits import MAX_EVENT_JSON_BYTES
from island_msgs_py.qos import STREAM_QOS
from island_msgs_py.ros_params import BadMessageLog, declare_config, log_ready, run_node
from island_msgs_py.scan_inputs import subscribe_paired_scans
from island_msgs_py.stamps import Paired
from island_msgs_py.types import FloatArray, IslandTypeError
from rclpy.node import Node
from std_msgs.msg import String

from island_mapping.core.tracker import IslandTracker, TrackerConfig
from island_msgs_py import conversions as cv
from island_msgs_py import json_io

NODE_NAME = "island_localizer_node"
ODOM_BUFFER = 200  # odometry stamps kept for pairing scans (4 s at 50 Hz)


class IslandLocalizerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.tracker = IslandTracker(declare_config(self, "tracker", TrackerConfig()))
        self._warn = BadMessageLog(self)
        self.published = 0
        self.pose_pub = self.create_publisher(PoseWithCovarianceStamped, "island_pose", 10)
        self.create_subscription(String, "island_builder/events", self._on_event, STREAM_QOS)
        subscribe_paired_scans(self, ODOM_BUFFER, self._handle, self._warn)
        log_ready(self)

    @property
    def bad_msg_count(self) -> int:
        """Messages ignored as bad so far."""
        return self._warn.count

    def _on_event(self, msg: String) -> None:
        try:
            d = load_json(msg.data, "island_builder/events", max_bytes=MAX_EVENT_JSON_BYTES)
            if not isinstance(d, dict) or d.get("kind") != "island_accepted":
                return
            island = json_io.island_from_dict(d.get("island"), "event.island")
            origin = json_io.pose_from_dict(d.get("anchor_odom"), "event.anchor_odom")
        except (ValueError, GraphFormatError, IslandTypeError) as exc:
            self._warn("island_builder/events", exc)
            return
        self.tracker.add_island(island, origin)

    def _handle(self, paired: list[Paired[tuple[FloatArray, FloatArray]]]) -> None:
        for p in paired:
            try:
                fix = self.tracker.on_scan(p.pose, p.payload[0], p.payload[1])
            except ValueError as exc:
                self._warn("sonar/scan", exc)
                continue
            if fix is not None:
                self.published += 1
                self.pose_pub.publish(cv.pose2d_to_pose_with_covariance_stamped(
                    fix.pose, fix.frame_id, fix.covariance, ns_to_time(p.stamp_ns)))


def main(args: Sequence[str] | None = None) -> int:
    return run_node(IslandLocalizerNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
