"""hall_follower_node: sonar scans + odometry -> /cmd_vel by the hall-following state machine.

Subscribes  sonar/scan               sensor_msgs/LaserScan
            odom                     nav_msgs/Odometry
Publishes   cmd_vel                  geometry_msgs/TwistStamped, exactly one per scan processed,
                                     stamped with the scan's stamp (none while paused, so
                                     another node can drive; zero until the robot is claimed)
            hall_follower/strategy   std_msgs/String, latched: the executed control strategy in
                                     the paper's Table 1 form `Go 125, Rot 270, Go 652`, up to its
                                     last completed step (the whole record while paused);
                                     published when a step is completed, at a reset, at a pause
            hall_follower/progress   std_msgs/String, stream: the record including the step
                                     under way, whenever it changes (what a mapper reads)
Services    hall_follower/reset      std_srvs/Trigger: forget the strategy (restart the record);
                                     refused while following (pause first): the record is then
                                     the strategy of the edge being driven
            hall_follower/enable     std_srvs/SetBool: false pauses, true resumes
Names are relative to the node's namespace. Start-up: unless `autostart`, the follower holds the
robot still (a zero command per scan, which keeps a lockstep simulator stepping) until the first
hall_follower/enable call claims it, so a mapper started later still maps from the start pose.
Every `follower.*` parameter takes effect when set at run time (but default_hall_width_m, which
only matters before the first hallway is measured); the others are read-only.

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
from island_msgs_py.ros_params import BadMessageLog, declare_config, log_ready, run_node
from island_msgs_py.scan_inputs import subscribe_paired_scans
from island_msgs_py.stamps import Paired
from island_msgs_py.types import ControlStrategy, FloatArray, Pose2D
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

from island_sim.core.hall_follower import (
    HallFollower,
    HallFollowerConfig,
    HallFollowerError,
)

NODE_NAME = "hall_follower_node"
BASE_FRAME = "base_link"  # the robot frame /cmd_vel is in (after frame_prefix)


@dataclass(frozen=True)
class HallFollowerNodeConfig:
    """Parameters of hall_follower_node (the controller's own are `follower.*`)."""

    seed: int = field(default=0, metadata={"help": "seed of the random turn policy [-]"})
    odom_buffer: int = field(
        default=200,
        metadata={"help": "odometry messages kept for pairing with scans, and scans kept "
                  "waiting for their odometry [-]"},
    )
    autostart: bool = field(
        default=False,
        metadata={"help": "follow at once; false = hold the robot still (a zero cmd_vel per "
                  "scan) until the first hall_follower/enable call claims it [bool]"},
    )
    frame_prefix: str = field(
        default="", metadata={"help": "prepended to the cmd_vel frame base_link, e.g. 'robot1/'"}
    )
    follower: HallFollowerConfig = field(default_factory=HallFollowerConfig)


class HallFollowerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.cfg = declare_config(self, "", HallFollowerNodeConfig(), on_change=self._reconfigure)
        self.follower = HallFollower(self.cfg.follower, np.random.default_rng(self.cfg.seed))
        self.claimed = self.cfg.autostart
        """Has a controller claimed the robot (an enable call, or autostart)? Until then the
        follower holds the robot still."""
        self.scans_processed = 0
        self._warn = BadMessageLog(self)
        self._base_frame = self.cfg.frame_prefix + BASE_FRAME
        self._last_progress: str | None = None
        self._published_steps = -1  # steps in the last latched strategy (-1: none yet)
        self.cmd_pub = self.create_publisher(TwistStamped, "cmd_vel", STREAM_QOS)
        self.strategy_pub = self.create_publisher(String, "hall_follower/strategy", LATCHED)
        self.progress_pub = self.create_publisher(String, "hall_follower/progress", STREAM_QOS)
        subscribe_paired_scans(self, self.cfg.odom_buffer, self._handle, self._warn)
        self.create_service(Trigger, "hall_follower/reset", self._on_reset)
        self.create_service(SetBool, "hall_follower/enable", self._on_enable)
        self._publish_strategy(latch=True)
        log_ready(self)

    def _reconfigure(self, cfg: HallFollowerNodeConfig) -> None:
        """A live `follower.*` parameter was set: follow with it from the next scan on."""
        self.cfg = cfg
        self.follower.reconfigure(cfg.follower)

    # --- inputs --------------------------------------------------------------------------------
    @property
    def bad_msg_count(self) -> int:
        """Messages ignored as bad so far."""
        return self._warn.count

    def _handle(self, paired: list[Paired[tuple[FloatArray, FloatArray]]]) -> None:
        for p in paired:
            self._process(p.stamp_ns, p.payload[0], p.payload[1], p.pose)

    def _process(self, t_ns: int, ranges: FloatArray, angles: FloatArray, pose: Pose2D) -> None:
        if not self.claimed:  # hold still until a controller claims the robot
            self.scans_processed += 1
            self.cmd_pub.publish(command_to_twist_stamped(0.0, 0.0, t_ns, self._base_frame))
            return
        try:
            v, w = self.follower.update(ranges, angles, pose, t_ns * 1e-9)
        except HallFollowerError as exc:
            self._warn("sonar/scan", exc)
            return
        self.scans_processed += 1
        if self.follower.enabled:
            self.cmd_pub.publish(command_to_twist_stamped(v, w, t_ns, self._base_frame))
        self._publish_strategy()

    # --- services ------------------------------------------------------------------------------
    @property
    def following(self) -> bool:
        """Claimed and not paused: the follower drives and its record grows."""
        return self.claimed and self.follower.enabled

    def _on_reset(self, _req: Trigger.Request, resp: Trigger.Response) -> Trigger.Response:
        if self.following:
            resp.success = False
            resp.message = ("refused: the hall follower is following, and its record is the "
                            "strategy of the edge being driven (the island builder's, while it "
                            "maps); pause it first (hall_follower/enable false), then reset")
            return resp
        self.follower.reset_strategy()
        self._publish_strategy(latch=True)
        resp.success = True
        resp.message = "control strategy reset"
        return resp

    def _on_enable(self, req: SetBool.Request, resp: SetBool.Response) -> SetBool.Response:
        self.claimed = True
        self.follower.set_enabled(bool(req.data))
        self._publish_strategy(latch=not req.data)
        resp.success = True
        resp.message = "hall following " + ("enabled" if req.data else "paused")
        return resp

    def _publish_strategy(self, latch: bool = False) -> None:
        """The record on hall_follower/progress when it changed; on hall_follower/strategy
        (latched) up to its last completed step when a step was completed since the last
        publication, or whole when `latch` (a reset or a pause)."""
        record = self.follower.strategy()
        text = str(record)
        if text != self._last_progress:
            self._last_progress = text
            self.progress_pub.publish(String(data=text))
        done = len(record.steps) - (1 if self.following and record.steps else 0)
        if latch or done > self._published_steps:
            self._published_steps = done
            self.strategy_pub.publish(String(data=str(ControlStrategy(record.steps[:done]))))


def main(args: Sequence[str] | None = None) -> int:
    return run_node(HallFollowerNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
