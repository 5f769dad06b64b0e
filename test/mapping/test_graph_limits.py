"""The map's bounds (island_msgs_py.limits) in the graph and its three file formats: every value
outside one is an error of the package's own type naming the file or field and the limit."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from island_mapping.cli import main
from island_mapping.core.graph import GraphError, TopoGraph
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.limits import (
    MAX_COORD_M,
    MAX_ISLAND_ID,
    MAX_JSON_DEPTH,
    MAX_SEGMENTS_PER_ISLAND,
    MAX_STRATEGY_STEPS,
)
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Island,
    IslandTypeError,
    LineModel,
    ModelType,
    PrimitiveKind,
    StrategyPrimitive,
)

from island_msgs_py import json_io


def island(i: int, segments: np.ndarray | None = None) -> Island:
    segs = np.random.default_rng(i).uniform(-3, 3, (3, 4)) if segments is None else segments
    return Island(i, LineModel(segs), ModelType.LINE, 0.7, 1.0)


def small() -> TopoGraph:
    return TopoGraph.from_parts([island(0), island(1)],
                                [Edge(0, 1, ControlStrategy.parse("Go 100"), 1.0)])


@pytest.mark.parametrize(
    ("text", "depth"),
    [
        ("{}", 1),
        ('{"a": [[1, 2], {"b": []}]}', 4),
        ('["[[[[", "]]", "\\"[[[["]', 1),  # brackets and escaped quotes inside strings
        ("[" * 5000 + "]" * 5000, 5000),
        ('"no brackets"', 0),
    ],
)
def test_json_depth_counts_only_structure(text: str, depth: int) -> None:
    assert json_io.json_depth(text) == depth
    assert json_io.json_depth(text.encode()) == depth


def test_bounded_parsing_refuses_depth_long_integers_and_size() -> None:
    with pytest.raises(GraphFormatError, match=rf"^f: JSON nested 50000 deep \(the limit is "
                                               rf"{MAX_JSON_DEPTH}\)"):
        json_io.loads("[" * 50_000 + "]" * 50_000, "f")
    assert json_io.loads("[" * MAX_JSON_DEPTH + "]" * MAX_JSON_DEPTH, "f") is not None
    with pytest.raises(GraphFormatError, match=r"^f: an integer of 4400 digits \(the limit is 20"):
        json_io.loads('{"id": ' + "1" * 4400 + "}", "f")
    assert json_io.loads("[12345678901234567890, -1, 1e400]", "f")[0] == 12345678901234567890
    with pytest.raises(GraphFormatError, match=r"^f: 11 bytes of JSON \(the limit is 10\)"):
        json_io.loads('{"a": [1] }', "f", max_bytes=10)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_each_file_format_names_the_file_and_the_limit(tmp_path: Path) -> None:
    g = small()
    doc = g.to_dict()
    doc["islands"][0]["model"]["segments"] = json.loads("[" * 40 + "]" * 40)
    cases: list[tuple[Path, str]] = [
        (_write(tmp_path / "deep.json", json.dumps(doc)), "JSON nested 44 deep (the limit is 32)"),
        (_write(tmp_path / "big.json", g.to_json().replace('"id": 1', '"id": ' + "9" * 5000)),
         "an integer of 5000 digits"),
        (_write(tmp_path / "far.json", g.to_json().replace('"id": 1', f'"id": {2**31}')),
         f"islands[1].id: must be <= {MAX_ISLAND_ID} (the limit)"),
    ]
    gj = g.to_geojson()
    gj["features"][0]["properties"]["metadata"]["nested"] = json.loads("[" * 40 + "]" * 40)
    cases.append((_write(tmp_path / "deep.geojson", json.dumps(gj)), "JSON nested"))
    gj = g.to_geojson()
    gj["features"][1]["properties"]["id"] = 2**31
    cases.append((_write(tmp_path / "id.geojson", json.dumps(gj)),
                  f"features[1].properties.id: must be <= {MAX_ISLAND_ID}"))
    gj = g.to_geojson()
    gj["features"][0]["properties"]["metadata"]["segments"][2] = 5.0e6
    cases.append((_write(tmp_path / "far.geojson", json.dumps(gj)),
                  "features[0].properties.metadata.segments[0:4]: coordinate 2 is 5e+06"))
    g.save_graphml(tmp_path / "g.graphml")
    text = (tmp_path / "g.graphml").read_text()
    cases.append((_write(tmp_path / "id.graphml", text.replace('id="1"', 'id="' + "1" * 5000 + '"')
                         .replace('target="1"', 'target="' + "1" * 5000 + '"')),
                  "the node id must be an island id in [0, 2147483647]"))
    seg = json.dumps(g.get_island(0).model.segments.tolist())
    deep_attr = ("[" * 40 + "]" * 40).replace("[", "&#91;").replace("]", "&#93;")
    cases.append((_write(tmp_path / "attr.graphml", text.replace(seg, deep_attr, 1)),
                  "node 0.segments: JSON nested 40 deep"))
    for path, message in cases:
        with pytest.raises(GraphFormatError) as info:
            TopoGraph.load_any(path)
        assert str(info.value).startswith(str(path)), str(info.value)
        assert message in str(info.value), (path.name, str(info.value))


def test_an_entity_expansion_bomb_in_graphml_is_refused(tmp_path: Path) -> None:
    lol = '<!ENTITY l0 "lol">' + "".join(
        f'<!ENTITY l{k} "{f"&l{k - 1};" * 10}">' for k in range(1, 10))  # 10^9 lols
    bomb = (f'<?xml version="1.0"?><!DOCTYPE graphml [{lol}]>'
            '<graphml xmlns="http://graphml.graphdrawing.org/xmlns"><graph edgedefault="directed">'
            '<node id="0"><data key="d0">&l9;</data></node></graph></graphml>')
    with pytest.raises(GraphFormatError, match=r"bomb\.graphml: not GraphML: .*amplification"):
        TopoGraph.load_graphml(_write(tmp_path / "bomb.graphml", bomb))


def _forced(obj: Any, **fields: Any) -> Any:
    """A copy with fields set past the constructor's checks, as a buggy caller might."""
    out = dataclasses.replace(obj)
    for k, v in fields.items():
        object.__setattr__(out, k, v)
    return out


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (lambda g: g.put_island(island(2, np.array([[0.0, 0.0, MAX_COORD_M * 1.5, 0.0]]))),
         r"island 2: segment 0 has a coordinate beyond 1e\+06 m \(the limit\)"),
        (lambda g: g.put_island(island(2, np.zeros((MAX_SEGMENTS_PER_ISLAND + 1, 4)))),
         r"island 2: 10001 segments \(the limit is 10000\)"),
        (lambda g: g.put_island(_forced(island(2), id=MAX_ISLAND_ID + 1)),
         r"island id must be an integer in \[0, 2147483647\]"),
        (lambda g: g.put_island(_forced(island(2), frame_id="f" * 300)),
         "island 2: frame_id must be a string of at most 256 characters"),
        (lambda g: g.put_edge(Edge(1, 0, ControlStrategy(()), 2.0e6)),
         r"edge 1->0: weight is 2e\+06 m, beyond 1e\+06 m \(the limit\)"),
        (lambda g: g.put_edge(_forced(Edge(1, 0, ControlStrategy(()), 1.0), target=2**40)),
         r"edge 1->1099511627776: target must be an island id in \[0, 2147483647\]"),
        (lambda g: g.put_edge(Edge(1, 0, ControlStrategy(
            (StrategyPrimitive(PrimitiveKind.ROT, 90),) * (MAX_STRATEGY_STEPS + 1)), 1.0)),
         r"edge 1->0: 1001 strategy steps \(the limit is 1000\)"),
    ],
)
def test_the_graph_refuses_values_beyond_the_limits(action: Any, message: str) -> None:
    g = small()
    before, version = g.to_json(), g.version
    with pytest.raises(GraphError, match=message):
        action(g)
    assert g.to_json() == before and g.version == version


def test_the_types_refuse_ids_and_steps_beyond_the_limits() -> None:
    with pytest.raises(IslandTypeError, match=r"island id must be an integer in \[0, 2147483647"):
        island(2**31)
    with pytest.raises(IslandTypeError, match="more than 9 digits"):
        ControlStrategy.parse("Go " + "1" * 5000)
    with pytest.raises(IslandTypeError, match=r"Go distance must be in \[0, 100000000\] cm"):
        ControlStrategy.parse("Go 100000001")
    assert math.isclose(ControlStrategy.parse("Go 100000000").length_m, 1.0e6)


def test_the_cli_turns_every_limit_into_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    deep = _write(tmp_path / "deep.json", "[" * 100_000 + "]" * 100_000)
    assert main(["graph", "info", str(deep)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "JSON nested 100000 deep (the limit is 32)" in err
