"""`islands evaluate` on hand-made run directories, and the new `islands explore` options."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from island_mapping.cli import main
from island_mapping.core.graph import TopoGraph
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Island,
    LineModel,
    ModelType,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
)

RING = {"name": "ring", "start_pose": [5.0, 1.0, 0.0], "segments": [
    [0, 0, 20, 0], [20, 0, 20, 12], [20, 12, 0, 12], [0, 12, 0, 0],
    [2, 2, 18, 2], [18, 2, 18, 10], [18, 10, 2, 10], [2, 10, 2, 2]]}
"""A square ring corridor: a loop with no junction and no end, so no place."""


def _run_dir(tmp_path: Path, world: str = "t_junction", events: list[object] | None = None,
             ) -> Path:
    """What `islands explore` would write for two islands on the t_junction."""
    d = tmp_path / "run"
    d.mkdir()
    go = ControlStrategy((StrategyPrimitive(PrimitiveKind.GO, 800),))
    graph = TopoGraph.from_parts(
        [Island(0, LineModel(), ModelType.LINE, 1.0, 0.0, origin_truth=Pose2D(2.0, 1.0, 0.0)),
         Island(1, LineModel(), ModelType.LINE, 1.0, 9.0, origin_truth=Pose2D(10.0, 1.5, 0.0))],
        [Edge(0, 1, go, 8.5, 8.5)])
    graph.save_json(d / "graph.json")
    summary = {"world": world, "world_spec": world, "seed": 1, "collisions": 0,
               "wall_seconds": 10.0, "start_pose": {"x": 2.0, "y": 1.0, "theta": 0.0},
               "routes": {"pairs": 1, "per_route": [
                   {"source": 1, "target": 0, "islands_success": True}]},
               "builder_events": events if events is not None else [
                   {"kind": "island_revisited", "t_s": 50.0, "revisited_island_id": 0,
                    "truth_pose": {"x": 2.5, "y": 1.0, "theta": 0.0},
                    "island_pose": {"x": 0.5, "y": 0.0, "theta": 0.0}}]}
    (d / "summary.json").write_text(json.dumps(summary))
    return d


def test_evaluate_writes_the_figures_and_the_places_picture(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    d = _run_dir(tmp_path)
    assert main(["evaluate", "--map", str(d)]) == 0
    ev = json.loads((d / "evaluation.json").read_text())
    assert (ev["places"], ev["junctions"]) == (4, 1)
    assert ev["covered_places"] == 2 and ev["junction_coverage"] == 1.0  # (1, 1) and (10, 1)
    assert ev["islands_per_place"] == 1.0 and ev["false_merges"] == 0 and ev["revisits"] == 1
    assert (ev["map_cycle_rank"], ev["world_cycle_rank"]) == (0, 0)
    assert ev["route_success_rate"] == 1.0
    assert ev["route_length_ratio_mean"] == pytest.approx(8.5 / 8.0, abs=0.02)
    assert ev["collisions"] == 0 and ev["world"] == "t_junction"
    assert (d / "places.png").stat().st_size > 0
    assert '"coverage": 0.5' in capsys.readouterr().out


def test_evaluate_on_a_world_with_no_reachable_place_exits_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    ring = tmp_path / "ring.yaml"
    ring.write_text(json.dumps(RING))
    d = _run_dir(tmp_path)
    assert main(["evaluate", "--map", str(d), "--world", str(ring), "--start", "5,1,0"]) == 2
    assert "no place" in capsys.readouterr().err
    assert main(["evaluate", "--map", str(d), "--start", "5,-4,0"]) == 2  # in the rock
    assert "no free space within" in capsys.readouterr().err
    assert not (d / "evaluation.json").exists()


@pytest.mark.parametrize(("change", "message"), [
    ({"builder_events": None}, "no builder_events"),
    ({"builder_events": [{"kind": "island_revisited", "revisited_island_id": 0}]},
     "truth_pose"),
    ({"routes": {"per_route": [{"source": 0}]}}, "routes.per_route[0]"),
    ({"world_spec": ""}, "--world is required"),
])
def test_evaluate_names_what_is_wrong_in_a_run_directory(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], change: dict[str, object],
        message: str) -> None:
    d = _run_dir(tmp_path)
    summary = json.loads((d / "summary.json").read_text())
    summary.update(change)
    (d / "summary.json").write_text(json.dumps(summary))
    assert main(["evaluate", "--map", str(d)]) == 2
    assert message in capsys.readouterr().err


def test_evaluate_without_a_run_directory_or_graph_exits_2(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["evaluate", "--map", str(tmp_path / "none")]) == 2
    assert "not a directory" in capsys.readouterr().err
    d = _run_dir(tmp_path)
    (d / "graph.json").write_text("{")
    assert main(["evaluate", "--map", str(d)]) == 2
    assert "graph.json" in capsys.readouterr().err


@pytest.mark.parametrize(("args", "message"), [
    (["--start", "1,2"], "--start: expected X,Y,THETA"),
    (["--start", "1,2,nan"], "--start: expected X,Y,THETA"),
    (["--resolution", "0.05"], "--resolution applies to image worlds"),
])
def test_explore_rejects_a_bad_start_or_resolution_before_writing(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
        message: str) -> None:
    assert main(["explore", "--out", str(tmp_path / "o"), "--quiet", *args]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
