"""hall_follower_node: sonar scans + odometry -> /cmd_vel by the hall-following state machine.

Subscribes  /sonar/scan               sensor_msgs/LaserScan
            /odom                     nav_msgs/Odometry
Publishes   /cmd_vel                  geometry_msgs/TwistStamped, exactly one per scan processed,
                                      stamped with the scan's stamp (none while paused, so
                                      another node can drive)
            /hall_follower/strategy   std_msgs/String, latched: the executed control strategy in
                                      the paper's Table 1 form `Go 125, Rot 270, Go 652`
Services    /hall_follower/reset      std_srvs/Trigger: forget the strategy (restart the record)
            /hall_follower/enable     std_srvs/SetBool: false pauses, true resumes

Each scan is paired with the odometry message of the SAME stamp (the simulator publishes both
at every sensor period), so the controller's inputs do not depend on delivery order; a scan
whose stamp has no odometry is paired with the newest older odometry once a newer one arrives
(`island_msgs_py.stamps.ScanOdomPairer`).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from geometry_msgs.msg import TwistStamped
from island_msgs_py.conversions import command_to_twist_stamped
from island_msgs_py.qos import LATCHED, STREAM_QOS
from island_msgs_py.ros_params import BadMessageLog, declare_config, run_node
from island_msgs_py.scan_inputs import subscribe_paired_scans
from island_msgs_py.stamps import Paired
from island_msgs_py.types import FloatArray, Pose2D
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

from island_sim.core.hall_follower import (
    HallFollower,
    HallFollowerConfig,
    HallFollowerError,
)

NODE_NAME = "hall_follower_node"


@dataclass(frozen=True)
class HallFollowerNodeConfig:
    """Parameters of hall_follower_node (the controller's own are `follower.*`)."""

    seed: int = field(default=0, metadata={"help": "seed of the random turn policy [-]"})
    odom_buffer: int = field(
        default=200,
        metadata={"help": "odometry messages kept for pairing with scans, and scans kept "
                  "waiting for their odometry [-]"},
    )
    follower: HallFollowerConfig = field(default_factory=HallFollowerConfig)


class HallFollowerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.cfg = declare_config(self, "", HallFollowerNodeConfig())
        self.follower = HallFollower(self.cfg.follower, np.random.default_rng(self.cfg.seed))
        self.scans_processed = 0
        self._warn = BadMessageLog(self)
        self._last_strategy: str | None = None
        self.cmd_pub = self.create_publisher(TwistStamped, "/cmd_vel", STREAM_QOS)
        self.strategy_pub = self.create_publisher(String, "/hall_follower/strategy", LATCHED)
        subscribe_paired_scans(self, self.cfg.odom_buffer, self._handle, self._warn)
        self.create_service(Trigger, "/hall_follower/reset", self._on_reset)
        self.create_service(SetBool, "/hall_follower/enable", self._on_enable)
        self._publish_strategy()

    # --- inputs --------------------------------------------------------------------------------
    @property
    def bad_msg_count(self) -> int:
        """Messages ignored as bad so far."""
        return self._warn.count

    def _handle(self, paired: list[Paired[tuple[FloatArray, FloatArray]]]) -> None:
        for p in paired:
            self._process(p.stamp_ns, p.payload[0], p.payload[1], p.pose)

    def _process(self, t_ns: int, ranges: FloatArray, angles: FloatArray, pose: Pose2D) -> None:
        try:
            v, w = self.follower.update(ranges, angles, pose, t_ns * 1e-9)
        except HallFollowerError as exc:
            self._warn("scan for the follower", exc)
            return
        self.scans_processed += 1
        if self.follower.enabled:
            self.cmd_pub.publish(command_to_twist_stamped(v, w, t_ns))
        self._publish_strategy()

    # --- services ------------------------------------------------------------------------------
    def _on_reset(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        self.follower.reset_strategy()
        self._publish_strategy()
        resp.success = True
        resp.message = "control strategy reset"
        return resp

    def _on_enable(self, req: SetBool.Request, resp: SetBool.Response) -> SetBool.Response:
        self.follower.set_enabled(bool(req.data))
        self._publish_strategy()
        resp.success = True
        resp.message = "hall following " + ("enabled" if req.data else "paused")
        return resp

    def _publish_strategy(self) -> None:
        text = str(self.follower.strategy())
        if text != self._last_strategy:
            self._last_strategy = text
            self.strategy_pub.publish(String(data=text))


def main(args: Sequence[str] | None = None) -> int:
    return run_node(HallFollowerNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
