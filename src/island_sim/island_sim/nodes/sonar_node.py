"""sonar_node: the simulated sonar ring, driven by the ground-truth stamps (not a wall timer).

Subscribes  ground_truth       nav_msgs/Odometry (the true pose, from odometry_node)
Publishes   sonar/scan         sensor_msgs/LaserScan, once per sensor period: when a ground-truth
                               stamp crosses a period boundary, the scan is computed at that pose
                               and carries that stamp (so scan k is the pose at t_k)
            sonar/range_<i>    sensor_msgs/Range per transducer when `publish_ranges`
                               (ULTRASOUND, field_of_view = beam width, frame `sonar_<i>`)
Names are relative to the node's namespace; `frame_prefix` (e.g. `robot1/`) prefixes frame_id
and the `sonar_<i>` frames. Every parameter is read-only (the ring is fixed for a run).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from island_msgs_py.conversions import (
    ConversionError,
    check_stamp,
)
from island_msgs_py.qos import STREAM_QOS
from island_msgs_py.raycast import NearbyRayCaster
from island_msgs_py.ros_params import (
    BadMessageLog,
    clock_ns,
    declare_config,
    log_ready,
    run_node,
)
from island_msgs_py.serialized import arrays_to_scan_cdr, odometry_cdr_to_pose
from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import LaserScan, Range

from island_sim.conversions import range_msg
from island_sim.core.sim_loop import SimLoopConfig
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world_loader import load_world

NODE_NAME = "sonar_node"


class SonarNodeError(ValueError):
    """Bad node parameter (the message names it)."""


@dataclass(frozen=True)
class SonarNodeConfig:
    """Parameters of sonar_node (the ring's own parameters are `sonar.*`)."""

    world: str = field(
        default="paper_fig4", metadata={"help": "built-in world name or world file path"}
    )
    seed: int = field(default=0, metadata={"help": "seed of the range noise generator [-]"})
    sensor_rate_hz: float = field(
        default=SimLoopConfig.sensor_rate_hz,
        metadata={"help": "scans per simulated second (period boundaries of the stamps) [Hz]"},
    )
    publish_ranges: bool = field(
        default=False,
        metadata={"help": "also publish one sensor_msgs/Range per transducer [bool]"},
    )
    frame_id: str = field(default="base_link", metadata={"help": "frame of the LaserScan"})
    frame_prefix: str = field(
        default="",
        metadata={"help": "prepended to frame_id and the sonar_<i> frames, e.g. 'robot1/'"},
    )
    sonar: SonarConfig = field(default_factory=SonarConfig)


class SonarNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.cfg = declare_config(self, "", SonarNodeConfig())
        if not (math.isfinite(self.cfg.sensor_rate_hz) and self.cfg.sensor_rate_hz > 0):
            raise SonarNodeError(f"sensor_rate_hz: must be > 0, got {self.cfg.sensor_rate_hz}")
        self.world = load_world(self.cfg.world)
        self.model = SonarModel(self.cfg.sonar)
        # The world's echoes, cast against the walls within the sonar's range only.
        self.caster = NearbyRayCaster(self.world, self.cfg.sonar.range_max_m)
        self.rng = np.random.default_rng(self.cfg.seed)
        self.period_ns = round(1e9 / self.cfg.sensor_rate_hz)
        self.limits_m = self.model.scan_limits_m()
        self.scans_published = 0
        self._warn = BadMessageLog(self)
        self._last_period: int | None = None
        self.scan_pub = self.create_publisher(LaserScan, "sonar/scan", STREAM_QOS)
        self.range_pubs = []
        if self.cfg.publish_ranges:
            self.range_pubs = [
                self.create_publisher(Range, f"sonar/range_{i}", STREAM_QOS)
                for i in range(self.model.angles_rad.shape[0])
            ]
        # raw: the stamp and pose are read from the bytes (island_msgs_py.serialized), 50 times a
        # simulated second, without building the message
        self.create_subscription(Odometry, "ground_truth", self._on_truth, STREAM_QOS, raw=True)
        log_ready(self)

    @property
    def bad_msg_count(self) -> int:
        """Messages ignored as bad so far."""
        return self._warn.count

    def _on_truth(self, data: bytes) -> None:
        try:
            pose, _, t_ns = odometry_cdr_to_pose(data)
            check_stamp(t_ns, clock_ns(self), "ground_truth")
        except ConversionError as exc:
            self._warn("ground_truth", exc)
            return
        period = t_ns // self.period_ns
        if self._last_period is not None and period <= self._last_period:
            return  # still inside the period of the last scan (or an old message)
        self._last_period = period
        ranges = self.model.scan(self.caster, pose, self.rng)
        # transducer i is scan index i; bearings increase from first_angle_deg (CCW)
        # serialized here (island_msgs_py.serialized): arrays_to_scan's message, without
        # building rclpy's message objects
        scan = arrays_to_scan_cdr(ranges, self.model.angles_rad, self.limits_m, t_ns,
                                  self.cfg.frame_prefix + self.cfg.frame_id,
                                  self.period_ns * 1e-9)
        self.scan_pub.publish(scan)
        self.scans_published += 1
        fov = math.radians(self.cfg.sonar.beam_width_deg)
        for i, pub in enumerate(self.range_pubs):
            pub.publish(range_msg(float(ranges[i]), fov, self.limits_m, t_ns,
                                  f"{self.cfg.frame_prefix}sonar_{i}"))


def main(args: Sequence[str] | None = None) -> int:
    return run_node(SonarNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
