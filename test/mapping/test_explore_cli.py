"""`islands explore`: every node in one process on sim time, and what it writes (short run)."""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import pytest
from island_mapping.bag.reader import open_bag
from island_mapping.cli import main
from island_mapping.core.graph import TopoGraph
from island_mapping.executors import ExecutorKind
from island_mapping.runner import RunConfig, RunParameterError, run
from island_msgs_py.json_io import load_graph_json
from island_sim.core.robot import OdometryConfig


@pytest.mark.slow
def test_explore_writes_the_map_figures_recording_and_summary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    code = main(["explore", "--world", "paper_fig4", "--out", str(out), "--seed", "2",
                 "--sim-seconds", "150", "--routes", "2", "--quiet",
                 "--builder-param", "builder.peak_min_gain=0.1"])  # the default: same run
    assert code == 0
    for name in ("graph.json", "graph.geojson", "graph.graphml", "exploration.png",
                 "topology.png", "strategies.txt", "summary.json"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    islands, edges = load_graph_json(out / "graph.json")
    assert summary["islands"] == len(islands) >= 1
    assert summary["parameters"] == {"island_builder_node": {"builder.peak_min_gain": 0.1}}
    assert summary["edges"] == len(edges)
    assert summary["accepted"] == len(islands)
    assert summary["attempts"] >= summary["accepted"]
    assert summary["collisions"] == 0
    assert abs(summary["sim_seconds"] - 150.0) < 0.5
    assert set(summary["island_places"]) == {str(i.id) for i in islands}
    # Routes are reported per edge: a route succeeds only through edges that each succeeded,
    # chained from its source to its target.
    per_route = summary["routes"]["per_route"]
    assert len(per_route) == summary["routes"]["pairs"] >= 1
    assert any(r["islands_success"] for r in per_route)
    for r in per_route:
        legs = r["islands_edges"]
        assert all(e["localized"] and e["error_m"] <= 0.25 for e in legs if e["success"])
        assert all(a["target"] == b["source"] for a, b in itertools.pairwise(legs))
        if r["islands_success"]:
            assert legs and all(e["success"] for e in legs)
            assert (legs[0]["source"], legs[-1]["target"]) == (r["source"], r["target"])
            assert r["islands_final_error_m"] <= 0.25
    # The exports describe the same graph.
    g = TopoGraph.from_parts(islands, edges)
    assert TopoGraph.from_geojson(json.loads((out / "graph.geojson").read_text())).to_json() == (
        g.to_json())
    table = (out / "strategies.txt").read_text().splitlines()
    assert len(table) == 1 + len(edges)
    # The recording holds the run's topics with sim-time stamps.
    reader = open_bag(out / "run_bag")
    assert {"/odom", "/ground_truth", "/sonar/scan", "/cmd_vel", "/clock",
            "/island_builder/events"} <= set(reader.topics)
    assert reader.topics["/sonar/scan"].message_count >= 1400  # 10 Hz for 150 s
    # Lockstep: /odom at every 50 Hz step (eq. 3 integrates each), /clock and /ground_truth
    # only at the 10 Hz sensor instants (nothing reads them in between).
    counts = {t: reader.topics[t].message_count for t in ("/odom", "/ground_truth", "/clock")}
    assert counts["/odom"] == 5 * (counts["/ground_truth"] - 1) + 1, counts
    assert counts["/clock"] == counts["/ground_truth"] == 1501, counts
    assert 140.0 <= reader.duration_ns * 1e-9 <= 151.0
    assert "results in" in capsys.readouterr().out
    # The map measured against the world's places, in the summary and by `islands evaluate`.
    ev = summary["world_evaluation"]
    assert ev["places"] == 36 and ev["world_cycle_rank"] == 3 and ev["islands"] == len(islands)
    assert ev["covered_places"] >= 1 and ev["false_merges"] == 0
    assert (out / "places.png").stat().st_size > 0
    assert main(["evaluate", "--map", str(out), "--out", str(tmp_path / "ev")]) == 0
    again = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    assert {k: again[k] for k in ev} == ev


def test_explore_rejects_a_bad_world(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("segments: [[0, 0, 0, 0]]\n")
    assert main(["explore", "--world", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "bad.yaml" in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("flag", "value", "message"), [
    ("--executor", "multi", "invalid choice: 'multi'"),
    ("--param", "odometry.wheelbase_error=0.01", "expected NODE:NAME=VALUE"),
    ("--param", "odometry_node:odometry.wheelbase_error", "expected NAME=VALUE"),
    ("--builder-param", "builder.e_min_m", "expected NAME=VALUE"),
    ("--builder-param", "builder.e_min_m=[1, 2]", "must be a bool, number or string"),
])
def test_explore_rejects_malformed_parameters_before_writing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str, value: str, message: str
) -> None:
    assert main(["explore", "--out", str(tmp_path / "o"), flag, value, "--quiet"]) == 2
    err = capsys.readouterr().err
    assert message in err and flag in err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("params", "message"), [
    ({"odometry_nod": {"seed": 3}}, "no node odometry_nod in the run"),
    ({"island_builder_node": {"builder.no_such": 1}},
     "island_builder_node has no parameter builder.no_such"),
    ({"island_builder_node": {"builder.e_min_m": -1.0}}, "island_builder_node rejected"),
])
def test_a_run_names_the_node_and_parameter_it_cannot_take(
    params: dict[str, dict[str, object]], message: str
) -> None:
    with pytest.raises(RunParameterError, match=message):
        run(RunConfig(sim_seconds=1.0, params=params))


def test_explore_names_a_parameter_no_node_has(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(["explore", "--out", str(tmp_path / "o"), "--quiet", "--no-record",
                 "--builder-param", "builder.no_such=1.0"])
    assert code == 2
    err = capsys.readouterr().err
    assert "island_builder_node has no parameter builder.no_such" in err
    assert "Traceback" not in err and not (tmp_path / "o" / "summary.json").exists()


@pytest.mark.parametrize("executor", list(ExecutorKind))
def test_a_run_drives_and_reports_the_parameters_it_was_given(
        tmp_path: Path, executor: ExecutorKind) -> None:
    """An odometry override reaches the robot, and route evaluation drives the same robot;
    on either executor."""
    rec = run(RunConfig(sim_seconds=2.0, executor=executor, params={
        "odometry_node": {"odometry.var_heading_rad2_per_rad": 0.002},
    }))
    assert rec.sim_setup is not None
    assert rec.sim_setup.odometry.var_heading_rad2_per_rad == 0.002
    assert rec.sim_setup.odometry.var_dist_m2_per_m == OdometryConfig().var_dist_m2_per_m
    assert rec.sim_seconds >= 1.9
