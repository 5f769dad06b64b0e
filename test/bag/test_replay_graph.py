"""Replaying a recorded run into a fresh builder and graph server reproduces the run's map.

One short run of every node (module fixture: runner.run, what `islands explore` does) records
run_bag/ and graph.json; `islands replay` rebuilds the graph from the bag alone and must give
the same islands (ids, model types, segments to 1e-9 m, r) and edges (source, target, strategy
text, weights), and the same builder events. A truncated copy of the bag is refused with an
error naming the file, or with --allow-damaged replays its intact part (a prefix of the run:
the same first islands).
"""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest

SIM_SECONDS = 120.0
"""Long enough for island 0, one more island and the edge between them (paper_fig4, seed 1:
accepted at about 25 s and 70 s of sim time), short enough to keep this file near a minute."""


@pytest.fixture(scope="module")
def recorded_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`islands explore`'s layout: run_bag/ and graph.json side by side (no figures)."""
    from island_mapping.runner import RunConfig, run

    out = tmp_path_factory.mktemp("recorded_run")
    rec = run(RunConfig(world="paper_fig4", seed=1, sim_seconds=SIM_SECONDS,
                        record_dir=str(out / "run_bag"), wall_timeout_s=600.0))
    assert rec.bag_dir == out / "run_bag" and (out / "run_bag" / "metadata.yaml").is_file()
    rec.graph.save_json(out / "graph.json")
    return out


def _run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    from island_mapping.cli import main

    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_replay_reproduces_the_recorded_graph(
    recorded_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from island_mapping.bag.compare import compare_graphs
    from island_mapping.bag.reader import open_bag
    from island_mapping.core.graph import TopoGraph

    recorded = TopoGraph.load_json(recorded_run / "graph.json")
    # The run must have built something worth comparing: two islands and the edge between.
    assert len(recorded) >= 2 and recorded.num_edges >= 1

    out = tmp_path / "replayed"
    code, stdout, stderr = _run_cli(
        ["replay", str(recorded_run / "run_bag"), "--out", str(out), "--quiet"], capsys)
    report = json.loads(stdout)
    assert code == 0, (report, stderr)
    assert report["reference"] == str(recorded_run / "graph.json")
    assert report["graph"]["identical"], report["graph"]["differences"]
    assert report["events"]["identical"], report["events"]
    assert report["events"]["recorded"] >= 3  # at least attempt, acceptance, hand-back
    assert report["warnings"] == []
    topics = open_bag(recorded_run / "run_bag").topics
    for topic in ("/odom", "/ground_truth", "/sonar/scan"):
        assert report["messages"][topic] == topics[topic].message_count > 0  # none dropped
    for topic in ("/clock", "/hall_follower/progress"):  # only the newest before each scan
        assert (report["messages"][topic] + report["superseded"][topic]
                == topics[topic].message_count)
    assert json.loads((out / "replay.json").read_text()) == report

    # Independently of compare_graphs: island by island, edge by edge.
    replayed = TopoGraph.load_json(out / "graph.json")
    assert TopoGraph.load_any(out / "graph.geojson") == replayed
    assert TopoGraph.load_any(out / "graph.graphml") == replayed
    assert replayed.island_ids() == recorded.island_ids()
    for a, b in zip(recorded.islands(), replayed.islands(), strict=True):
        assert (a.id, a.model_type) == (b.id, b.model_type)
        assert a.model.segments.shape == b.model.segments.shape
        np.testing.assert_allclose(b.model.segments, a.model.segments, rtol=0, atol=1e-9)
        assert b.r == pytest.approx(a.r, rel=1e-12)
    rec_edges = {(e.source, e.target): e for e in recorded.edges()}
    rep_edges = {(e.source, e.target): e for e in replayed.edges()}
    assert rep_edges.keys() == rec_edges.keys()
    for k, e in rec_edges.items():
        assert str(rep_edges[k].strategy) == str(e.strategy) != ""
        assert rep_edges[k].weight == pytest.approx(e.weight, rel=1e-12)
    assert compare_graphs(recorded, replayed).identical


def test_truncated_bag_is_refused_or_replayed_up_to_the_damage(
    recorded_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from island_mapping.bag.compare import compare_graphs
    from island_mapping.bag.reader import open_bag
    from island_mapping.core.graph import TopoGraph

    (mcap,) = sorted((recorded_run / "run_bag").glob("*.mcap"))
    cut = tmp_path / "cut"
    cut.mkdir()
    broken = cut / mcap.name
    data = mcap.read_bytes()
    broken.write_bytes(data[: len(data) // 2])

    # Default: a clear error naming the file and where it breaks, exit code 2, no output.
    code, stdout, stderr = _run_cli(
        ["replay", str(broken), "--out", str(tmp_path / "refused"), "--quiet"], capsys)
    assert code == 2 and stdout == ""
    assert str(broken) in stderr and "byte offset" in stderr and "--allow-damaged" not in stdout
    assert not (tmp_path / "refused").exists()

    # --allow-damaged: the intact first half is replayed, with a warning naming the file.
    shutil.copy(recorded_run / "graph.json", tmp_path / "graph.json")  # BAG_DIR/../graph.json
    out = tmp_path / "partial"
    code, stdout, stderr = _run_cli(
        ["replay", str(broken), "--out", str(out), "--allow-damaged", "--quiet"], capsys)
    report = json.loads(stdout)
    assert code == 1  # differs from the full run's graph...
    assert any(str(broken) in w for w in report["warnings"])
    assert "warning: damaged recording" in stderr
    full_scans = open_bag(recorded_run / "run_bag").topics["/sonar/scan"].message_count
    assert 0 < report["messages"]["/sonar/scan"] < full_scans
    # ...but is a prefix of it: the islands (and edges) it has are the run's first ones.
    full = TopoGraph.load_json(recorded_run / "graph.json")
    partial = TopoGraph.load_json(out / "graph.json")
    assert 1 <= len(partial) < len(full)
    prefix = TopoGraph.from_parts(
        [full.get_island(i) for i in partial.island_ids()],
        [e for e in full.edges() if e.source in partial and e.target in partial],
    )
    assert compare_graphs(prefix, partial).identical


# ---- fast checks without a run ---------------------------------------------------------------


def _graph() -> Any:
    from island_mapping.core.graph import TopoGraph
    from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType

    rng = np.random.default_rng(7)
    islands = [Island(id=i, model=LineModel(rng.uniform(-3, 3, (3, 4))), model_type=ModelType.LINE,
                      r=1.0 + i, built_at_s=10.0 * i) for i in range(3)]
    edges = [Edge(i, i + 1, ControlStrategy.parse("Go 120, Rot 90, Go 40"), 2.5, 2.0, 0.5)
             for i in range(2)]
    return TopoGraph.from_parts(islands, edges)


def test_compare_graphs_finds_each_kind_of_difference() -> None:
    from island_mapping.bag.compare import compare_graphs
    from island_mapping.core.graph import TopoGraph
    from island_msgs_py.types import ControlStrategy, LineModel, ModelType

    g = _graph()
    assert compare_graphs(g, _graph()).identical
    islands, edges = g.islands(), g.edges()

    seg = islands[1].model.segments.copy()
    seg[0, 0] += 1e-6  # a micrometre is a difference at 1e-9
    moved = [*islands[:1], dataclasses.replace(islands[1], model=LineModel(seg)), *islands[2:]]
    diff = compare_graphs(g, TopoGraph.from_parts(moved, edges))
    assert diff.differences == ("island 1: segments differ by up to 1e-06 m",)
    seg[0, 0] -= 1e-6 - 1e-12  # below the tolerance: equal
    close = [*islands[:1], dataclasses.replace(islands[1], model=LineModel(seg)), *islands[2:]]
    assert compare_graphs(g, TopoGraph.from_parts(close, edges)).identical

    typed = [dataclasses.replace(islands[0], model_type=ModelType.FISHER), *islands[1:]]
    assert "island 0: model type" in compare_graphs(g, TopoGraph.from_parts(typed, edges)
                                                    ).differences[0]
    other = [dataclasses.replace(edges[0], strategy=ControlStrategy.parse("Go 121")), edges[1]]
    diff = compare_graphs(g, TopoGraph.from_parts(islands, other))
    assert diff.differences == ("edge 0->1: strategy 'Go 120, Rot 90, Go 40' != 'Go 121'",)
    heavier = [edges[0], dataclasses.replace(edges[1], weight=2.6)]
    assert compare_graphs(g, TopoGraph.from_parts(islands, heavier)).differences == (
        "edge 1->2: weight 2.5 != 2.6",)
    fewer = compare_graphs(g, TopoGraph.from_parts(islands[:2], edges[:1]))
    assert fewer.differences == ("island 2: missing from the replay",
                                 "edge 1->2: missing from the replay")
    assert fewer.to_dict()["actual"] == {"islands": 2, "edges": 1}
    with pytest.raises(ValueError, match="tol"):
        compare_graphs(g, g, tol=float("nan"))


def test_compare_events_reports_the_first_difference() -> None:
    from island_mapping.bag.compare import compare_events

    a = [{"kind": "attempt_started", "t_s": 0.0}, {"kind": "island_accepted", "t_s": 25.0}]
    assert compare_events(a, list(a))["identical"]
    b = [a[0], {"kind": "island_accepted", "t_s": 25.02}]
    assert compare_events(a, b) == {"identical": False, "recorded": 2, "replayed": 2,
                                    "first_difference_index": 1,
                                    "recorded_kind": "island_accepted",
                                    "replayed_kind": "island_accepted"}
    assert compare_events(a, a[:1])["first_difference_index"] == 1


def test_bad_input_gives_clear_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from island_mapping.bag.writer import BagWriter
    from island_mapping.replay import ReplayConfig, ReplayError, replay_run
    from rosgraph_msgs.msg import Clock

    code, _, err = _run_cli(["replay", str(tmp_path / "nope"), "--out", str(tmp_path / "o")],
                            capsys)
    assert code == 2 and "nope: no such bag" in err

    bag = tmp_path / "clock_only"
    with BagWriter(bag) as w:
        for s in range(3):
            msg = Clock()
            msg.clock.sec = s
            w.write("/clock", msg)
    with pytest.raises(ReplayError, match="has no /odom, /sonar/scan"):
        replay_run(bag)
    code, _, err = _run_cli(["replay", str(bag), "--out", str(tmp_path / "o"),
                             "--builder-param", "builder.e_min_m"], capsys)
    assert code == 2 and "expected NAME=VALUE" in err
    with pytest.raises(ReplayError, match="delivery_timeout_s"):
        ReplayConfig(delivery_timeout_s=0.0)

    tiny = _tiny_bag(tmp_path / "tiny")
    with pytest.raises(ReplayError, match=r"has no parameter builder\.no_such_thing"):
        replay_run(tiny, builder_params={"builder.no_such_thing": 1.0})
    with pytest.raises(ReplayError, match=r"rejected the builder parameters.*e_min_m"):
        replay_run(tiny, builder_params={"builder.e_min_m": -1.0})
    code, _, err = _run_cli(["replay", str(tiny), "--out", str(tmp_path / "o"),
                             "--builder-param", "builder.e_min_m=-1"], capsys)
    assert code == 2 and "e_min_m" in err and "Traceback" not in err


def _tiny_bag(path: Path) -> Path:
    """Two scans with their odometry: enough for a replay to start."""
    from island_mapping.bag.writer import BagWriter
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan

    with BagWriter(path) as w:
        for k in range(2):
            odom = Odometry()
            odom.header.stamp.nanosec = 100_000_000 * k
            odom.pose.pose.orientation.w = 1.0
            w.write("/odom", odom)
            scan = LaserScan()
            scan.header.stamp.nanosec = 100_000_000 * k
            scan.angle_increment = 0.5
            scan.range_max = 5.0
            scan.ranges = [1.0, 2.0, 3.0]
            w.write("/sonar/scan", scan)
    return path


def test_refuses_to_replay_next_to_another_publisher(ros_context: Any, tmp_path: Path) -> None:
    """A simulation publishing /odom in the same domain would feed the replayed builder."""
    from island_mapping.replay import ReplayError, replay_into_builder, replay_run
    from nav_msgs.msg import Odometry
    from rclpy.node import Node

    bag = _tiny_bag(tmp_path / "tiny")
    assert len(replay_into_builder(bag)) == 0  # alone in the domain: fine (no island yet)
    foreign = Node("foreign_simulator", context=ros_context)
    try:
        foreign.create_publisher(Odometry, "/odom", 10)
        with pytest.raises(ReplayError, match=r"other publishers .*/odom: 1.*ROS_DOMAIN_ID"):
            replay_run(bag)
    finally:
        foreign.destroy_node()


def test_scan_before_its_odometry_is_processed_when_the_odometry_comes(tmp_path: Path) -> None:
    """The builder holds a scan back until odometry of its stamp arrives: the replay must not
    stall on it (its delivery is counted when the scan is taken, its processing later), and the
    scan is processed with the odometry of its own stamp, at its own time."""
    from island_mapping.bag.writer import BagWriter
    from island_mapping.replay import replay_run
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan

    def odom(t_ns: int, x: float) -> Odometry:
        msg = Odometry()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
        msg.pose.pose.position.x = x
        msg.pose.pose.orientation.w = 1.0
        return msg

    def scan(t_ns: int) -> LaserScan:
        msg = LaserScan()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
        msg.angle_min, msg.angle_increment, msg.range_max = -1.0, 0.5, 5.0
        msg.ranges = [1.0, 1.5, 2.0, 2.5, 3.0]
        return msg

    bag = tmp_path / "scan_first"
    with BagWriter(bag) as w:
        w.write("/sonar/scan", scan(1_000_000_000))  # before any odometry of its stamp
        w.write("/odom", odom(1_000_000_000, 2.0))  # releases it: the pose it must use
        for k in range(1, 8):  # later odometry (one batch, had the scan not been held)
            w.write("/odom", odom(1_000_000_000 + 20_000_000 * k, 2.0 + 0.01 * k))
    res = replay_run(bag)
    assert res.messages == {"/odom": 8, "/sonar/scan": 1}
    assert res.warnings[0].endswith("has no /clock; replaying without it")
    (started,) = res.events
    assert started["kind"] == "attempt_started"
    assert started["t_s"] == pytest.approx(1.0)
    assert started["anchor_odom"]["x"] == 2.0
