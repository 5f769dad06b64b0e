"""A store written in the format before SQLite (snapshot.json + changes.jsonl, the write-ahead log
of docs/graph_server.md before this version) is imported into the new database on the first
writable open, its files kept aside; a damaged one is refused naming the file and line."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from island_mapping.core.graph import GraphStore, GraphStoreError, TopoGraph
from island_mapping.core.graph.store_schema import DATABASE
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType

from island_msgs_py import json_io


def _island(i: int, r: float = 0.5) -> Island:
    rng = np.random.default_rng(i)
    return Island(i, LineModel(rng.uniform(-3, 3, (4, 4))), ModelType.LINE, r, float(i))


def _edge(a: int, b: int, w: float) -> Edge:
    return Edge(a, b, ControlStrategy.parse("Go 125, Rot 270, Go 652"), w, length_m=w)


def _v1_island(island: Island) -> dict[str, Any]:
    d = json_io.island_to_dict(island)
    assert "exits" not in d  # no exits: written as version 1 wrote it
    return d


def _v1_edge(edge: Edge) -> dict[str, Any]:
    d = json_io.edge_to_dict(edge)
    assert "source_exit" not in d and "target_exit" not in d
    return d


def _old_store(path: Path) -> TopoGraph:
    """Write a store as the old GraphStore did: islands 0-5 and a chain of edges compacted into
    snapshot.json at seq 9, then 5 logged changes (a replace, a removal, a re-added island)."""
    path.mkdir(parents=True, exist_ok=True)
    g = TopoGraph()
    for i in range(5):
        g.add_island(_island(i))
        if i:
            g.add_edge(_edge(i - 1, i, float(i)))
    graph_doc = json_io.graph_to_dict(g.islands(), g.edges())
    graph_doc["version"] = 1
    graph_doc["islands"] = [_v1_island(i) for i in g.islands()]
    graph_doc["edges"] = [_v1_edge(e) for e in g.edges()]
    (path / "snapshot.json").write_text(json.dumps(
        {"format": "islands-graph-snapshot", "version": 1, "seq": 9, "graph": graph_doc}) + "\n")
    log = [
        {"seq": 8, "op": "put_island", "island": _v1_island(_island(4))},  # already in snapshot
        {"seq": 10, "op": "put_island", "island": _v1_island(_island(2, r=0.9))},
        {"seq": 11, "op": "remove_edge", "source": 3, "target": 4},
        {"seq": 12, "op": "remove_island", "id": 4},
        {"seq": 13, "op": "put_island", "island": _v1_island(_island(4, r=0.25))},
        {"seq": 14, "op": "put_edge", "edge": _v1_edge(_edge(0, 4, 7.0))},
    ]
    (path / "changes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in log))
    g.put_island(_island(2, r=0.9))
    g.remove_edge(3, 4)
    g.remove_island(4)
    g.put_island(_island(4, r=0.25))
    g.put_edge(_edge(0, 4, 7.0))
    return g


def test_an_old_store_is_imported_and_its_files_kept_aside(tmp_path: Path) -> None:
    want = _old_store(tmp_path)
    snapshot = (tmp_path / "snapshot.json").read_bytes()
    log = (tmp_path / "changes.jsonl").read_bytes()
    assert GraphStore.read(tmp_path) == want  # read in place, nothing changed
    assert not (tmp_path / DATABASE).exists()
    with GraphStore(tmp_path) as store:
        assert store.migrated and store.graph == want
        assert store.legacy is not None and store.legacy.seq == 14
        store.put_island(_island(9))  # and it is a working store
    assert (tmp_path / "pre-sqlite" / "snapshot.json").read_bytes() == snapshot
    assert (tmp_path / "pre-sqlite" / "changes.jsonl").read_bytes() == log
    assert not (tmp_path / "snapshot.json").exists() and not (tmp_path / "changes.jsonl").exists()
    conn = sqlite3.connect(tmp_path / DATABASE)
    (source,) = conn.execute("SELECT value FROM meta WHERE key = 'migrated_from'").fetchone()
    conn.close()
    assert "seq 14" in source
    with GraphStore(tmp_path) as again:
        assert not again.migrated
        assert again.graph.island_ids() == [0, 1, 2, 3, 4, 9]
        assert again.graph.get_island(2).r == 0.9 and again.graph.get_edge(0, 4).weight == 7.0


def test_a_torn_last_line_was_never_acknowledged_and_is_dropped(tmp_path: Path) -> None:
    want = _old_store(tmp_path)
    with open(tmp_path / "changes.jsonl", "ab") as f:
        f.write(b'{"seq": 15, "op": "put_island", "island": {"id": 9, "mod')  # killed mid-write
    with GraphStore(tmp_path) as store:
        assert store.legacy is not None and store.legacy.dropped_torn_tail
        assert store.graph == want


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ("garbage", r"changes\.jsonl:3: corrupt change record"),
        ('{"seq": 99, "op": "remove_island"}', r"changes\.jsonl:3\.id: expected an integer"),
        ('{"seq": 99, "op": "fly"}', r"changes\.jsonl:3\.op: unknown operation 'fly'"),
        ('{"op": "put_edge"}', r"changes\.jsonl:3: change record without an integer seq"),
        ('{"seq": 99, "op": "remove_edge", "source": 0, "target": 3}', "cannot replay: no edge"),
        ('{"seq": 99, "op": "remove_island", "id": ' + "9" * 5000 + "}",
         r"changes\.jsonl:3: corrupt change record"),
    ],
)
def test_a_damaged_old_store_is_refused_naming_the_line_and_left_as_it_is(
    tmp_path: Path, bad: str, message: str
) -> None:
    _old_store(tmp_path)
    lines = (tmp_path / "changes.jsonl").read_text().splitlines()
    lines[2] = bad
    (tmp_path / "changes.jsonl").write_text("\n".join(lines) + "\n")
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(GraphFormatError, match=message):
        GraphStore(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([*before, ".lock"])


def test_a_migration_cut_short_is_finished_or_redone(tmp_path: Path) -> None:
    want = _old_store(tmp_path / "a")
    # killed while writing the new database: the partial file is discarded, the import redone
    (tmp_path / "a" / f"{DATABASE}.importing").write_bytes(b"SQLite format 3\x00 partial")
    with GraphStore(tmp_path / "a") as store:
        assert store.migrated and store.graph == want
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == [".lock", DATABASE,
                                                                   "pre-sqlite"]
    # killed after the database was renamed into place, before the old files were moved aside
    _old_store(tmp_path / "b")
    with GraphStore(tmp_path / "b"):
        pass
    for name in ("snapshot.json", "changes.jsonl"):
        (tmp_path / "b" / "pre-sqlite" / name).rename(tmp_path / "b" / name)
    with GraphStore(tmp_path / "b") as store:
        assert not store.migrated and store.graph == want  # nothing imported twice
    assert not (tmp_path / "b" / "snapshot.json").exists()
    # a database beside old files it did not import: which is right is not ours to guess
    with GraphStore(tmp_path / "c") as store:
        store.put_island(_island(0))
    _old_store(tmp_path / "old")
    for name in ("snapshot.json", "changes.jsonl"):
        (tmp_path / "old" / name).rename(tmp_path / "c" / name)
    with pytest.raises(GraphStoreError, match=r"holds both graph\.sqlite3 and old-format files"):
        GraphStore(tmp_path / "c")
