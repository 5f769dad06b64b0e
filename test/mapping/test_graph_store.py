"""GraphStore (SQLite): every accepted change is committed before it is acknowledged, one
transaction each; reload rebuilds it; a damaged store or a directory that is not a store is
refused and left as it is."""

from __future__ import annotations

import shutil
import sqlite3
from pathlib import Path

import numpy as np
import pytest
from island_mapping.core.graph import GraphError, GraphStore, GraphStoreError, TopoGraph
from island_mapping.core.graph import store_schema as sch
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitState,
    Island,
    LineModel,
    ModelType,
)

DB = sch.DATABASE


def island(i: int, r: float = 0.5, exits: tuple[Exit, ...] = ()) -> Island:
    rng = np.random.default_rng(i)
    return Island(i, LineModel(rng.uniform(-3, 3, (4, 4))), ModelType.LINE, r, float(i),
                  exits=exits)


def edge(a: int, b: int, w: float = 1.0, **kw: int) -> Edge:
    return Edge(a, b, ControlStrategy.parse("Go 125, Rot 270, Go 652"), w, length_m=w, **kw)


def _fill(store: GraphStore, n: int) -> None:
    for i in range(n):
        store.put_island(island(i))
        if i:
            store.put_edge(edge(i - 1, i, float(i)))


def _sql(path: Path, statement: str, *args: object) -> list[tuple[object, ...]]:
    """Run SQL on a store's database from outside it (as a user with the sqlite3 tool would)."""
    conn = sqlite3.connect(path / DB, isolation_level=None)
    try:
        return conn.execute(statement, args).fetchall()
    finally:
        conn.close()


def _files(path: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(path.iterdir()) if p.is_file()}


def _unchanged(path: Path, before: dict[str, bytes]) -> None:
    """Every file is as it was; opening may only have added SQLite's empty log and its index."""
    after = _files(path)
    assert {k: after[k] for k in before} == before
    assert set(after) - set(before) <= {f"{DB}-wal", f"{DB}-shm"}
    assert after.get(f"{DB}-wal", b"") == before.get(f"{DB}-wal", b"")


def test_reload_gives_the_same_graph(tmp_path: Path) -> None:
    with GraphStore(tmp_path / "s") as store:
        _fill(store, 6)
        store.put_island(island(2, r=0.9))  # replace
        store.put_edge(edge(0, 1, 7.0))  # replace
        store.remove_edge(3, 4)
        store.remove_island(5)
        want = store.graph.to_json()
    with GraphStore(tmp_path / "s") as again:
        assert again.graph.to_json() == want
        assert again.graph.get_island(2).r == 0.9 and again.graph.get_edge(0, 1).weight == 7.0
        assert not again.graph.has_edge(3, 4) and 5 not in again.graph


def test_each_acknowledged_change_is_committed_in_wal_mode_with_full_sync(tmp_path: Path) -> None:
    with GraphStore(tmp_path) as store:
        assert _sql(tmp_path, "PRAGMA journal_mode") == [("wal",)]
        for i in range(5):
            store.put_island(island(i))
            # another connection sees it at once: committed, not buffered until close
            assert _sql(tmp_path, "SELECT count(*) FROM islands") == [(i + 1,)]
            assert len(GraphStore.read(tmp_path)) == i + 1
        assert _sql(tmp_path, "PRAGMA user_version") == [(sch.SCHEMA_VERSION,)]
        assert _sql(tmp_path, "PRAGMA application_id") == [(sch.APPLICATION_ID,)]


def test_exits_are_stored_and_changed_one_transaction_each(tmp_path: Path) -> None:
    four = tuple(Exit(k, a, 1.0) for k, a in enumerate((0.0, 1.57, 3.14, -1.57)))
    with GraphStore(tmp_path) as store:
        store.put_island(island(0, exits=four))
        store.put_island(island(1, exits=four))
        store.put_edge(edge(0, 1, source_exit=0, target_exit=2))
        store.set_exit(0, 0, ExitState.EXPLORED, (0, 1))
        store.set_exit(1, 3, ExitState.BLOCKED)
        want = store.graph.to_json()
    with GraphStore(tmp_path) as again:
        assert again.graph.to_json() == want
        assert again.graph.get_island(0).exits[0].edge == (0, 1)
        again.remove_edge(0, 1)  # resets the exit it explored, in the same transaction
    back = GraphStore.read(tmp_path)
    assert back.get_island(0).exits[0].state is ExitState.UNEXPLORED
    assert back.get_island(1).exits[3].state is ExitState.BLOCKED


def test_rejected_changes_leave_the_database_unchanged(tmp_path: Path) -> None:
    with GraphStore(tmp_path) as store:
        _fill(store, 2)
        dump = _sql(tmp_path, "SELECT * FROM islands") + _sql(tmp_path, "SELECT * FROM edges")
        with pytest.raises(GraphError, match="unknown target island 5"):
            store.put_edge(edge(0, 5))
        with pytest.raises(GraphError, match="unknown island 8"):
            store.remove_island(8)
        with pytest.raises(GraphError, match="island 1 has no exit 3"):
            store.put_edge(edge(1, 0, source_exit=3))
        with pytest.raises(GraphError, match="no such exit"):
            store.set_exit(0, 0, ExitState.BLOCKED)
        assert _sql(tmp_path, "SELECT * FROM islands") + \
            _sql(tmp_path, "SELECT * FROM edges") == dump


def test_store_of_a_copied_directory_is_independent(tmp_path: Path) -> None:
    with GraphStore(tmp_path / "a") as store:
        _fill(store, 4)
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    with GraphStore(tmp_path / "b") as b:
        b.put_island(island(10))
    assert 10 not in GraphStore.read(tmp_path / "a")
    assert TopoGraph.from_json(GraphStore.read(tmp_path / "b").to_json()).island_ids()[-1] == 10


def test_one_writer_at_a_time_and_read_only_changes_nothing(tmp_path: Path) -> None:
    with GraphStore(tmp_path) as store:
        _fill(store, 3)
        with pytest.raises(GraphError, match="in use by another process"):
            GraphStore(tmp_path)
        assert GraphStore.read(tmp_path).island_ids() == [0, 1, 2]  # readers are fine
    before = (tmp_path / DB).read_bytes()
    ro = GraphStore(tmp_path, read_only=True)
    with pytest.raises(GraphError, match="read-only"):
        ro.put_island(island(5))
    assert ro.graph.island_ids() == [0, 1, 2]
    ro.close()
    assert (tmp_path / DB).read_bytes() == before
    with pytest.raises(GraphFormatError, match="no such graph store"):
        GraphStore.read(tmp_path / "missing")


def test_a_failed_write_is_not_applied_and_leaves_nothing_partial(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    store = GraphStore(tmp_path)
    _fill(store, 2)
    real = sch.exit_row

    def disk_full(island_id: int, e: Exit) -> tuple[object, ...]:
        if e.index == 1:  # after the island row and its first exit were written
            raise OSError(28, "No space left on device")
        return real(island_id, e)

    monkeypatch.setattr(sch, "exit_row", disk_full)
    with pytest.raises(OSError, match="No space left"):
        store.put_island(island(5, exits=(Exit(0, 0.0, 1.0), Exit(1, 1.0, 1.0))))
    monkeypatch.undo()
    assert 5 not in store.graph
    assert _sql(tmp_path, "SELECT count(*) FROM islands WHERE id = 5") == [(0,)]
    assert _sql(tmp_path, "SELECT count(*) FROM exits") == [(0,)]
    store.put_island(island(6))
    store.close()
    assert GraphStore.read(tmp_path).island_ids() == [0, 1, 6]


# ----------------------------------------------------------------------------- what is a store


def test_only_a_directory_that_holds_a_store_is_a_store(tmp_path: Path) -> None:
    other = tmp_path / "etc"
    other.mkdir()
    (other / "passwd").write_text("root:x:0:0\n")
    for open_it in (lambda: GraphStore.read(other), lambda: GraphStore(other)):
        with pytest.raises(GraphStoreError, match="not a graph store"):
            open_it()
    assert [p.name for p in other.iterdir()] == ["passwd"]  # nothing created there
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(GraphStoreError, match="not a graph store"):
        GraphStore.read(empty)  # reading an empty directory is not reading an empty store
    with GraphStore(empty) as store:  # but a writer may start a store there
        store.put_island(island(0))
    assert GraphStore.read(empty).island_ids() == [0]
    (tmp_path / "file").write_text("x")
    with pytest.raises(GraphStoreError, match="not a graph store"):
        GraphStore(tmp_path / "file")


def _damage_cases() -> list[tuple[str, str]]:
    return [
        ("changed_value", "checksum mismatch"),
        ("truncated", "damaged store"),
        ("garbage_page", "damaged store"),
        ("deleted_edge", "rows refer to rows that are missing"),
        ("foreign_sqlite", "not an islands graph store"),
        ("newer_schema", "written by a newer version"),
        ("orphan_wal", "database file is missing but its write-ahead log"),
        ("deleted_database", r"database file is missing \(the store had made one\)"),
    ]


def _damage(path: Path, how: str) -> None:
    db = path / DB
    if how == "changed_value":  # a changed digit, as a bit flip on disk would do
        _sql(path, "UPDATE islands SET r = 0.6 WHERE id = 2")
    elif how == "truncated":
        data = db.read_bytes()
        db.write_bytes(data[: len(data) // 2])
    elif how == "garbage_page":  # the islands table's page overwritten
        [(root,)] = _sql(path, "SELECT rootpage FROM sqlite_master WHERE name = 'islands'")
        [(size,)] = _sql(path, "PRAGMA page_size")
        data = bytearray(db.read_bytes())
        start = (int(root) - 1) * int(size)
        data[start: start + int(size)] = np.random.default_rng(0).bytes(int(size))
        db.write_bytes(bytes(data))
    elif how == "deleted_edge":  # a row deleted by hand: an exit still names it
        _sql(path, "DELETE FROM edges WHERE source = 0 AND target = 1")
    elif how == "foreign_sqlite":
        db.unlink()
        _sql(path, "CREATE TABLE notes (text TEXT)")
    elif how == "newer_schema":
        _sql(path, "PRAGMA user_version = 99")
    elif how == "deleted_database":  # not an empty directory to start afresh in
        db.unlink()
    elif how == "orphan_wal":
        shutil.copy(db, path / f"{DB}-wal")
        db.unlink()


@pytest.mark.parametrize(("how", "message"), _damage_cases())
def test_a_damaged_store_is_refused_and_left_as_it_is(
    tmp_path: Path, how: str, message: str
) -> None:
    four = tuple(Exit(k, 0.5 * k, 1.0) for k in range(4))
    with GraphStore(tmp_path) as store:
        for i in range(8):
            store.put_island(island(i, exits=four))
        for i in range(7):
            store.put_edge(edge(i, i + 1, source_exit=0, target_exit=1))
        store.set_exit(0, 0, ExitState.EXPLORED, (0, 1))
    _damage(tmp_path, how)
    before = _files(tmp_path)
    for open_it in (lambda: GraphStore(tmp_path), lambda: GraphStore.read(tmp_path)):
        with pytest.raises(GraphStoreError, match=message) as info:
            open_it()
        assert str(tmp_path) in str(info.value)
        if "damaged store:" in str(info.value):
            assert "islands graph salvage" in str(info.value)  # the recovery path
    _unchanged(tmp_path, before)


def test_salvage_copies_what_is_intact_and_lists_what_is_lost(tmp_path: Path) -> None:
    from island_mapping.core.graph import salvage_store

    four = tuple(Exit(k, 0.5 * k, 1.0) for k in range(4))
    src = tmp_path / "store"
    with GraphStore(src) as store:
        for i in range(6):
            store.put_island(island(i, exits=four))
        for i in range(5):
            store.put_edge(edge(i, i + 1, source_exit=0, target_exit=1))
        store.set_exit(3, 0, ExitState.EXPLORED, (3, 4))
        want = store.graph
    _sql(src, "UPDATE islands SET r = 0.6 WHERE id = 4")  # island 4 is damaged
    before = _files(src)
    report = salvage_store(src, tmp_path / "new")
    _unchanged(src, before)
    got = GraphStore.read(tmp_path / "new")
    assert got.island_ids() == [0, 1, 2, 3, 5]
    assert [(e.source, e.target) for e in got.edges()] == [(0, 1), (1, 2), (2, 3)]
    assert got.get_island(3).exits[0].state is ExitState.UNEXPLORED  # its edge went with 4
    for i in (0, 1, 2, 5):
        assert got.get_island(i) == want.get_island(i)
    assert report.islands == 5 and report.edges == 3 and report.exits == 20
    assert any("islands row (id 4): checksum mismatch" in lost for lost in report.lost)
    assert any("edge 3->4" in lost for lost in report.lost)
    assert any("island 3 exit 0" in lost for lost in report.lost)
    with pytest.raises(GraphStoreError, match="missing or empty directory"):
        salvage_store(src, tmp_path / "new")
