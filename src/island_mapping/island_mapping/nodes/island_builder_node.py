"""island_builder_node: builds islands of reliability while the hall follower explores (eq. 3).

Subscribes  odom                     nav_msgs/Odometry (pose + covariance: epsilon); each scan
                                     is decided with the odometry of its own stamp
            sonar/scan               sensor_msgs/LaserScan
            hall_follower/progress   std_msgs/String, the executed strategy so far
            ground_truth             nav_msgs/Odometry, only to stamp islands' origin_truth
Publishes   cmd_vel                  geometry_msgs/TwistStamped (the scan's stamp), one per scan
                                     while the builder drives
            island_builder/events    std_msgs/String, one JSON object per builder event
Calls       hall_follower/enable (SetBool), hall_follower/reset (Trigger),
            topo_graph/add (rcl_interfaces/SetParameters: `island`, `edge` and, managed,
            `exit` JSON strings)
All service calls are asynchronous; the executor is never blocked. The decisions are in
island_mapping.core.builder; localization in the islands is island_localizer_node.

Managed mode (`managed`, read-only; exploration by the map, issue 16: an explorer_node drives
between islands): the builder installs the explorer's hooks (`core.explore.explorer_hooks`
with the `explorer.*` parameters: exits found at acceptance, the revisit gate), hands back at an
island by going idle (the follower stays paused, the explorer answers the scans), and adds:
Publishes   island_builder/decision  std_msgs/String JSON, one per scan decided: `{"stamp_ns",
                                     "mode": follow|drive|idle, "events": [...]}` (the
                                     explorer pairs it with the scan of that stamp)
Services    island_builder/explorer  rcl_interfaces/SetParameters, the explorer's requests in
                                     order: `docked` {"island", "origin_odom"}, `handover`
                                     {"island", "exit", "prefix"}, `abort` {}; one result per
                                     item, a refused one with its reason (logged)
The builder alone owns the hall follower in both modes: it pauses it while it drives or idles
and, at a handover, restarts its record and resumes it.

Names are relative to the node's namespace. Start-up: with `wait_for_services` (the default) the
builder subscribes only once the hall follower's services and topo_graph/add are up, so whatever
order the nodes start in, it maps from where the robot stands when they all are (the follower
holds the robot still until the builder claims it) and no island is sent to a server that is not
there yet. Every `builder.*` parameter is read-only (fixed for a run).
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from geometry_msgs.msg import TwistStamped
from island_msgs_py.conversions import (
    ConversionError,
    check_stamp,
    command_to_twist_stamped,
)
from island_msgs_py.qos import STREAM_QOS
from island_msgs_py.ros_params import (
    BadMessageLog,
    clock_ns,
    declare_config,
    log_ready,
    run_node,
)
from island_msgs_py.serialized import odometry_cdr_to_pose, scan_cdr_to_arrays
from island_msgs_py.stamps import ScanOdomPairer
from island_msgs_py.types import ControlStrategy, IslandTypeError
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

from island_mapping import conversions as mcv
from island_mapping.core import builder as core
from island_mapping.core.builder import BuilderEvent, CommandMode, EventKind
from island_mapping.core.builder.hooks import graph_items
from island_mapping.core.builder.inputs import (
    GROUND_TRUTH,
    ScanArrays,
    checked_cov,
    checked_scan,
    feed,
)
from island_mapping.core.explore import (
    ExplorerConfig,
    FollowerAction,
    apply_to_builder,
    explorer_hooks,
)
from island_mapping.core.graph import TopoGraph

NODE_NAME = "island_builder_node"
ODOM_BUFFER = 200  # stamps kept for pairing scans with odometry (4 s at 50 Hz)
BASE_FRAME = "base_link"  # the robot frame /cmd_vel is in (after frame_prefix)
SERVICE_POLL_S = 0.1  # how often (wall clock) to look for the services mapping waits for
WARN_THROTTLE_S = 1.0  # refused explorer requests are logged at most this often [s]
PROGRESS_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
"""The follower's record: only the newest matters (`set_strategy` overwrites)."""


@dataclass(frozen=True)
class IslandBuilderNodeConfig:
    """Parameters of island_builder_node beside the builder's own (`builder.*`)."""

    wait_for_services: bool = field(
        default=True,
        metadata={"help": "subscribe (start mapping) only once hall_follower/enable, "
                  "hall_follower/reset and topo_graph/add are up; false = at once (replays, "
                  "which answer no follower calls) [bool]"},
    )
    frame_prefix: str = field(
        default="", metadata={"help": "prepended to the cmd_vel frame base_link, e.g. 'robot1/'"}
    )
    managed: bool = field(
        default=False,
        metadata={"help": "an explorer_node drives between islands: hand back at an island by "
                  "going idle, take its requests on island_builder/explorer, publish "
                  "island_builder/decision; false = the paper's plain hall following [bool]"},
    )


class IslandBuilderNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.node_cfg = declare_config(self, "", IslandBuilderNodeConfig())
        self.cfg = declare_config(self, "builder", core.BuilderConfig())
        self.explorer_cfg = declare_config(self, "explorer", ExplorerConfig())
        managed = self.node_cfg.managed
        hooks = explorer_hooks(self.explorer_cfg, TopoGraph) if managed else None
        self.builder = core.IslandBuilder(self.cfg, hooks=hooks)
        self.refused_requests = 0
        """Explorer requests refused so far (malformed, or the builder could not take them)."""
        self._warn = BadMessageLog(self)
        # Confirmed state of the hall follower; None until the builder has claimed it.
        self.follower_enabled: bool | None = None
        self._enable_pending: bool | None = None
        self._base_frame = self.node_cfg.frame_prefix + BASE_FRAME
        self.pairer: ScanOdomPairer[ScanArrays] = ScanOdomPairer(
            ODOM_BUFFER, every_odometry=True, streams=(GROUND_TRUTH,))
        self.cmd_pub = self.create_publisher(TwistStamped, "cmd_vel", STREAM_QOS)
        self.event_pub = self.create_publisher(String, "island_builder/events", STREAM_QOS)
        self.enable_cli = self.create_client(SetBool, "hall_follower/enable")
        self.reset_cli = self.create_client(Trigger, "hall_follower/reset")
        self.add_cli = self.create_client(SetParameters, "topo_graph/add")
        if managed:
            self.decision_pub = self.create_publisher(String, "island_builder/decision",
                                                      STREAM_QOS)
            self.create_service(SetParameters, "island_builder/explorer", self._on_explorer)
        self.mapping = False
        """Subscribed to the robot's topics (once the services are up, see wait_for_services)."""
        if self.node_cfg.wait_for_services:
            self.get_logger().info(
                f"waiting for {self.enable_cli.service_name}, {self.reset_cli.service_name} "
                f"and {self.add_cli.service_name} before mapping")
            self._wait_timer = self.create_timer(SERVICE_POLL_S, self._start_when_ready,
                                                 clock=Clock(clock_type=ClockType.STEADY_TIME))
        else:
            self._start_mapping()

    # --- start-up: map only once the follower and the graph server are there ------------------
    def _start_when_ready(self) -> None:
        clients = (self.enable_cli, self.reset_cli, self.add_cli)
        if self.mapping or not all(c.service_is_ready() for c in clients):
            return
        self._wait_timer.cancel()
        self._start_mapping()

    def _start_mapping(self) -> None:
        self.mapping = True
        # raw: read from the bytes (island_msgs_py.serialized), without building the messages
        self.create_subscription(Odometry, "odom", self._on_odom, STREAM_QOS, raw=True)
        self.create_subscription(Odometry, "ground_truth", self._on_truth, STREAM_QOS, raw=True)
        self.create_subscription(LaserScan, "sonar/scan", self._on_scan, STREAM_QOS, raw=True)
        self.create_subscription(String, "hall_follower/progress", self._on_strategy,
                                 PROGRESS_QOS)
        log_ready(self)

    @property
    def bad_msg_count(self) -> int:
        """Messages ignored as bad so far."""
        return self._warn.count

    # --- inputs: each scan meets the odometry and ground truth of its stamp, after every
    # odometry increment up to it (island_msgs_py.stamps.ScanOdomPairer, every_odometry) -----
    def _on_odom(self, data: bytes) -> None:
        try:
            pose, cov, t_ns = odometry_cdr_to_pose(data)
            check_stamp(t_ns, clock_ns(self), "odom")
            released = self.pairer.odometry(t_ns, pose, checked_cov(t_ns * 1e-9, cov))
            self._act(feed(self.builder, released))
        except (ConversionError, ValueError) as exc:
            self._warn("odom", exc)

    def _on_truth(self, data: bytes) -> None:
        try:
            pose, _, t_ns = odometry_cdr_to_pose(data)
            check_stamp(t_ns, clock_ns(self), "ground_truth")
            self._act(feed(self.builder, self.pairer.stream(GROUND_TRUTH, t_ns, pose)))
        except (ConversionError, ValueError) as exc:
            self._warn("ground_truth", exc)

    def _on_strategy(self, msg: String) -> None:
        try:
            self.builder.set_strategy(ControlStrategy.parse(msg.data))
        except IslandTypeError as exc:
            self._warn("hall_follower/progress", exc)

    def _on_scan(self, data: bytes) -> None:
        try:
            ranges, angles, t_ns = scan_cdr_to_arrays(data)
            check_stamp(t_ns, clock_ns(self), "sonar/scan")
            scan = checked_scan(t_ns * 1e-9, ranges, angles)
            self._act(feed(self.builder, self.pairer.scan(t_ns, scan)))
        except (ConversionError, ValueError) as exc:
            self._warn("sonar/scan", exc)

    # --- one decision per scan ----------------------------------------------------------------
    def _act(self, commands: list[tuple[int, core.BuilderCommand]]) -> None:
        for t_ns, cmd in commands:
            for e in cmd.events:
                self._handle_event(e)
            if self.node_cfg.managed:
                self.decision_pub.publish(mcv.decision_to_msg(t_ns, cmd.mode, cmd.events))
            if cmd.mode is CommandMode.IDLE:  # managed: the explorer answers this scan
                self._set_follower(False)
            elif cmd.mode is CommandMode.DRIVE:
                self._set_follower(False)
                self.cmd_pub.publish(command_to_twist_stamped(cmd.v_mps, cmd.w_radps, t_ns,
                                                              self._base_frame))
            else:
                if not self.follower_enabled:  # until it confirms, keep the lockstep fed
                    self.cmd_pub.publish(command_to_twist_stamped(0.0, 0.0, t_ns,
                                                                  self._base_frame))
                if self._enable_pending is None and not self.follower_enabled:
                    self._set_follower(True)

    def _handle_event(self, e: BuilderEvent) -> None:
        self.event_pub.publish(String(data=json.dumps(core.event_to_dict(e))))
        if e.kind is EventKind.ISLAND_ACCEPTED and e.island is not None:
            self.get_logger().info(f"island {e.island.id} accepted ({e.island.model_type.value}, "
                                   f"measure {e.measure:.2f} > bound {e.bound:.2f})")
        if e.kind is EventKind.ISLAND_REVISITED and e.edge is not None:
            self.get_logger().info(f"island {e.revisited_island_id} revisited: edge "
                                   f"{e.edge.source}->{e.edge.target}")
        items = graph_items(e)  # the island, its edge, the exits the edge explored, in order
        if items:
            req = SetParameters.Request()
            req.parameters = [mcv.graph_item_to_parameter(item) for item in items]
            self.add_cli.call_async(req).add_done_callback(self._on_added)
        if e.kind is EventKind.HANDED_BACK and e.accepted_island_id is not None:
            if self.node_cfg.managed:  # the explorer drives on: restart the record, stay paused
                self.reset_cli.call_async(Trigger.Request()).add_done_callback(
                    lambda f: self._on_reset(f, resume=False))
                return
            # At a new or revisited island's origin: the follower's record restarts, it resumes.
            self._restart_follower()

    def _restart_follower(self) -> None:
        """Restart the follower's record (it is paused) and resume it."""
        self._enable_pending = True
        self.reset_cli.call_async(Trigger.Request()).add_done_callback(self._on_reset)

    # --- the explorer's requests (managed mode) -----------------------------------------------
    def _on_explorer(self, request: SetParameters.Request,
                     response: SetParameters.Response) -> Any:
        """Apply the explorer's requests in order; a refused one says why (and is logged)."""
        for k, param in enumerate(request.parameters):
            try:
                reason = self._apply_request(mcv.parameter_to_request(param, f"parameters[{k}]"))
                ok = True
            except (mcv.ExplorerMessageError, core.BuilderError) as exc:
                ok, reason = False, str(exc)
            if not ok:
                self.refused_requests += 1
                self.get_logger().warn(f"island_builder/explorer refused parameters[{k}]: "
                                       f"{reason}", throttle_duration_sec=WARN_THROTTLE_S)
            response.results.append(SetParametersResult(successful=ok, reason=reason))
        return response

    def _apply_request(self, r: mcv.ExplorerRequest) -> str:
        """One request to the builder (`core.explore.apply_to_builder`); BuilderError when it
        cannot take it."""
        done = apply_to_builder(self.builder, r)
        if done.follower is FollowerAction.STOP:
            self._set_follower(False)
        elif done.follower is FollowerAction.RESTART:
            self._restart_follower()
        return done.message

    def _on_reset(self, fut: Any, resume: bool = True) -> None:
        """The follower's record restarted (it refuses while following: say so); resume it."""
        res = fut.result()
        if res is None or not res.success:
            why = res.message if res is not None else "no answer"
            self.get_logger().warn(f"{self.reset_cli.service_name} failed: {why}")
        if resume:
            self._send_enable(True)

    def _on_added(self, fut: Any) -> None:
        res = fut.result()
        for r in res.results if res is not None else []:
            if not r.successful:
                name = self.resolve_service_name("topo_graph/add")
                self.get_logger().warn(f"{name} rejected an item: {r.reason}")

    def _set_follower(self, enabled: bool) -> None:
        if self._enable_pending == enabled or (
            self._enable_pending is None and self.follower_enabled == enabled
        ):
            return
        self._enable_pending = enabled
        self._send_enable(enabled)

    def _send_enable(self, enabled: bool) -> None:
        fut = self.enable_cli.call_async(SetBool.Request(data=enabled))
        fut.add_done_callback(lambda f: self._on_enabled(enabled, f))

    def _on_enabled(self, enabled: bool, fut: Any) -> None:
        if fut.result() is not None and fut.result().success:
            self.follower_enabled = enabled
        if self._enable_pending == enabled:
            self._enable_pending = None


def main(args: Sequence[str] | None = None) -> int:
    return run_node(IslandBuilderNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
