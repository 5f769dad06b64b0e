"""Side exits (an opening beside an edge, reached by a strategy prefix and a turn) in every
form of the saved graph; maps written before side exits still load; malformed ones are clear
errors naming what was wrong."""

from __future__ import annotations

import dataclasses
import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from island_mapping.core.graph import GraphError, TopoGraph
from island_mapping.core.graph.store import GraphStore
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitSide,
    ExitState,
    Island,
    IslandTypeError,
    LineModel,
    ModelType,
    NewExit,
)

from island_msgs_py import json_io

SIDE = Exit(3, 1.5708, 1.4, prefix=ControlStrategy.parse("Rot 90, Go 150, Rot 2, Go 300"),
            side=ExitSide.LEFT)


SCHEMA_1_EXITS = """CREATE TABLE exits (
    island INTEGER NOT NULL REFERENCES islands (id) ON DELETE CASCADE
        DEFERRABLE INITIALLY DEFERRED,
    idx INTEGER NOT NULL CHECK (idx >= 0),
    heading_rad REAL NOT NULL,
    width_m REAL NOT NULL CHECK (width_m > 0),
    state TEXT NOT NULL,
    edge_source INTEGER,
    edge_target INTEGER,
    crc INTEGER NOT NULL,
    PRIMARY KEY (island, idx),
    FOREIGN KEY (edge_source, edge_target) REFERENCES edges (source, target)
        DEFERRABLE INITIALLY DEFERRED
) STRICT"""
"""The exits table as schema 1 wrote it (before side exits)."""


def island(i: int, *exits: Exit) -> Island:
    rng = np.random.default_rng(i)
    return Island(i, LineModel(rng.uniform(-3, 3, (2, 4))), ModelType.LINE, 0.6, float(i),
                  exits=exits)


def graph() -> TopoGraph:
    """Island 0 with a plain exit 0 (explored by 0 -> 1) and side exit 3; island 1 plain."""
    return TopoGraph.from_parts(
        [island(0, Exit(0, 0.0, 1.2, ExitState.EXPLORED, (0, 1)), SIDE),
         island(1, Exit(0, 3.14, 1.2))],
        [Edge(0, 1, ControlStrategy.parse("Go 800"), 8.0, source_exit=0)])


def test_a_side_exit_survives_json_geojson_graphml(tmp_path: Path) -> None:
    g = graph()
    for path in (g.save_json(tmp_path / "g.json"), g.save_geojson(tmp_path / "g.geojson"),
                 g.save_graphml(tmp_path / "g.graphml")):
        back = TopoGraph.load_any(path)
        ex = back.get_island(0).exits[1]
        assert (ex.prefix, ex.side, ex.index) == (SIDE.prefix, ExitSide.LEFT, 3), path.name
        assert not back.get_island(0).exits[0].is_side
    doc = json.loads(g.to_json())
    assert doc["islands"][0]["exits"][1]["prefix"] == "Rot 90, Go 150, Rot 2, Go 300"
    assert "prefix" not in doc["islands"][0]["exits"][0]  # a plain exit is written as before
    geo = g.to_geojson()
    meta = next(f for f in geo["features"] if f["properties"].get("id") == 0)
    assert meta["properties"]["metadata"]["exits"]["3"]["side"] == "left"


def test_a_side_exit_survives_the_store_and_an_added_one_persists(tmp_path: Path) -> None:
    with GraphStore(tmp_path / "s") as store:
        store.put_island(island(0))
        store.add_exit(NewExit(0, SIDE))
        store.set_exit(0, 3, ExitState.BLOCKED)
    with GraphStore(tmp_path / "s", read_only=True) as again:
        ex = again.graph.get_island(0).exits[0]
        assert (ex.prefix, ex.side, ex.state) == (SIDE.prefix, ExitSide.LEFT, ExitState.BLOCKED)


def test_a_schema_1_store_loads_and_is_migrated(tmp_path: Path) -> None:
    """A store written before side exits (no prefix/side columns, user_version 1)."""
    with GraphStore(tmp_path / "s") as store:
        store.put_island(island(0, Exit(0, 0.0, 1.2)))
    db = next((tmp_path / "s").glob("*.sqlite3"))
    conn = sqlite3.connect(db, isolation_level=None)
    conn.execute("PRAGMA foreign_keys = OFF")
    conn.execute("BEGIN")
    conn.execute(SCHEMA_1_EXITS.replace("CREATE TABLE exits", "CREATE TABLE old"))
    conn.execute("INSERT INTO old SELECT island, idx, heading_rad, width_m, state, "
                 "edge_source, edge_target, crc FROM exits")
    conn.execute("DROP TABLE exits")
    conn.execute("ALTER TABLE old RENAME TO exits")
    conn.execute("PRAGMA user_version = 1")
    conn.execute("COMMIT")
    conn.close()
    with GraphStore(tmp_path / "s", read_only=True) as ro:
        assert not ro.graph.get_island(0).exits[0].is_side
    with GraphStore(tmp_path / "s") as rw:  # migrated on open: a side exit can be added
        rw.add_exit(NewExit(0, SIDE))
    with GraphStore(tmp_path / "s") as again:
        assert [e.is_side for e in again.graph.get_island(0).exits] == [False, True]


def test_an_old_document_without_the_fields_loads_as_plain_exits() -> None:
    doc = json.loads(graph().to_json())
    for ex in doc["islands"][0]["exits"]:
        ex.pop("prefix", None)
        ex.pop("side", None)
    g = TopoGraph.from_dict(doc)
    assert not any(e.is_side for i in g.islands() for e in i.exits)


def test_a_malformed_side_exit_is_an_error_naming_the_field() -> None:
    doc = json.loads(graph().to_json())
    doc["islands"][0]["exits"][1]["prefix"] = "Go 300, Fly 2"
    with pytest.raises(GraphFormatError, match=r"islands\[0\]\.exits\[1\]\.prefix: not a "
                                               r"strategy.*'Fly 2'"):
        TopoGraph.from_dict(doc)
    doc["islands"][0]["exits"][1]["prefix"] = "Go 300"
    doc["islands"][0]["exits"][1]["side"] = "up"
    with pytest.raises(GraphFormatError, match=r"exits\[1\]\.side: unknown side 'up'"):
        TopoGraph.from_dict(doc)
    del doc["islands"][0]["exits"][1]["side"]
    with pytest.raises(GraphFormatError, match=r"exits\[1\]\.side: a side exit needs both"):
        TopoGraph.from_dict(doc)
    with pytest.raises(IslandTypeError, match="prefix must drive"):
        Exit(0, 0.0, 1.0, prefix=ControlStrategy.parse("Rot 90"), side=ExitSide.RIGHT)


def test_a_new_exit_names_an_unknown_island_or_a_taken_index() -> None:
    g = graph()
    with pytest.raises(GraphError, match="new exit: unknown island 7"):
        g.add_exit(NewExit(7, SIDE))
    with pytest.raises(GraphError, match="already has exit 3"):
        g.add_exit(NewExit(0, SIDE))
    added = g.add_exit(NewExit(1, dataclasses.replace(SIDE, index=1)))
    assert [e.index for e in added.exits] == [0, 1]
    with pytest.raises(GraphFormatError, match=r"new_exit\.exit\.prefix: not a strategy"):
        json_io.new_exit_from_json('{"island": 1, "exit": {"index": 2, "heading_rad": 0.0, '
                                   '"width_m": 1.0, "state": "unexplored", "prefix": "Go x", '
                                   '"side": "left"}}')
    item = NewExit(1, dataclasses.replace(SIDE, index=2))
    assert json_io.new_exit_from_json(json_io.new_exit_to_json(item)) == item


def test_a_new_exit_is_a_topo_graph_add_item() -> None:
    from island_msgs_py import conversions as cv
    item = NewExit(2, dataclasses.replace(SIDE, index=5))
    param = cv.new_exit_to_parameter(item)
    assert param.name == "new_exit" and cv.parameter_to_item(param) == item
