"""Exits in the shared types and their JSON: round trips, version 1 still read, clear errors."""

from __future__ import annotations

import copy
import json
import math
from typing import Any

import numpy as np
import pytest
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitState,
    ExitUpdate,
    Island,
    IslandTypeError,
    LineModel,
    ModelType,
)

from island_msgs_py import json_io

EXPLORED, UNEXPLORED, BLOCKED = ExitState.EXPLORED, ExitState.UNEXPLORED, ExitState.BLOCKED


def _parts() -> tuple[list[Island], list[Edge]]:
    """Island 3 left by its exit 1 along edge 3->5, which enters island 5 by its exit 0."""
    rng = np.random.default_rng(4)
    i3 = Island(3, LineModel(rng.uniform(-3, 3, (3, 4))), ModelType.LINE, 0.7, 1.0, exits=(
        Exit(1, math.pi / 2, 1.4, EXPLORED, (3, 5)), Exit(0, 0.0, 1.1), Exit(2, -3.0, 0.9, BLOCKED),
    ))
    i5 = Island(5, LineModel(rng.uniform(-3, 3, (2, 4))), ModelType.FISHER, 0.6, 2.0,
                exits=(Exit(0, math.pi, 1.2, EXPLORED, (3, 5)),))
    e = Edge(3, 5, ControlStrategy.parse("Go 300, Rot 90, Go 120"), 4.5, 4.2, 0.3,
             source_exit=1, target_exit=0)
    return [i3, i5], [e]


def test_exits_are_sorted_and_round_trip_exactly() -> None:
    islands, edges = _parts()
    assert [e.index for e in islands[0].exits] == [0, 1, 2]
    doc = json_io.graph_to_dict(islands, edges)
    assert doc["version"] == 2
    assert doc["islands"][0]["exits"][1] == {
        "index": 1, "heading_rad": math.pi / 2, "width_m": 1.4, "state": "explored",
        "edge": [3, 5]}
    assert doc["edges"][0]["source_exit"] == 1 and doc["edges"][0]["target_exit"] == 0
    assert json_io.graph_from_json(json.dumps(doc)) == (islands, edges)
    for island in islands:
        assert json_io.island_from_json(json_io.island_to_json(island)) == island
    assert json_io.edge_from_json(json_io.edge_to_json(edges[0])) == edges[0]


def test_version_1_documents_are_still_read_without_exits() -> None:
    islands, edges = _parts()
    doc = json_io.graph_to_dict(islands, edges)
    doc["version"] = 1
    for i in doc["islands"]:
        del i["exits"]
    for e in doc["edges"]:
        del e["source_exit"], e["target_exit"]
    got_islands, got_edges = json_io.graph_from_dict(doc)
    assert [i.exits for i in got_islands] == [(), ()]
    assert got_edges[0].source_exit is None and got_edges[0].strategy == edges[0].strategy
    doc["islands"][0]["exits"] = []  # version 1 had no exits: a key from the future is a typo
    with pytest.raises(GraphFormatError, match=r"^islands\[0\]\.exits: unknown key"):
        json_io.graph_from_dict(doc)


def _bad(path: list[Any], value: Any) -> dict[str, Any]:
    doc = copy.deepcopy(json_io.graph_to_dict(*_parts()))
    obj: Any = doc
    for key in path[:-1]:
        obj = obj[key]
    obj[path[-1]] = value
    return doc


_X = ["islands", 0, "exits"]


@pytest.mark.parametrize(
    ("path", "value", "expected"),
    [
        ([*_X, 1, "heading_rad"], float("nan"), "islands[0].exits[1].heading_rad: NaN"),
        ([*_X, 1, "heading_rad"], 4.0, "islands[0].exits[1].heading_rad: must be in [-pi, pi]"),
        ([*_X, 0, "width_m"], 0.0, "islands[0].exits[0].width_m: must be > 0"),
        ([*_X, 0, "width_m"], 2e6, "islands[0].exits[0].width_m: |value| must be <= 1e+06"),
        ([*_X, 2, "index"], 1, "islands[0].exits[2].index: duplicate exit index 1 (also at [1])"),
        ([*_X, 0, "index"], -1, "islands[0].exits[0].index: must be >= 0"),
        ([*_X, 0, "state"], "open", "islands[0].exits[0].state: unknown exit state 'open'"),
        ([*_X, 0, "state"], "explored", "islands[0].exits[0]: exit 0: an explored exit names"),
        ([*_X, 2, "edge"], [3, 5], "islands[0].exits[2]: exit 2: an explored exit names"),
        ([*_X, 1, "edge"], [4, 5], "islands[0].exits[1].edge: edge 4->5 does not touch island 3"),
        ([*_X, 1, "edge"], [5, 3], "islands[0].exits[1].edge: exit 1 of island 3 explored by "
                                   "edge 5->3, which is not in the graph"),
        ([*_X, 1, "edge"], [3], "islands[0].exits[1].edge: expected [source, target]"),
        (["edges", 0, "source_exit"], 7, "edges[0].source_exit: island 3 has no exit 7"),
        (["edges", 0, "target_exit"], 1, "edges[0].target_exit: island 5 has no exit 1"),
        (["edges", 0, "source_exit"], "1", "edges[0].source_exit: expected an integer"),
        ([*_X, 0, "colour"], "red", "islands[0].exits[0].colour: unknown key"),
    ],
)
def test_inconsistent_exits_are_errors_naming_the_field(
    path: list[Any], value: Any, expected: str
) -> None:
    with pytest.raises(GraphFormatError) as info:
        json_io.graph_from_json(json.dumps(_bad(path, value)))
    assert str(info.value).startswith(expected), str(info.value)


def test_exit_types_check_themselves() -> None:
    with pytest.raises(IslandTypeError, match="explored exit names the edge"):
        Exit(0, 0.0, 1.0, EXPLORED)
    with pytest.raises(IslandTypeError, match="explored exit names the edge"):
        Exit(0, 0.0, 1.0, UNEXPLORED, (1, 2))
    with pytest.raises(IslandTypeError, match="heading_rad: expected a finite number"):
        Exit(0, math.inf, 1.0)
    with pytest.raises(IslandTypeError, match="width_m must be in"):
        Exit(0, 0.0, -1.0)
    with pytest.raises(IslandTypeError, match="duplicate exit index 0"):
        Island(1, LineModel(), ModelType.LINE, 0.5, 0.0, exits=(Exit(0, 0.0, 1.0),) * 2)
    with pytest.raises(IslandTypeError, match="source_exit must be an exit index"):
        Edge(1, 2, ControlStrategy(()), 1.0, source_exit=-2)


def test_exit_update_json() -> None:
    u = ExitUpdate(3, 1, EXPLORED, (3, 5))
    text = json_io.exit_update_to_json(u)
    assert json.loads(text) == {"island": 3, "exit": 1, "state": "explored", "edge": [3, 5]}
    assert json_io.exit_update_from_json(text) == u
    assert json_io.exit_update_from_json('{"island": 3, "exit": 2, "state": "blocked"}') == \
        ExitUpdate(3, 2, BLOCKED)
    for text, message in [
        ('{"island": 3, "exit": 1, "state": "explored"}', "exit: exit 1: an explored exit"),
        ('{"island": -3, "exit": 1, "state": "blocked"}', "exit.island: must be >= 0"),
        ('{"island": 3, "exit": 1, "state": "gone"}', "exit.state: unknown exit state"),
        ('{"island": 3, "state": "blocked"}', "exit.exit: missing"),
    ]:
        with pytest.raises(GraphFormatError) as info:
            json_io.exit_update_from_json(text)
        assert str(info.value).startswith(message), str(info.value)
