"""Exits in the graph: set_exit, consistency with the edges kept by every change, three formats."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from island_mapping.core.graph import GraphError, TopoGraph
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitState,
    ExitUpdate,
    Island,
    LineModel,
    ModelType,
)

EXPLORED, UNEXPLORED, BLOCKED = ExitState.EXPLORED, ExitState.UNEXPLORED, ExitState.BLOCKED


def island(i: int, *exits: Exit) -> Island:
    rng = np.random.default_rng(i)
    return Island(i, LineModel(rng.uniform(-3, 3, (2, 4))), ModelType.LINE, 0.6, float(i),
                  exits=exits)


def junction(i: int) -> Island:
    """Four unexplored exits: east, north, west, south."""
    return island(i, *(Exit(k, a, 1.2) for k, a in enumerate((0.0, 1.5708, 3.1415, -1.5708))))


def graph() -> TopoGraph:
    """Junctions 0, 1, 2; 0 -> 1 leaves 0 by exit 0 and enters 1 by exit 2 (0 explored by it);
    1 -> 2 by exits 1 and 3, not yet marked."""
    g = TopoGraph.from_parts(
        [dataclasses.replace(junction(0), exits=(
            Exit(0, 0.0, 1.2, EXPLORED, (0, 1)), *junction(0).exits[1:])), junction(1),
         junction(2)],
        [Edge(0, 1, ControlStrategy.parse("Go 500"), 5.0, source_exit=0, target_exit=2),
         Edge(1, 2, ControlStrategy.parse("Rot 90, Go 400"), 4.0, source_exit=1, target_exit=3)],
    )
    return g


def states(g: TopoGraph, i: int) -> list[tuple[str, tuple[int, int] | None]]:
    return [(e.state.value, e.edge) for e in g.get_island(i).exits]


def test_from_parts_accepts_an_exit_explored_by_a_later_edge() -> None:
    g = graph()
    assert states(g, 0)[0] == ("explored", (0, 1))
    assert TopoGraph.from_json(g.to_json()) == g


def test_set_exit_changes_one_exit_and_says_which() -> None:
    g = graph()
    version = g.version
    changed = g.set_exit(1, 1, EXPLORED, (1, 2))
    assert g.get_island(1) == changed and g.version == version + 1
    assert states(g, 1)[1] == ("explored", (1, 2))
    g.set_exit(2, 3, EXPLORED, (1, 2))  # the target end may record it too
    g.set_exit(2, 0, BLOCKED)
    assert [s for s, _ in states(g, 2)] == ["blocked", "unexplored", "unexplored", "explored"]
    g.set_exit(2, 0, UNEXPLORED)
    assert states(g, 2)[0] == ("unexplored", None)
    assert g.apply_exit_update(ExitUpdate(1, 0, BLOCKED)).exits[0].state is BLOCKED


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (lambda g: g.set_exit(9, 0, BLOCKED), "exit update: unknown island 9"),
        (lambda g: g.set_exit(1, 7, BLOCKED), r"island 1: exit 7: no such exit .*\[0, 1, 2, 3\]"),
        (lambda g: g.set_exit(1, 1, EXPLORED, (2, 1)), "explored by edge 2->1, which is not in"),
        (lambda g: g.set_exit(1, 1, EXPLORED, (0, 2)), "edge 0->2, which does not touch"),
        (lambda g: g.apply_exit_update("exit 1"), "expected an ExitUpdate"),
        (lambda g: g.put_edge(Edge(2, 0, ControlStrategy(()), 1.0, source_exit=4)),
         "edge 2->0: source_exit 4: island 2 has no exit 4"),
        (lambda g: g.put_edge(Edge(2, 0, ControlStrategy(()), 1.0, target_exit=9)),
         "edge 2->0: target_exit 9: island 0 has no exit 9"),
        (lambda g: g.put_island(island(1)),
         r"island 1: exit 2 is named by edge 0->1 \(target_exit\)"),
        (lambda g: g.put_island(island(7, Exit(0, 0.0, 1.0, EXPLORED, (7, 1)))),
         "island 7: exit 0 explored by edge 7->1, which is not in the graph"),
    ],
)
def test_inconsistent_exit_changes_are_rejected_and_change_nothing(
    action: Any, message: str
) -> None:
    g = graph()
    before, version = g.to_json(), g.version
    with pytest.raises(GraphError, match=message):
        action(g)
    assert g.to_json() == before and g.version == version


def test_removing_an_edge_sets_the_exits_it_explored_back_to_unexplored() -> None:
    g = graph()
    g.set_exit(1, 2, EXPLORED, (0, 1))
    g.set_exit(1, 1, EXPLORED, (1, 2))
    g.remove_edge(0, 1)
    assert states(g, 0)[0] == ("unexplored", None) and states(g, 1)[2] == ("unexplored", None)
    assert states(g, 1)[1] == ("explored", (1, 2))  # another edge's exit is left alone
    assert g.get_island(0).exits[0].heading_rad == 0.0 and g.get_island(0).exits[0].width_m == 1.2
    g.remove_island(2)
    assert states(g, 1)[1] == ("unexplored", None)
    assert TopoGraph.from_json(g.to_json()) == g  # still a consistent map


def test_exits_in_all_three_formats(tmp_path: Path) -> None:
    g = graph()
    g.set_exit(1, 0, BLOCKED)
    for p in g.save_all(tmp_path).values():
        assert TopoGraph.load_any(p) == g, p
    doc = g.to_geojson()
    points = {f["properties"]["id"]: f for f in doc["features"] if f["geometry"]["type"] == "Point"}
    ex = points[0]["properties"]["metadata"]["exits"]
    assert ex["0"] == {"heading_rad": 0.0, "width_m": 1.2, "state": "explored", "edge": [0, 1]}
    assert ex["1"] == {"heading_rad": 1.5708, "width_m": 1.2, "state": "unexplored"}  # no null
    lines = [f["properties"] for f in doc["features"] if f["geometry"]["type"] != "Point"]
    fwd = next(p for p in lines if (p["startid"], p["endid"]) == (0, 1))
    back = next(p for p in lines if (p["startid"], p["endid"]) == (1, 0))
    assert (fwd["metadata"]["source_exit"], fwd["metadata"]["target_exit"]) == (0, 2)
    assert back["metadata"]["derived"]
    assert (back["metadata"]["source_exit"], back["metadata"]["target_exit"]) == (2, 0)
    graphml = (tmp_path / "graph.graphml").read_text()
    assert 'attr.name="exits"' in graphml and 'attr.name="source_exit"' in graphml


def test_geojson_exit_errors_name_the_field() -> None:
    doc = graph().to_geojson()
    meta = doc["features"][1]["properties"]["metadata"]
    meta["exits"]["3"]["heading_rad"] = math.nan
    with pytest.raises(GraphFormatError,
                       match=r"^features\[1\]\.properties\.metadata\.exits\.3\.heading_rad: NaN"):
        TopoGraph.from_geojson(json.loads(json.dumps(doc)))
    meta["exits"] = {"x": {"heading_rad": 0.0, "width_m": 1.0, "state": "blocked"}}
    with pytest.raises(GraphFormatError, match=r"metadata\.exits\.x: an exit key must be"):
        TopoGraph.from_geojson(doc)
