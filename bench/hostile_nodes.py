"""The node half of bench/hostile_run.py: the six nodes of an exploration, each in its own
process on a private domain, and a probe that sends one hostile message class at a time.

After each case every node must still be alive (deaths), answer a parameter request and, for
the simulator, keep publishing /odom, /sonar/scan and /cmd_vel (silent). Also: a builder
restarted mid-run; the graph server SIGKILLed and restarted on its own
store after hostile requests; a server started on a damaged store exits 2 in one line. Peak
memory per node is its VmHWM.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
NODES = {
    "odometry_node": ("island_sim", ["-p", "sim.real_time_factor:=2.0", "-p", "seed:=5"]),
    "sonar_node": ("island_sim", ["-p", "use_sim_time:=true"]),
    "hall_follower_node": ("island_sim", ["-p", "use_sim_time:=true"]),
    "island_builder_node": ("island_mapping", ["-p", "use_sim_time:=true"]),
    "island_localizer_node": ("island_mapping", ["-p", "use_sim_time:=true"]),
    "topo_graph_server_node": ("island_mapping", []),
}
SERVER_NAME = "topo_graph_server"  # the graph server's ROS node name
FLOWS = ("/odom", "/sonar/scan", "/cmd_vel")
ANSWER_TIMEOUT_S = 10.0
RESTART_TRIES = 4
MEMORY_LIMIT_MIB = 1024.0
FAR_NS = (2**31 - 1) * 10**9


class NodeSet:
    """The node processes, their logs and the probe's view of them."""

    def __init__(self, tmp: Path, env: dict[str, str]) -> None:
        self.tmp, self.env = tmp, env
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        self.peak_mib: dict[str, float] = {}
        self.starts = Counter[str]()

    def start(self, name: str, *extra: str) -> subprocess.Popen[bytes]:
        pkg, args = NODES[name]
        exe = Path(sys.prefix) / "bin" / name
        params = ROOT / "src" / pkg / "config" / f"{name}.yaml"
        self.starts[name] += 1
        log = open(self.tmp / f"{name}.{self.starts[name]}.log", "wb")
        proc = subprocess.Popen([str(exe), "--ros-args", "--params-file", str(params), *args,
                                 *extra], stdout=log, stderr=subprocess.STDOUT, env=self.env)
        self.procs[name] = proc
        return proc

    def sample_memory(self) -> None:
        for name, p in self.procs.items():
            try:
                text = Path(f"/proc/{p.pid}/status").read_text()
            except OSError:
                continue
            kib = next((int(ln.split()[1]) for ln in text.splitlines()
                        if ln.startswith("VmHWM:")), 0)
            self.peak_mib[name] = max(self.peak_mib.get(name, 0.0), kib / 1024.0)

    def dead(self) -> list[str]:
        return [n for n, p in self.procs.items() if p.poll() is not None]

    def stop(self, name: str, sig: int = signal.SIGINT) -> int | None:
        p = self.procs.pop(name)
        p.send_signal(sig)
        try:
            return p.wait(10.0)
        except subprocess.TimeoutExpired:
            p.kill()
            return p.wait()

    def tracebacks(self) -> int:
        return sum(f.read_text(errors="replace").count("Traceback (most recent call last)")
                   for f in self.tmp.glob("*.log"))


def _messages() -> dict[str, Any]:
    from geometry_msgs.msg import TwistStamped
    from island_msgs_py.conversions import command_to_twist_stamped, pose_to_odometry
    from island_msgs_py.types import Pose2D
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan
    from std_msgs.msg import String

    def scan(n: int, t_ns: int = 0, increment: float = 0.01) -> LaserScan:
        msg = LaserScan(angle_increment=increment, range_max=10.0)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 10**9)
        msg.ranges = [1.0] * n
        return msg

    def odom(t_ns: int, nan: bool = False, zero_q: bool = False) -> Odometry:
        msg = pose_to_odometry(Pose2D(5.0, 5.0, 0.0), None, t_ns, "odom")
        if nan:
            msg.pose.pose.position.x = float("nan")
        if zero_q:
            msg.pose.pose.orientation.w = 0.0
            msg.pose.pose.orientation.z = 0.0
        return msg

    event = {"kind": "island_accepted", "island": {"id": 1},
             "anchor_odom": {"x": int("9" * 400), "y": 0, "theta": 0}}
    return {
        "types": {"/cmd_vel": TwistStamped, "/ground_truth": Odometry, "/odom": Odometry,
                  "/sonar/scan": LaserScan, "/island_builder/events": String,
                  "/hall_follower/progress": String},
        "cases": [
            ("cmd_vel stamped 2^31-1 s", "/cmd_vel", [command_to_twist_stamped(0.3, 0, FAR_NS)]),
            ("cmd_vel NaN", "/cmd_vel", [command_to_twist_stamped(float("nan"), 0, 0)]),
            ("ground_truth stamped 2^31-1 s", "/ground_truth", [odom(FAR_NS)]),
            ("ground_truth zero quaternion", "/ground_truth", [odom(0, zero_q=True)]),
            ("odom stamped 2^31-1 s", "/odom", [odom(FAR_NS)]),
            ("odom NaN position", "/odom", [odom(0, nan=True)]),
            ("3 scans of 10^6 ranges", "/sonar/scan", [scan(10**6)] * 3),
            ("scan stamped 2^31-1 s", "/sonar/scan", [scan(16, FAR_NS)]),
            ("scan NaN increment", "/sonar/scan", [scan(16, 0, float("nan"))]),
            ("event 400-digit coordinate", "/island_builder/events", [String(data=json.dumps(
                event))]),
            ("event nested 10^5 deep", "/island_builder/events",
             [String(data="[" * 100_000 + "]" * 100_000)]),
            ("event of 9 MB", "/island_builder/events", [String(data="[" + "1," * 4_500_000
                                                                + "1]")]),
            ("progress Go of 5000 digits", "/hall_follower/progress",
             [String(data="Go " + "9" * 5000)]),
        ],
    }


class Probe:
    """An rclpy node on the nodes' domain: publishes the cases, counts the flows, asks each node
    for a parameter (answers = its executor is alive)."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor

        self.ctx = Context()
        rclpy.init(context=self.ctx)
        self.node = rclpy.create_node("hostile_probe", context=self.ctx)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.seen = Counter[str]()
        self.msgs = _messages()
        self.pubs: dict[str, Any] = {}
        for topic, cls in self.msgs["types"].items():
            from island_msgs_py.qos import LATCHED
            from rclpy.qos import QoSProfile
            qos = LATCHED if topic == "/hall_follower/progress" else QoSProfile(depth=10)
            self.pubs[topic] = self.node.create_publisher(cls, topic, qos)
            if topic in FLOWS:
                self.node.create_subscription(cls, topic, self._counter(topic), 10)

    def _counter(self, topic: str) -> Callable[[Any], None]:
        return lambda _m: self.seen.update([topic])

    def spin(self, seconds: float, until: Callable[[], bool] | None = None) -> bool:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.ex.spin_once(timeout_sec=0.05)
            if until is not None and until():
                return True
        return until is None

    def answers(self, node_name: str) -> bool:
        from rcl_interfaces.srv import ListParameters

        cli = self.node.create_client(ListParameters, f"/{node_name}/list_parameters")
        try:
            if not self.spin(ANSWER_TIMEOUT_S, cli.service_is_ready):
                return False
            fut = cli.call_async(ListParameters.Request())
            return self.spin(ANSWER_TIMEOUT_S, fut.done)
        finally:
            self.node.destroy_client(cli)

    def flows_move(self) -> list[str]:
        """The flows that published nothing new within ANSWER_TIMEOUT_S."""
        before = dict(self.seen)
        self.spin(ANSWER_TIMEOUT_S, lambda: all(self.seen[t] > before.get(t, 0) + 2
                                                for t in FLOWS))
        return [t for t in FLOWS if self.seen[t] <= before.get(t, 0) + 2]

    def close(self) -> None:
        self.ex.shutdown()
        self.node.destroy_node()
        self.ctx.try_shutdown()


def _check(probe: Probe, nodes: NodeSet, case: str, results: list[dict[str, Any]],
           t0: float) -> None:
    nodes.sample_memory()
    dead = nodes.dead()
    silent = [n.replace("topo_graph_server_node", SERVER_NAME) for n in nodes.procs
              if n not in dead
              and not probe.answers(n.replace("topo_graph_server_node", SERVER_NAME))]
    silent += [f"flow {t}" for t in probe.flows_move()]
    results.append({"case": case, "dead": dead, "silent": silent,
                    "seconds": round(time.monotonic() - t0, 2)})
    print(f"  {case:<40} dead={dead} silent={silent} {time.monotonic() - t0:.1f} s", flush=True)
    for name in dead:  # keep the run going for the next cases
        nodes.procs.pop(name)
        nodes.start(name)


def _server_cases(probe: Probe, nodes: NodeSet, results: list[dict[str, Any]], store: Path
                  ) -> None:
    from rcl_interfaces.msg import Parameter, ParameterType
    from rcl_interfaces.srv import SetParameters

    cli = probe.node.create_client(SetParameters, "/topo_graph/add")

    def item(text: str) -> Parameter:
        p = Parameter(name="island")
        p.value.type = ParameterType.PARAMETER_STRING
        p.value.string_value = text
        return p

    island = {"id": 0, "model_type": "line", "r": 1.0, "built_at_s": 0.0,
              "model": {"segments": [[0, 0, 1, 0]]}}
    cases = [("add island id 2^63", [item(json.dumps(dict(island, id=2**63)))]),
             ("add island id 10^30", [item(json.dumps(dict(island, id=10**30)))]),
             ("add coordinate 1e308", [item(json.dumps(dict(island, model={
                 "segments": [[0, 0, 1e308, 0]]})))]),
             ("add 10,000 items", [item(json.dumps(dict(island, id=k))) for k in range(10_000)])]
    probe.spin(ANSWER_TIMEOUT_S, cli.service_is_ready)
    for case, params in cases:
        t0 = time.monotonic()
        fut = cli.call_async(SetParameters.Request(parameters=params))
        probe.spin(30.0, fut.done)
        _check(probe, nodes, case, results, t0)
    t0 = time.monotonic()
    nodes.stop("topo_graph_server_node", signal.SIGKILL)
    nodes.start("topo_graph_server_node", "-p", f"storage_path:={store}")
    # DDS forgets a SIGKILLed process's endpoints only when its lease runs out: a request may
    # go to the dead server first, so the restarted one gets a few chances.
    any(probe.answers(SERVER_NAME) for _ in range(RESTART_TRIES))
    _check(probe, nodes, "server SIGKILLed, restarted on its store", results, t0)


def _damaged_store_case(nodes: NodeSet, store: Path, results: list[dict[str, Any]]) -> None:
    t0 = time.monotonic()
    damaged = store.parent / "damaged_store"
    damaged.mkdir()
    for f in store.iterdir():
        if f.is_file() and f.suffix == ".sqlite3":
            (damaged / f.name).write_bytes(f.read_bytes()[: f.stat().st_size // 2])
    p = nodes.start("topo_graph_server_node", "-p", f"storage_path:={damaged}")
    nodes.procs.pop("topo_graph_server_node")
    rc = p.wait(30.0)
    log = nodes.tmp / f"topo_graph_server_node.{nodes.starts['topo_graph_server_node']}.log"
    ok = rc == 2 and "Traceback" not in log.read_text(errors="replace")
    results.append({"case": "server on a damaged store", "dead": [] if ok else ["server"],
                    "silent": [], "seconds": round(time.monotonic() - t0, 2), "rc": rc})
    print(f"  server on a damaged store: rc={rc}", flush=True)


def run_nodes() -> dict[str, Any]:
    results: list[dict[str, Any]] = []
    domain = random.SystemRandom().randint(150, 200)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    os.environ.update(ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
    with tempfile.TemporaryDirectory(prefix="hostile_nodes_") as tmp:
        d = Path(tmp)
        store = d / "store"
        nodes = NodeSet(d, env)
        for name in NODES:
            extra = ["-p", f"storage_path:={store}"] if name == "topo_graph_server_node" else []
            nodes.start(name, *extra)
        probe = Probe()
        try:
            probe.spin(5.0)
            _check(probe, nodes, "baseline (no hostile input)", results, time.monotonic())
            for case, topic, msgs in probe.msgs["cases"]:
                t0 = time.monotonic()
                for m in msgs:
                    probe.pubs[topic].publish(m)
                probe.spin(1.0)
                _check(probe, nodes, case, results, t0)
            t0 = time.monotonic()
            nodes.stop("island_builder_node")
            nodes.start("island_builder_node")
            probe.spin(3.0)
            _check(probe, nodes, "builder restarted mid-run", results, t0)
            _server_cases(probe, nodes, results, store)
        finally:
            probe.close()
            nodes.sample_memory()
            for name in list(nodes.procs):
                nodes.stop(name)
        _damaged_store_case(nodes, store, results)
        return {
            "cases": len(results),
            "deaths": sum(len(r["dead"]) for r in results),
            "silent": sum(len(r["silent"]) for r in results),
            "tracebacks": nodes.tracebacks(),
            "peak_mib": {k: round(v, 1) for k, v in nodes.peak_mib.items()},
            "over_memory": sum(v > MEMORY_LIMIT_MIB for v in nodes.peak_mib.values()),
            "max_case_seconds": max(r["seconds"] for r in results),
            "results": results,
        }


if __name__ == "__main__":
    print(json.dumps(run_nodes(), indent=1))
