"""Real-time factor of the three simulator nodes in one process on sim time (goal: >= 20x).

  python bench/bench_sim_rtf.py [--sim-seconds 60] [--world paper_fig4]

odometry_node (50 Hz physics, /odom + /ground_truth + /clock at --publish-rate-hz, default 50),
sonar_node (10 Hz, use_sim_time) and hall_follower_node (use_sim_time) share one
SingleThreadedExecutor; the robot runs as fast as possible (real_time_factor 0). Variants, side by
side in this one run:
- lockstep: the robot waits for each period's /cmd_vel (closed loop, deterministic);
- lockstep, lean: the same without the nodes' parameter services (fewer wait-set entities);
- lockstep, odom at 10 Hz: /odom, /ground_truth and /clock only at the sensor rate;
- free-running: no lockstep; the physics does not wait, so the consumers drop messages (the
  scans and commands actually processed are printed);
- core only: the same robot/sonar/follower loop without ROS, for reference.
RTF = simulated seconds / wall seconds; CPU RTF = simulated seconds / process CPU seconds (the
machine is shared, so wall time includes other processes' load).
"""

from __future__ import annotations

import argparse
import os
import random
import time
from typing import Any

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 101)))

import rclpy
from island_msgs_py.ros_params import ensure_ros_env
from island_sim.nodes.hall_follower_node import HallFollowerNode
from island_sim.nodes.odometry_node import OdometryNode
from island_sim.nodes.sonar_node import SonarNode
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

GOAL_RTF = 20.0


def run(world: str, sim_s: float, lockstep: bool, publish_hz: float, lean: bool) -> dict[str, Any]:
    ctx = Context()
    rclpy.init(context=ctx)
    kw: dict[str, Any] = {"start_parameter_services": False} if lean else {}
    p = Parameter
    common = [p("start_type_description_service", value=not lean)]
    odo = OdometryNode(context=ctx, parameter_overrides=[
        *common, p("world", value=world), p("sim.real_time_factor", value=0.0),
        p("sim.lockstep", value=lockstep), p("sim.stop_after_s", value=sim_s),
        p("sim.publish_rate_hz", value=publish_hz)], **kw)
    sonar = SonarNode(context=ctx, parameter_overrides=[
        *common, p("use_sim_time", value=True), p("world", value=world)], **kw)
    follower = HallFollowerNode(context=ctx, parameter_overrides=[
        *common, p("use_sim_time", value=True), p("autostart", value=True)], **kw)
    ex = SingleThreadedExecutor(context=ctx)
    for n in (odo, sonar, follower):
        ex.add_node(n)
    t0, c0 = time.monotonic(), time.process_time()
    while not odo.finished:
        ex.spin_once(timeout_sec=0.05)
    wall, cpu = time.monotonic() - t0, time.process_time() - c0
    out = {
        "wall_s": wall, "cpu_s": cpu, "rtf": sim_s / wall, "cpu_rtf": sim_s / cpu,
        "scans": sonar.scans_published, "processed": follower.scans_processed,
        "cmds": odo.cmd_count, "collisions": odo.robot.collisions,
        "timeouts": odo.lockstep_timeouts,
    }
    ex.shutdown()
    for n in (odo, sonar, follower):
        n.destroy_node()
    ctx.try_shutdown()
    return out


def run_core(world_name: str, sim_s: float) -> dict[str, Any]:
    """The same loop without ROS: SimRobot at 50 Hz, SonarModel + HallFollower at 10 Hz."""
    import numpy as np
    from island_sim.core.hall_follower import HallFollower
    from island_sim.core.robot import SimRobot
    from island_sim.core.sonar import SonarModel
    from island_sim.core.world_loader import load_world

    world = load_world(world_name)
    rng = np.random.default_rng(0)
    robot = SimRobot(world, world.start_pose, rng)
    sonar, follower = SonarModel(), HallFollower()
    v = w = 0.0
    t0, c0 = time.monotonic(), time.process_time()
    for k in range(round(sim_s * 50)):
        if k % 5 == 0:
            ranges = sonar.scan(world, robot.true_pose, rng)
            v, w = follower.update(ranges, sonar.angles_rad, robot.odom_pose, robot.time_s)
        robot.step(v, w, 0.02)
    wall, cpu = time.monotonic() - t0, time.process_time() - c0
    n = round(sim_s * 10)
    return {"wall_s": wall, "rtf": sim_s / wall, "cpu_rtf": sim_s / cpu, "processed": n,
            "scans": n, "timeouts": 0}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim-seconds", type=float, default=60.0)
    ap.add_argument("--world", default="paper_fig4")
    ap.add_argument("--publish-rate-hz", type=float, default=50.0)
    args = ap.parse_args()
    ensure_ros_env()
    variants = [
        ("lockstep", True, args.publish_rate_hz, False),
        ("lockstep, lean", True, args.publish_rate_hz, True),
        ("lockstep, lean, odom 10 Hz", True, 10.0, True),
        ("free-running", False, args.publish_rate_hz, False),
    ]
    print(f"{args.world}: {args.sim_seconds:g} s simulated, physics 50 Hz, sonar 10 Hz, "
          f"goal {GOAL_RTF:g}x real time, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.1f}")
    print(f"{'variant':30s} {'wall s':>7s} {'RTF':>6s} {'/goal':>6s} {'CPU RTF':>8s} "
          f"{'scans used/made':>15s} {'timeouts':>8s}")
    rows = [(name, lambda v=v: run(args.world, args.sim_seconds, *v)) for name, *v in variants]
    rows.append(("core only, no ROS (reference)", lambda: run_core(args.world, args.sim_seconds)))
    for name, fn in rows:
        r = fn()
        print(f"{name:30s} {r['wall_s']:7.1f} {r['rtf']:6.1f} {r['rtf'] / GOAL_RTF:6.2f} "
              f"{r['cpu_rtf']:8.1f} {r['processed']:7d}/{r['scans']:<7d} {r['timeouts']:8d}")


if __name__ == "__main__":
    main()
