"""`islands explore`: every node in one process on sim time, and what it writes (short run)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from island_mapping.bag.reader import open_bag
from island_mapping.cli import main
from island_mapping.core.graph import TopoGraph
from island_msgs_py.json_io import load_graph_json


@pytest.mark.slow
def test_explore_writes_the_map_figures_recording_and_summary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "run"
    code = main(["explore", "--world", "paper_fig4", "--out", str(out), "--seed", "2",
                 "--sim-seconds", "150", "--routes", "2", "--quiet"])
    assert code == 0
    for name in ("graph.json", "graph.geojson", "graph.graphml", "exploration.png",
                 "topology.png", "strategies.txt", "summary.json"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    islands, edges = load_graph_json(out / "graph.json")
    assert summary["islands"] == len(islands) >= 1
    assert summary["edges"] == len(edges)
    assert summary["accepted"] == len(islands)
    assert summary["attempts"] >= summary["accepted"]
    assert summary["collisions"] == 0
    assert abs(summary["sim_seconds"] - 150.0) < 0.5
    assert set(summary["island_places"]) == {str(i.id) for i in islands}
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
    assert 140.0 <= reader.duration_ns * 1e-9 <= 151.0
    assert "results in" in capsys.readouterr().out


def test_explore_rejects_a_bad_world(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("segments: [[0, 0, 0, 0]]\n")
    assert main(["explore", "--world", str(bad), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "bad.yaml" in err
    assert not (tmp_path / "o").exists()
