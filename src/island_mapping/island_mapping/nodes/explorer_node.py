"""explorer_node: exploration by the map (issue 16), one decision per scan.

Subscribes  odom                      nav_msgs/Odometry (pose; twist: the measured turn rate)
            sonar/scan                sensor_msgs/LaserScan, paired with the odometry of its stamp
            island_builder/decision   std_msgs/String JSON, the builder's verdict on each scan
                                      (managed mode): a scan is decided once its verdict is in,
                                      so the explorer sees the builder's events of that scan
            topo_graph/json           std_msgs/String (latched), the map
            hall_follower/progress    std_msgs/String, the follower's record (a return by it)
Publishes   cmd_vel                   geometry_msgs/TwistStamped (the scan's stamp), one per scan
                                      while the explorer drives, and a zero one for a scan
                                      nobody else answers (the builder idle): the simulator's
                                      lockstep waits for exactly one answer per scan
            explorer/status           std_msgs/String JSON (latched): state, island, target
                                      [island, exit], exits_left, done, reason; on every change
Calls       island_builder/explorer   rcl_interfaces/SetParameters: `docked`, `handover`,
                                      `abort` (island_mapping.conversions)
            topo_graph/add            `exit` items: exits found blocked
The decisions are `island_mapping.core.explore.Explorer`'s; this node converts and publishes.
The builder (its `managed` parameter true) owns the hall follower: it resumes it at a handover
and pauses it when it hands back or stops. Names are relative to the node's namespace. With
`wait_for_services` the node subscribes only once island_builder/explorer and topo_graph/add
are up. Every parameter is read-only (fixed for a run).
"""

from __future__ import annotations

import sys
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from geometry_msgs.msg import TwistStamped
from island_msgs_py.conversions import (
    ConversionError,
    check_stamp,
    command_to_twist_stamped,
)
from island_msgs_py.hall_perception import HallPerceptionConfig
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.qos import LATCHED, STREAM_QOS
from island_msgs_py.ros_params import BadMessageLog, clock_ns, declare_config, log_ready, run_node
from island_msgs_py.serialized import odometry_cdr_to_pose_twist, scan_cdr_to_arrays
from island_msgs_py.stamps import Paired, ScanOdomPairer, StampJoin, paired_only
from island_msgs_py.types import ControlStrategy, ExitUpdate, FloatArray, IslandTypeError, NewExit
from nav_msgs.msg import Odometry
from rcl_interfaces.srv import SetParameters
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String

from island_mapping import conversions as mcv
from island_mapping.core.builder import CommandMode
from island_mapping.core.explore import Explorer, ExplorerConfig
from island_mapping.core.graph import GraphError, TopoGraph
from island_mapping.core.route import NavigateConfig, Sense, stalled

NODE_NAME = "explorer_node"
BASE_FRAME = "base_link"  # the robot frame cmd_vel is in (after frame_prefix)
SERVICE_POLL_S = 0.1  # how often (wall clock) to look for the services the node waits for
PROGRESS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
DECISION_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
"""The builder's verdicts: every one matters (a scan waits for its own)."""


@dataclass(frozen=True)
class ExplorerNodeConfig:
    """Parameters of explorer_node (the mission's own are `explorer.*`, route following's
    `navigate.*`)."""

    wait_for_services: bool = field(
        default=True,
        metadata={"help": "subscribe (start exploring) only once island_builder/explorer and "
                  "topo_graph/add are up [bool]"},
    )
    frame_prefix: str = field(
        default="", metadata={"help": "prepended to the cmd_vel frame base_link, e.g. 'robot1/'"}
    )
    odom_buffer: int = field(
        default=200,
        metadata={"help": "odometry messages kept for pairing with scans, and scans or builder "
                  "decisions kept waiting for their counterpart [-]"},
    )
    hall_width_m: float = field(
        default=2.0,
        metadata={"help": "hallway width assumed by route following until both walls are seen "
                  "(the hall follower's default_hall_width_m) [m]"},
    )
    explorer: ExplorerConfig = field(default_factory=ExplorerConfig)
    navigate: NavigateConfig = field(default_factory=NavigateConfig)


@dataclass(frozen=True)
class _Scan:
    ranges_m: FloatArray
    angles_rad: FloatArray
    pose: Any
    w_radps: float
    v_mps: float


class ExplorerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.cfg = declare_config(self, "", ExplorerNodeConfig())
        c = self.cfg
        # Hallway perception as the hall follower's defaults (route following and the
        # follower must agree; the follower's perception fields are its own parameters).
        self.explorer = Explorer(c.explorer, c.navigate, HallPerceptionConfig(), c.hall_width_m)
        self._warn = BadMessageLog(self)
        self._base_frame = c.frame_prefix + BASE_FRAME
        self._pairer: ScanOdomPairer[tuple[FloatArray, FloatArray]] = ScanOdomPairer(
            c.odom_buffer)
        self._twists: deque[tuple[int, float, float]] = deque(maxlen=c.odom_buffer)
        self._join: StampJoin[_Scan, mcv.Decision] = StampJoin(c.odom_buffer)
        self._overflow_seen: dict[str, int] = {}
        self._last_v_mps = 0.0  # what the explorer commanded for the last scan it answered
        self._status = ""
        self.scans_decided = 0
        self.scans_answered = 0
        self.refused_requests = 0
        self.cmd_pub = self.create_publisher(TwistStamped, "cmd_vel", STREAM_QOS)
        self.status_pub = self.create_publisher(String, "explorer/status", LATCHED)
        self.builder_cli = self.create_client(SetParameters, "island_builder/explorer")
        self.add_cli = self.create_client(SetParameters, "topo_graph/add")
        self.exploring = False
        """Subscribed (once the services are up, see wait_for_services)."""
        self.done_future = Future()
        """Done in the callback in which the explorer first says it is done (`done`)."""
        self._publish_status()
        if c.wait_for_services:
            self.get_logger().info(f"waiting for {self.builder_cli.service_name} and "
                                   f"{self.add_cli.service_name} before exploring")
            self._wait_timer = self.create_timer(SERVICE_POLL_S, self._start_when_ready,
                                                 clock=Clock(clock_type=ClockType.STEADY_TIME))
        else:
            self._start()

    @property
    def done(self) -> bool:
        """The explorer says so: no unexplored exit left."""
        return self.explorer.done

    @property
    def bad_msg_count(self) -> int:
        return self._warn.count

    def _start_when_ready(self) -> None:
        if self.exploring or not (self.builder_cli.service_is_ready()
                                  and self.add_cli.service_is_ready()):
            return
        self._wait_timer.cancel()
        self._start()

    def _start(self) -> None:
        self.exploring = True
        # raw: both read from the bytes (island_msgs_py.serialized), without building them
        self.create_subscription(Odometry, "odom", self._on_odom, STREAM_QOS, raw=True)
        self.create_subscription(LaserScan, "sonar/scan", self._on_scan, STREAM_QOS, raw=True)
        self.create_subscription(String, "island_builder/decision", self._on_decision,
                                 DECISION_QOS)
        self.create_subscription(String, "topo_graph/json", self._on_graph, LATCHED)
        self.create_subscription(String, "hall_follower/progress", self._on_progress,
                                 PROGRESS_QOS)
        log_ready(self)

    # --- inputs --------------------------------------------------------------------------------
    def _on_odom(self, data: bytes) -> None:
        try:
            pose, _, t_ns, (v, w) = odometry_cdr_to_pose_twist(data)
            check_stamp(t_ns, clock_ns(self), "odom")
        except ConversionError as exc:
            self._warn("odom", exc)
            return
        self._twists.append((t_ns, v, w))
        self._paired(paired_only(self._pairer.odometry(t_ns, pose)))

    def _on_scan(self, data: bytes) -> None:
        try:
            ranges, angles, t_ns = scan_cdr_to_arrays(data)
            scan = (ranges, angles)
            check_stamp(t_ns, clock_ns(self), "sonar/scan")
        except ConversionError as exc:
            self._warn("sonar/scan", exc)
            return
        self._paired(paired_only(self._pairer.scan(t_ns, scan)))

    def _paired(self, paired: list[Paired[tuple[FloatArray, FloatArray]]]) -> None:
        for p in paired:
            v, w = next(((v, w) for t, v, w in reversed(self._twists) if t <= p.stamp_ns),
                        (0.0, 0.0))
            self._decide(self._join.left(p.stamp_ns,
                                         _Scan(p.payload[0], p.payload[1], p.pose, w, v)))

    def _on_decision(self, msg: String) -> None:
        try:
            d = mcv.msg_to_decision(msg)
        except mcv.ExplorerMessageError as exc:
            self._warn("island_builder/decision", exc)
            return
        self._decide(self._join.right(d.stamp_ns, d))

    def _on_graph(self, msg: String) -> None:
        try:
            self.explorer.on_graph(TopoGraph.from_json(msg.data))
        except (GraphFormatError, GraphError, IslandTypeError) as exc:
            self._warn("topo_graph/json", exc)
        self._note_done()

    def _on_progress(self, msg: String) -> None:
        try:
            self.explorer.on_strategy(ControlStrategy.parse(msg.data))
        except IslandTypeError as exc:
            self._warn("hall_follower/progress", exc)

    # --- one decision per scan, once the builder's verdict on it is in -------------------------
    def _decide(self, joined: list[tuple[int, _Scan, mcv.Decision]]) -> None:
        overflow = (self._join.overflow_left, self._join.overflow_right)
        for t_scan, scan, d in joined:
            self._step(t_scan, scan, d)
        for n, what in zip(overflow, ("sonar/scan", "island_builder/decision"), strict=True):
            for _ in range(n - self._overflow_seen.get(what, 0)):
                self._warn(what, ValueError("no counterpart arrived (scan without the "
                                            "builder's decision or the reverse): dropped"))
            self._overflow_seen[what] = n

    def _step(self, t_ns: int, scan: _Scan, decision: mcv.Decision) -> None:
        self.scans_decided += 1
        blocked = stalled(self._last_v_mps, scan.v_mps)
        self.explorer.on_events(decision.events)
        cmd = self.explorer.step(Sense(t_ns * 1e-9, scan.pose, scan.ranges_m, scan.angles_rad,
                                       scan.w_radps, blocked))
        self._send(cmd.requests)
        self._last_v_mps = cmd.v_mps if cmd.drive else 0.0
        if cmd.drive or decision.mode is CommandMode.IDLE:  # else the builder side answers
            v, w = (cmd.v_mps, cmd.w_radps) if cmd.drive else (0.0, 0.0)
            self.cmd_pub.publish(command_to_twist_stamped(v, w, t_ns, self._base_frame))
            self.scans_answered += 1
        self._publish_status()
        self._note_done()

    def _note_done(self) -> None:
        if self.explorer.done and not self.done_future.done():
            self.done_future.set_result(True)

    # --- outputs -------------------------------------------------------------------------------
    def _send(self, requests: tuple[mcv.ExplorerRequest | ExitUpdate | NewExit, ...]) -> None:
        """The mission's requests: to the builder in order; exits' new states and side exits
        to the map, in order."""
        to_builder = [mcv.request_to_parameter(r) for r in requests
                      if not isinstance(r, ExitUpdate | NewExit)]
        exits = [mcv.graph_item_to_parameter(r) for r in requests
                 if isinstance(r, ExitUpdate | NewExit)]
        for cli, params in ((self.builder_cli, to_builder), (self.add_cli, exits)):
            if params:
                fut = cli.call_async(SetParameters.Request(parameters=params))
                fut.add_done_callback(lambda f, name=cli.service_name: self._on_result(name, f))

    def _on_result(self, service: str, fut: Any) -> None:
        res = fut.result()
        for r in res.results if res is not None else []:
            if not r.successful:
                self.refused_requests += 1
                self.get_logger().warn(f"{service} refused a request: {r.reason}",
                                       throttle_duration_sec=1.0)

    def _publish_status(self) -> None:
        msg = mcv.status_to_msg(self.explorer.status)
        if msg.data == self._status:
            return
        first_done = self.explorer.done and '"done": true' not in self._status
        self._status = msg.data
        self.status_pub.publish(msg)
        if first_done:
            self.get_logger().info(f"exploration done: {self.explorer.status.reason}")


def main(args: Sequence[str] | None = None) -> int:
    return run_node(ExplorerNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
