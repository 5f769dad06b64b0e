"""odometry_node: the simulated robot. It owns sim time and steps physics at a fixed dt.

Subscribes  cmd_vel         geometry_msgs/TwistStamped, stamped with the sensor stamp it answers
                            (as Jazzy's diff_drive_controller; NaN/inf ignored with a throttled
                            warning, counted; a command older than one already applied is stale
                            and ignored; stamp 0 = "now", for hand-typed commands)
Publishes   odom            nav_msgs/Odometry  odom -> base_link, drifting pose + its covariance
                            (sim.publish_rate_hz)
            ground_truth    nav_msgs/Odometry  map -> base_link, the true pose (evaluation only;
                            sim.truth_rate_hz)
            /clock          rosgraph_msgs/Clock when sim.own_clock (sim.clock_rate_hz)
Both Odometry topics are written as CDR bytes (island_msgs_py.serialized): the same message.
Names are relative (`--ros-args -r __ns:=/robot1` moves the robot's topics) but for /clock,
which is where every sim-time node's time source listens. `frame_prefix` (e.g. `robot1/`)
prefixes the robot's frames (odom_frame, base_frame), not the shared world frame map_frame.
`sim.real_time_factor`, `sim.lockstep_timeout_s` and `sim.cmd_timeout_s` take effect when set at
run time; every other parameter is read-only.

Pacing: `sim.real_time_factor` simulated seconds per wall second, or 0 = as fast as possible;
the wall clock only decides WHEN to step, every step is one fixed `1 / sim.physics_rate_hz`.
Lockstep (`sim.lockstep`): at every sensor period boundary, after publishing that instant, the
robot waits until it has received a /cmd_vel stamped with that instant (or later) before stepping
on, so controllers always act on the newest scan whatever the DDS timing; after
`sim.lockstep_timeout_s` of wall time without one, it logs and steps on with the last command.
Waiting by stamp, not by counting messages: when two controllers answer one scan (the hall
follower and the island builder at a hand-over) a count would run ahead for good and every later
command would act a period late; a stamp cannot (`island_sim.core.sim_loop.CommandGate`). A
paused hall follower publishes nothing, so in lockstep whoever drives the robot meanwhile must
answer every scan, or each period waits for the timeout.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from geometry_msgs.msg import TwistStamped
from island_msgs_py.conversions import (
    NS_PER_S,
    ConversionError,
    check_stamp,
    twist_stamped_to_command,
)
from island_msgs_py.qos import STREAM_QOS
from island_msgs_py.ros_params import BadMessageLog, declare_config, log_ready, run_node
from island_msgs_py.serialized import pose_to_odometry_cdr
from island_msgs_py.types import Pose2D
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.task import Future
from rosgraph_msgs.msg import Clock

from island_sim.core.robot import OdometryConfig, RobotConfig, SimRobot
from island_sim.core.sim_loop import CommandGate, RealTimePacer, SimClock, SimLoopConfig
from island_sim.core.world_loader import load_world

NODE_NAME = "odometry_node"
WARN_THROTTLE_S = 2.0
# Most physics steps taken in one timer callback, so subscriptions are served in between.
_MAX_STEPS_PER_CALLBACK = 50
# Wall period [s] of the pacing timer when a real-time factor is set.
_PACING_PERIOD_S = 0.005


class OdometryNodeError(ValueError):
    """Bad node parameter (the message names it)."""


@dataclass(frozen=True)
class OdometryNodeConfig:
    """Parameters of odometry_node (nested groups become `sim.*`, `robot.*`, `odometry.*`)."""

    world: str = field(
        default="paper_fig4", metadata={"help": "built-in world name or world file path"}
    )
    seed: int = field(default=0, metadata={"help": "seed of the odometry noise generator [-]"})
    start_pose: str = field(
        default="",
        metadata={"help": "start pose 'x,y,theta' [m, m, rad]; empty = the world's start"},
    )
    odom_frame: str = field(default="odom", metadata={"help": "frame of /odom"})
    map_frame: str = field(default="map", metadata={"help": "frame of /ground_truth"})
    base_frame: str = field(default="base_link", metadata={"help": "robot body frame"})
    frame_prefix: str = field(
        default="",
        metadata={"help": "prepended to the robot's frames (odom_frame, base_frame), e.g. "
                  "'robot1/'; map_frame is the shared world's and stays as it is"},
    )
    sim: SimLoopConfig = field(default_factory=SimLoopConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)


def parse_start_pose(text: str) -> Pose2D | None:
    """'x,y,theta' -> Pose2D; empty -> None; OdometryNodeError naming the parameter otherwise."""
    if not text.strip():
        return None
    try:
        vals = [float(v) for v in text.split(",")]
        if len(vals) != 3:
            raise ValueError
        return Pose2D(*vals)
    except ValueError:
        raise OdometryNodeError(
            f"start_pose: expected 'x,y,theta' with three finite numbers, got {text!r}"
        ) from None


class OdometryNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.cfg = declare_config(self, "", OdometryNodeConfig(), on_change=self._reconfigure)
        sim = self.cfg.sim
        self.world = load_world(self.cfg.world)
        start = parse_start_pose(self.cfg.start_pose) or self.world.start_pose
        self.robot = SimRobot(self.world, start, np.random.default_rng(self.cfg.seed),
                              self.cfg.robot, self.cfg.odometry)
        self.clock = SimClock(sim)
        self._clock_msg = Clock()
        self.gate = CommandGate(sim.lockstep, round(sim.cmd_timeout_s * 1e9))
        self._warn = BadMessageLog(self)
        self.lockstep_timeouts = 0
        self.finished_future = Future()
        """Done (with the sim time [ns]) at the step that reaches `sim.stop_after_s`: an
        executor can spin until it, e.g. `spin_until_future_complete`."""
        self._wait_since = 0.0
        self._started = not sim.lockstep
        self._created = time.monotonic()
        self._pacer = (
            RealTimePacer(sim.real_time_factor, sim.dt_ns, _MAX_STEPS_PER_CALLBACK)
            if sim.real_time_factor > 0 else None
        )
        self.odom_pub = self.create_publisher(Odometry, "odom", STREAM_QOS)
        self.truth_pub = self.create_publisher(Odometry, "ground_truth", STREAM_QOS)
        self.clock_pub = (
            self.create_publisher(Clock, "/clock", STREAM_QOS) if sim.own_clock else None
        )
        self.create_subscription(TwistStamped, "cmd_vel", self._on_cmd, STREAM_QOS)
        self.timer = self.create_timer(self._timer_period_s(), self._on_timer)
        self.create_timer(0.05, self._check_lockstep_timeout)
        self.get_logger().info(
            f"world {self.world.name!r} ({self.world.segments.shape[0]} walls), start {start}, "
            f"{sim.physics_rate_hz:g} Hz physics, rtf {sim.real_time_factor:g}, "
            f"lockstep {sim.lockstep}"
        )
        log_ready(self)

    # --- parameters set at run time ------------------------------------------------------------
    def _timer_period_s(self) -> float:
        return _PACING_PERIOD_S if self.cfg.sim.real_time_factor > 0 else 0.0

    def _reconfigure(self, cfg: OdometryNodeConfig) -> None:
        """Apply the live parameters (the others are read-only): pacing, lockstep timeout (read
        where it is used) and the command timeout."""
        self.cfg = cfg
        rtf = cfg.sim.real_time_factor
        self._pacer = (RealTimePacer(rtf, cfg.sim.dt_ns, _MAX_STEPS_PER_CALLBACK)
                       if rtf > 0 else None)
        self.timer.timer_period_ns = round(self._timer_period_s() * 1e9)
        self.gate.cmd_timeout_ns = round(cfg.sim.cmd_timeout_s * 1e9)

    # --- inputs --------------------------------------------------------------------------------
    def _on_cmd(self, msg: TwistStamped) -> None:
        try:
            v, w, stamp_ns = twist_stamped_to_command(msg)
            check_stamp(stamp_ns, self.sim_time_ns, "cmd_vel")
        except ConversionError as exc:
            self._warn("cmd_vel", exc)
            return
        if self.gate.offer(v, w, stamp_ns, self.sim_time_ns):  # the awaited answer came
            if self.cfg.sim.real_time_factor > 0:
                self.timer.reset()
            else:
                self._on_timer()  # as fast as possible: step on now, saving an executor cycle
                if self.gate.waiting_for_ns is None and not self.finished:
                    self.timer.reset()

    # --- stepping ------------------------------------------------------------------------------
    @property
    def sim_time_ns(self) -> int:
        return self.clock.sim_time_ns

    @property
    def step_count(self) -> int:
        return self.clock.step_count

    @property
    def finished(self) -> bool:
        return self.clock.finished

    @property
    def bad_cmd_count(self) -> int:
        """/cmd_vel messages ignored as bad (NaN or infinite) so far."""
        return self._warn.count

    @property
    def cmd_count(self) -> int:
        """Commands taken (stale and malformed ones not counted)."""
        return self.gate.taken

    def _ready_to_start(self) -> bool:
        """Lockstep starts once the controller and the sensor are connected (or after timeout)."""
        connected = (
            self.count_publishers("cmd_vel") > 0
            and self.truth_pub.get_subscription_count() > 0
            and self.odom_pub.get_subscription_count() > 0
        )
        waited = time.monotonic() - self._created > self.cfg.sim.lockstep_timeout_s
        if waited and not connected:
            self.get_logger().warn("lockstep: no controller/sensor connected, starting anyway")
        return connected or waited

    def _on_timer(self) -> None:
        if self.gate.waiting_for_ns is not None:
            self.timer.cancel()
            return
        if not self._started:
            if not self._ready_to_start():
                return
            self._started = True
            self._publish()
            if self._boundary_wait():
                return
        if self._pacer is not None:
            budget = self._pacer.steps_due(time.monotonic(), self.clock.step_count)
        else:
            budget = min(_MAX_STEPS_PER_CALLBACK, self.clock.steps_per_period)
        for _ in range(budget):
            if self.clock.finished:
                self.timer.cancel()
                return
            v, w = self.gate.current(self.clock.sim_time_ns)
            self.robot.step(v, w, self.clock.dt_ns * 1e-9)
            if self.clock.advance():
                self._publish()
            if self.clock.finished and not self.finished_future.done():
                self.finished_future.set_result(self.clock.sim_time_ns)
            if self._boundary_wait():
                return

    def _boundary_wait(self) -> bool:
        """At a sensor boundary in lockstep, wait for that period's command; True if waiting."""
        if not self.clock.at_boundary or not self.gate.must_wait(self.clock.sim_time_ns):
            return False
        self._wait_since = time.monotonic()
        self.timer.cancel()
        return True

    def _check_lockstep_timeout(self) -> None:
        if self.gate.waiting_for_ns is None:
            return
        if time.monotonic() - self._wait_since > self.cfg.sim.lockstep_timeout_s:
            self.lockstep_timeouts += 1
            self.get_logger().warn(
                f"lockstep: no /cmd_vel for the scan at {self.gate.waiting_for_ns} ns within "
                f"{self.cfg.sim.lockstep_timeout_s:g} s wall; stepping on with the last command "
                f"({self.lockstep_timeouts} timeouts)",
                throttle_duration_sec=WARN_THROTTLE_S,
            )
            self.gate.give_up()
            self.timer.reset()

    def _publish(self) -> None:
        t_ns = self.sim_time_ns
        if self.clock_pub is not None and self.clock.due(self.clock.steps_per_clock):
            self._clock_msg.clock.sec = int(t_ns // NS_PER_S)
            self._clock_msg.clock.nanosec = int(t_ns % NS_PER_S)
            self.clock_pub.publish(self._clock_msg)
        vel = self.robot.velocity
        c = self.cfg
        base, odom = c.frame_prefix + c.base_frame, c.frame_prefix + c.odom_frame
        # Serialized here (island_msgs_py.serialized): the same message as fill_odometry, without
        # building rclpy's message objects at every physics step.
        if self.clock.due(self.clock.steps_per_truth):
            self.truth_pub.publish(pose_to_odometry_cdr(self.robot.true_pose, None, t_ns,
                                                        c.map_frame, base, vel))
        self.odom_pub.publish(pose_to_odometry_cdr(self.robot.odom_pose,
                                                   self.robot.odom_covariance, t_ns, odom, base,
                                                   vel))


def main(args: Sequence[str] | None = None) -> int:
    return run_node(OdometryNode, NODE_NAME, args)


if __name__ == "__main__":
    sys.exit(main())
