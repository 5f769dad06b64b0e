"""JSON forms of islands, edges and graphs: round trips, validation errors naming the field."""

from __future__ import annotations

import copy
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType, Pose2D

from island_msgs_py import json_io


def _islands() -> list[Island]:
    rng = np.random.default_rng(3)
    return [
        Island(0, LineModel(rng.uniform(-4, 4, (5, 4))), ModelType.LINE, 0.731, 12.5),
        Island(1, LineModel(rng.uniform(-4, 4, (3, 4))), ModelType.FISHER, 1.0 / 3.0, 40.25,
               origin_truth=Pose2D(12.0, -3.5, 1.25)),
        Island(4, LineModel(np.zeros((0, 4))), ModelType.LINE, 0.0, 99.0, frame_id="lab_door"),
    ]


def _edges() -> list[Edge]:
    return [
        Edge(0, 1, ControlStrategy.parse("Go 125, Rot 270, Go 652"), 8.1, 7.77, 0.33),
        Edge(1, 4, ControlStrategy.parse("Rot 270, Go 28, Rot 90, Go 832"), 9.0, 8.6, 0.4),
        Edge(4, 0, ControlStrategy(()), 0.0),
    ]


def _doc() -> dict[str, Any]:
    return json_io.graph_to_dict(_islands(), _edges())


def test_graph_round_trip_is_exact() -> None:
    text = json_io.graph_to_json(_islands(), _edges())
    islands, edges = json_io.graph_from_json(text)
    assert islands == _islands()
    assert edges == _edges()
    assert islands[2].frame_id == "lab_door" and islands[0].frame_id == "island_0"
    # exact float round trip (repr), e.g. 1/3
    assert islands[1].r == 1.0 / 3.0
    doc = json.loads(text)
    assert doc["format"] == "islands-graph" and doc["version"] == 2
    assert doc["edges"][0]["strategy"] == "Go 125, Rot 270, Go 652"


def test_single_island_and_edge_round_trip() -> None:
    for island in _islands():
        assert json_io.island_from_json(json_io.island_to_json(island)) == island
    for edge in _edges():
        assert json_io.edge_from_json(json_io.edge_to_json(edge)) == edge


def _mutated(path: list[Any], value: Any) -> dict[str, Any]:
    doc = copy.deepcopy(_doc())
    obj: Any = doc
    for key in path[:-1]:
        obj = obj[key]
    if value is _DELETE:
        del obj[path[-1]]
    else:
        obj[path[-1]] = value
    return doc


_DELETE = object()
_S0 = ["islands", 0, "model", "segments"]
_S1 = ["islands", 1, "model", "segments"]


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        ([*_S1, 2, 1], float("nan"), "islands[1].model.segments[2]: NaN"),
        ([*_S0, 0, 3], float("inf"), "islands[0].model.segments[0]:"),
        ([*_S0, 1], [1, 2, 3], "islands[0].model.segments[1]: expected 4"),
        ([*_S0, 1, 0], "x", "islands[0].model.segments[1]: coordinate 0"),
        (["islands", 2, "r"], float("nan"), "islands[2].r: NaN"),
        (["islands", 2, "id"], -1, "islands[2].id: must be >= 0"),
        (["islands", 2, "id"], 0, "islands[2].id: duplicate island id 0"),
        (["islands", 0, "id"], True, "islands[0].id: expected an integer"),
        (["islands", 0, "model_type"], "sonar", "islands[0].model_type: unknown model type"),
        (["islands", 0, "built_at_s"], _DELETE, "islands[0].built_at_s: missing"),
        (["islands", 0, "colour"], "red", "islands[0].colour: unknown key"),
        (["islands", 1, "origin_truth", "theta"], None, "islands[1].origin_truth.theta"),
        (["edges", 0, "weight"], float("nan"), "edges[0].weight: NaN"),
        (["edges", 0, "weight"], -1.0, "edges[0].weight: must be >= 0"),
        (["edges", 1, "target"], 1, "edges[1]: an edge from island 1 to itself"),
        (["edges", 1, "target"], 7, "edges[1].target: unknown island 7"),
        (["edges", 2, "source"], 0, "edges[2]: an edge from island 0 to itself"),
        (["edges", 2, "target"], 1, None),  # 4->1 is new and valid
        (["edges", 0, "strategy"], "Go 1, Fly 3", "edges[0].strategy: control strategy"),
        (["edges", 0, "strategy"], "Rot 400", "edges[0].strategy: Rot angle must be in [0, 360)"),
        (["version"], 3, "version: unsupported version 3"),
        (["format"], "other", "format: expected 'islands-graph'"),
        (["islands"], {}, "islands: expected a list"),
    ],
)
def test_validation_names_the_bad_field(path: list[Any], value: Any, expected: str | None) -> None:
    doc = _mutated(path, value)
    text = json.dumps(doc)  # Python writes NaN/Infinity tokens, as a careless producer would
    if expected is None:
        json_io.graph_from_json(text)
        return
    with pytest.raises(GraphFormatError) as info:
        json_io.graph_from_json(text)
    assert str(info.value).startswith(expected), str(info.value)


def test_duplicate_edge_is_rejected() -> None:
    doc = _doc()
    doc["edges"].append(dict(doc["edges"][0]))
    with pytest.raises(GraphFormatError, match=r"edges\[3\]: duplicate edge 0->1"):
        json_io.graph_from_dict(doc)


def test_not_json_and_not_an_object() -> None:
    with pytest.raises(GraphFormatError, match="not valid JSON"):
        json_io.graph_from_json("{nope")
    with pytest.raises(GraphFormatError, match="expected a JSON object"):
        json_io.graph_from_json("[1, 2]")
    with pytest.raises(GraphFormatError, match=r"^island: expected an object"):
        json_io.island_from_json("3")


def test_dumps_refuses_nan() -> None:
    with pytest.raises(ValueError):
        json_io.dumps({"x": math.nan})


def test_save_is_atomic_and_load_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "sub" / "graph.json"
    json_io.save_graph_json(path, _islands(), _edges())
    assert json_io.load_graph_json(path) == (_islands(), _edges())
    assert sorted(p.name for p in path.parent.iterdir()) == ["graph.json"]  # no temp left
    assert path.stat().st_mode & 0o777 == 0o644
    bad = _mutated(["islands", 1, "model", "segments", 2, 1], float("nan"))
    path.write_text(json.dumps(bad))
    with pytest.raises(GraphFormatError) as info:
        json_io.load_graph_json(path)
    assert str(info.value).startswith(f"{path}: islands[1].model.segments[2]: NaN")
    with pytest.raises(GraphFormatError, match="cannot read"):
        json_io.load_graph_json(tmp_path / "missing.json")


def test_atomic_write_leaves_old_file_on_failure(tmp_path: Path) -> None:
    path = tmp_path / "graph.json"
    json_io.atomic_write_text(path, "old")

    with pytest.raises(TypeError):
        json_io.atomic_write_text(path, 123)  # type: ignore[arg-type]
    assert path.read_text() == "old"
    assert os.listdir(tmp_path) == ["graph.json"]


def test_json_io_does_not_import_ros() -> None:
    code = (
        "import sys, island_msgs_py.json_io\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in "
        "('rclpy', 'std_msgs', 'geometry_msgs')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
