"""island_localizer_node runs on a robot without the simulator: island_sim cannot be imported.

A fresh interpreter blocks every `island_sim` import on sys.meta_path, creates the node on its
own rclpy Context, feeds it an accepted island, odometry and scans of a room, and must receive
an /island_pose in the island's frame at the robot's pose there.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

# The robot stands here in the island frame (the island origin is the odometry origin) [m, rad].
ROBOT = (1.0, 0.5, 0.3)

SCRIPT = textwrap.dedent(
    """
    import importlib.abc, json, math, sys, time

    class BlockSimulator(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name == "island_sim" or name.startswith("island_sim."):
                raise ModuleNotFoundError(f"blocked: {name}", name=name)
            return None

    sys.meta_path.insert(0, BlockSimulator())
    try:
        import island_sim  # noqa: F401
        sys.exit("the island_sim blocker does not work")
    except ModuleNotFoundError:
        pass

    import numpy as np
    import rclpy
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from island_mapping.nodes.island_localizer_node import IslandLocalizerNode
    from island_msgs_py import json_io
    from island_msgs_py.conversions import (
        arrays_to_scan, pose_to_odometry, pose_with_covariance_stamped_to_pose2d)
    from island_msgs_py.qos import STREAM_QOS
    from island_msgs_py.raycast import raycast
    from island_msgs_py.types import Island, LineModel, ModelType, Pose2D
    from nav_msgs.msg import Odometry
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import String

    ROBOT = Pose2D(*json.loads(sys.argv[1]))
    # A 6 m x 4 m room around the island origin: constrained along both axes.
    room = np.array([[-2.0, -1.5, 4.0, -1.5], [4.0, -1.5, 4.0, 2.5],
                     [4.0, 2.5, -2.0, 2.5], [-2.0, 2.5, -2.0, -1.5]])
    island = Island(7, LineModel(room), ModelType.LINE, 1.0, 0.0)
    angles = np.arange(36) * (2.0 * math.pi / 36)
    ranges = raycast(room, [[ROBOT.x, ROBOT.y]], angles + ROBOT.theta).distance_m

    ctx = Context()
    rclpy.init(context=ctx)
    node = IslandLocalizerNode(context=ctx)
    probe = Node("localizer_without_sim_probe", context=ctx)
    events = probe.create_publisher(String, "/island_builder/events", STREAM_QOS)
    odom = probe.create_publisher(Odometry, "/odom", STREAM_QOS)
    scans = probe.create_publisher(LaserScan, "/sonar/scan", STREAM_QOS)
    got = []
    probe.create_subscription(PoseWithCovarianceStamped, "/island_pose", got.append, STREAM_QOS)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    ex.add_node(probe)

    def spin_until(cond, timeout_s):
        deadline = time.monotonic() + timeout_s
        while not cond() and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.02)
        return cond()

    pubs = (events, odom, scans)
    assert spin_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs), 20.0)
    assert spin_until(lambda: probe.count_publishers("/island_pose") >= 1, 20.0)
    accepted = {"kind": "island_accepted", "island": json_io.island_to_dict(island),
                "anchor_odom": json_io.pose_to_dict(Pose2D(0.0, 0.0, 0.0))}
    events.publish(String(data=json.dumps(accepted)))
    assert spin_until(lambda: node.tracker.nearest(ROBOT) == 7, 10.0)
    for k in range(1, 12):  # scans paired with the odometry of their own stamps
        t_ns = k * 100_000_000
        odom.publish(pose_to_odometry(ROBOT, None, t_ns, "odom"))
        scans.publish(arrays_to_scan(ranges, angles, (0.1, 10.0), t_ns))
        spin_until(lambda: False, 0.05)
    odom.publish(pose_to_odometry(ROBOT, None, 12 * 100_000_000, "odom"))
    ok = spin_until(lambda: len(got) >= 1, 20.0)
    pose, _, frame = pose_with_covariance_stamped_to_pose2d(got[0]) if ok else (None, None, "")
    print(json.dumps({
        "received": ok,
        "frame": frame,
        "pose": [pose.x, pose.y, pose.theta] if ok else None,
        "bad_messages": node.bad_msg_count,
        "sim_modules": sorted(m for m in sys.modules if m.split(".")[0] == "island_sim"),
    }))
    ex.shutdown()
    node.destroy_node()
    probe.destroy_node()
    ctx.try_shutdown()
    """
)


def test_localizer_node_publishes_island_poses_with_island_sim_absent() -> None:
    out = subprocess.run(
        [sys.executable, "-c", SCRIPT, json.dumps(ROBOT)],
        capture_output=True, text=True, timeout=180, check=False,
    )
    assert out.returncode == 0, out.stderr[-3000:]
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["sim_modules"] == []
    assert res["received"], "no /island_pose within 20 s"
    assert res["frame"] == "island_7"
    x, y, theta = res["pose"]
    assert abs(x - ROBOT[0]) < 0.05 and abs(y - ROBOT[1]) < 0.05
    assert abs(theta - ROBOT[2]) < 0.02
    assert res["bad_messages"] == 0
