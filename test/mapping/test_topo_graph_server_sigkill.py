"""Persistence across SIGKILL: server in a subprocess; every acknowledged island survives."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from island_mapping.core.graph import GraphStore, TopoGraph
from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType
from rcl_interfaces.srv import SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from island_msgs_py import conversions as cv

pytestmark = pytest.mark.slow


def _island(i: int) -> Island:
    rng = np.random.default_rng(100 + i)
    return Island(i, LineModel(rng.uniform(-4, 4, (12, 4))), ModelType.LINE, 0.6, float(i))


def _start(storage: Path, log: Path) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "island_mapping.nodes.topo_graph_server_node", "--ros-args",
           "-p", f"storage_path:={storage}"]
    with open(log, "ab") as out:
        return subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, env=dict(os.environ))


def _kill(proc: subprocess.Popen[bytes]) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)


def _call(ex: SingleThreadedExecutor, client: Any, request: Any, log: Path,
          timeout_s: float = 30.0) -> Any:
    """Call until a server answers, resending after 1 s without an answer. After a SIGKILL, DDS
    still lists the dead server for a while and a request sent before the new server is matched
    is lost; resending is safe because every request here is idempotent (add-or-replace, get)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if not client.service_is_ready():
            ex.spin_once(timeout_sec=0.05)
            continue
        fut = client.call_async(request)
        attempt_end = time.monotonic() + 1.0
        while not fut.done() and time.monotonic() < attempt_end:
            ex.spin_once(timeout_sec=0.05)
        if fut.done():
            return fut.result()
    raise AssertionError(f"graph server never answered; its log:\n{log.read_text()}")


def test_acknowledged_islands_survive_sigkill(
    ros_context: Any, tmp_path: Path
) -> None:
    storage, log = tmp_path / "store", tmp_path / "server.log"
    node = Node("sigkill_client", context=ros_context)
    ex = SingleThreadedExecutor(context=ros_context)
    ex.add_node(node)
    add = node.create_client(SetParameters, "/topo_graph/add")
    get = node.create_client(Trigger, "/topo_graph/get")
    acked: list[Island] = []
    acked_edges: list[Edge] = []
    procs: list[subprocess.Popen[bytes]] = []
    try:
        next_id = 0
        for round_ in range(2):
            proc = _start(storage, log)
            procs.append(proc)
            _call(ex, get, Trigger.Request(), log)  # the new server is up and answering
            for _ in range(9):  # 9 islands per round, each linked to the previous one
                isl = _island(next_id)
                params = [cv.island_to_parameter(isl)]
                e = None
                if next_id:
                    e = Edge(next_id - 1, next_id, ControlStrategy.parse(f"Go {100 + next_id}"),
                             1.0 + next_id)
                    params.append(cv.edge_to_parameter(e))
                res = _call(ex, add, SetParameters.Request(parameters=params), log)
                assert all(r.successful for r in res.results), res.results
                acked.append(isl)
                if e is not None:
                    acked_edges.append(e)
                next_id += 1
            # one more request in flight, then SIGKILL right after the last acknowledgement
            add.call_async(SetParameters.Request(parameters=[cv.island_to_parameter(
                _island(1000 + round_))]))
            ex.spin_once(timeout_sec=0.0)
            _kill(proc)
        procs.append(_start(storage, log))
        graph = TopoGraph.from_json(_call(ex, get, Trigger.Request(), log).message)
        for isl in acked:
            assert graph.get_island(isl.id) == isl
        for e in acked_edges:
            assert graph.get_edge(e.source, e.target) == e
        assert set(graph.island_ids()) - {i.id for i in acked} <= {1000, 1001}
        # the killed servers left a store that passes its checks on open, as served
        assert GraphStore.read(storage) == graph
    finally:
        for p in procs:
            _kill(p)
        ex.shutdown()
        node.destroy_node()
