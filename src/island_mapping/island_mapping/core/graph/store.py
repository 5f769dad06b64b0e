"""`GraphStore`: a TopoGraph persisted in a directory as a SQLite database (standard library).

The directory holds `graph.sqlite3` (plus `graph.sqlite3-wal` and `-shm` while in use or after
a crash: they are part of the store) and `.lock`. The database runs in WAL mode with
`synchronous=FULL`; every accepted change is validated against the graph first, then written
in ONE transaction (an island with its exits, an edge, an exit's new state, a removal with the
exits it resets) and committed, and only then applied in memory and acknowledged: a process
killed at any moment loses no acknowledged change, and a change never half happens.

On open the store is checked: the SQLite header says it is an islands graph store of a schema
this build reads, `PRAGMA quick_check` (or `integrity_check`) and `foreign_key_check` pass,
every row's checksum matches, and the rows form a valid graph. A damaged store is refused with
`GraphStoreError` (naming the file, the problem and the recovery path) and left as it is; it is
never read as a smaller valid graph. Only a directory that holds a store is one: an existing
directory with anything else in it is refused, never taken as an empty store. A store of the
format before SQLite (snapshot.json + changes.jsonl) is imported into a new database on the
first writable open and its files are kept aside in `pre-sqlite/`; read-only opens read it in
place. One writer at a time: a writable store holds `flock` on `.lock` (released by the kernel
even on SIGKILL); readers may read while it writes.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import sqlite3
from collections.abc import Iterable, Iterator
from enum import StrEnum
from pathlib import Path

from island_msgs_py.json_io import GraphFormatError, fsync_dir
from island_msgs_py.types import Edge, Exit, ExitState, ExitUpdate, Island, NewExit

from island_mapping.core.graph import store_schema as sch
from island_mapping.core.graph.config import GraphStoreConfig
from island_mapping.core.graph.errors import GraphError
from island_mapping.core.graph.legacy_store import (
    LEGACY_FILES,
    LegacyStore,
    is_legacy_store,
    read_legacy_store,
)
from island_mapping.core.graph.model import PutMode, TopoGraph

LOCK = ".lock"
# Written into the lock file once the store's database exists: a directory whose lock file says
# so but holds no database lost it (deleted), and is not a place to start an empty store.
DATABASE_MADE = b"graph.sqlite3 made\n"
LEGACY_ASIDE = "pre-sqlite"  # where the files of a migrated old-format store are kept
IMPORTING_SUFFIX = ".importing"  # a database being written whole; renamed when complete
RECOVERY = ("the store was left unchanged; recovery: `islands graph salvage DIR --out NEW_DIR` "
            "copies every intact island, edge and exit into a new store and lists what was lost "
            "(docs/graph_server.md, Persistence)")


class GraphStoreError(GraphFormatError):
    """A directory is not a usable graph store: damaged, not a store, or of a newer schema.
    The message names the file and the problem (and, when damaged, the recovery path)."""


class DirState(StrEnum):
    """What a directory holds, as the store sees it."""

    MISSING = "missing"
    NEW = "new"  # empty (or only the lock file): a store may be created
    DATABASE = "database"
    LEGACY = "legacy"  # snapshot.json / changes.jsonl, no database yet
    ORPHAN_WAL = "orphan_wal"  # a write-ahead log without its database
    LOST_DATABASE = "lost_database"  # the lock file says a database was made; it is gone
    FOREIGN = "foreign"  # something else: not a store


def classify(directory: Path) -> DirState:
    if not directory.exists():
        return DirState.MISSING
    if not directory.is_dir():
        return DirState.FOREIGN
    names = {p.name for p in directory.iterdir()}
    if sch.DATABASE in names:
        return DirState.DATABASE
    if f"{sch.DATABASE}-wal" in names:
        return DirState.ORPHAN_WAL
    if is_legacy_store(directory):
        return DirState.LEGACY
    if names <= {LOCK, sch.DATABASE + IMPORTING_SUFFIX}:
        lock = directory / LOCK
        if LOCK in names and lock.is_file() and lock.read_bytes()[:64] == DATABASE_MADE:
            return DirState.LOST_DATABASE
        return DirState.NEW
    return DirState.FOREIGN


def _damaged(path: Path, problem: str) -> GraphStoreError:
    return GraphStoreError(str(path), f"damaged store: {problem}; {RECOVERY}")


def _connect(path: Path, read_only: bool) -> sqlite3.Connection:
    mode = "ro" if read_only else "rwc"
    return sqlite3.connect(f"{path.absolute().as_uri()}?mode={mode}", uri=True,
                           isolation_level=None, check_same_thread=False)


def _header(conn: sqlite3.Connection, path: Path) -> bool:
    """Check the SQLite header; True when the file is a new, empty database."""
    app_id = conn.execute("PRAGMA application_id").fetchone()[0]
    version = conn.execute("PRAGMA user_version").fetchone()[0]
    tables = conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
    if app_id == 0 and version == 0 and tables == 0:
        return True
    if app_id != sch.APPLICATION_ID:
        raise GraphStoreError(str(path), f"not an islands graph store (SQLite application_id "
                                         f"{app_id:#x}, expected {sch.APPLICATION_ID:#x})")
    if version > sch.SCHEMA_VERSION:
        raise GraphStoreError(str(path), f"written by a newer version (schema {version}; this "
                                         f"build reads up to {sch.SCHEMA_VERSION})")
    if version < 1:
        raise _damaged(path, f"schema version {version} in the header")
    return False


def _check_integrity(conn: sqlite3.Connection, path: Path, full: bool) -> None:
    check = "integrity_check" if full else "quick_check"
    problems = [r[0] for r in conn.execute(f"PRAGMA {check}").fetchall()]
    if problems != ["ok"]:
        raise _damaged(path, f"PRAGMA {check}: {'; '.join(problems[:3])}")
    fk = conn.execute("PRAGMA foreign_key_check").fetchall()
    if fk:
        raise _damaged(path, f"{len(fk)} rows refer to rows that are missing (first: table "
                             f"{fk[0][0]}, row {fk[0][1]} -> {fk[0][2]})")


def read_rows(conn: sqlite3.Connection) -> tuple[list[Island], list[Edge]]:
    """The islands (with their exits) and edges of a store, from one read transaction;
    RowError naming the first row that is not valid."""
    conn.execute("BEGIN")
    try:
        exits: dict[int, list[Exit]] = {}
        cols = ", ".join(sch.exits_select(conn))
        for row in conn.execute(f"SELECT {cols} FROM exits ORDER BY island, idx"):
            island_id, e = sch.exit_from_row(row)
            exits.setdefault(island_id, []).append(e)
        islands = [sch.island_from_row(row, exits.pop(row[0], []))
                   for row in conn.execute(sch.SELECT_ISLANDS)]
        if exits:
            raise sch.RowError(f"exits rows of islands that are not stored: {sorted(exits)[:5]}")
        edges = [sch.edge_from_row(row) for row in conn.execute(sch.SELECT_EDGES)]
    finally:
        conn.execute("COMMIT")
    return islands, edges


def write_rows(conn: sqlite3.Connection, islands: Iterable[Island], edges: Iterable[Edge]) -> None:
    """Insert islands, their exits and edges (in the open transaction of `conn`)."""
    listed = list(islands)
    conn.executemany(sch.UPSERT_ISLAND, [sch.island_row(i) for i in listed])
    conn.executemany(sch.INSERT_EDGE, [sch.edge_row(e) for e in edges])
    conn.executemany(sch.INSERT_EXIT, [sch.exit_row(i.id, e) for i in listed for e in i.exits])


def write_new_database(path: Path, graph: TopoGraph, meta: dict[str, str]) -> None:
    """Write `graph` whole into a new database file at `path` (one transaction, fsynced), as
    the migration and the salvage do; the caller renames it into place."""
    if path.exists():
        path.unlink()
    conn = _connect(path, read_only=False)
    try:
        conn.execute("PRAGMA foreign_keys = ON")
        conn.execute("BEGIN IMMEDIATE")
        sch.create_schema(conn, meta)
        write_rows(conn, graph.islands(), graph.edges())
        conn.execute("COMMIT")
    finally:
        conn.close()
    with open(path, "rb") as f:
        os.fsync(f.fileno())


class GraphStore:
    """A TopoGraph persisted in `directory` (see the module docstring)."""

    def __init__(
        self,
        directory: str | os.PathLike[str],
        config: GraphStoreConfig | None = None,
        read_only: bool = False,
    ) -> None:
        """Open the store (creating it in a missing or empty directory unless `read_only`),
        check it and load the graph. A writable store holds the directory's lock."""
        self.config = config or GraphStoreConfig()
        self.directory = Path(directory).expanduser()
        self.read_only = read_only
        self.graph = TopoGraph()
        self.legacy: LegacyStore | None = None  # an old-format store read or migrated
        self.migrated = False  # this open imported an old-format store
        self._conn: sqlite3.Connection | None = None
        self._lock_fd: int | None = None
        try:
            if read_only:
                self._open_read_only()
            else:
                self._open_writable()
        except BaseException:
            self.close()
            raise

    @property
    def database(self) -> Path:
        return self.directory / sch.DATABASE

    @classmethod
    def read(cls, directory: str | os.PathLike[str]) -> TopoGraph:
        """The graph of a store directory, read without changing it (even while in use)."""
        store = cls(directory, read_only=True)
        store.close()
        return store.graph

    # --- opening -------------------------------------------------------------------------------

    def _not_a_store(self, state: DirState) -> GraphFormatError:
        d = self.directory
        if state is DirState.MISSING:
            return GraphFormatError(str(d), "no such graph store directory")
        if state is DirState.ORPHAN_WAL:
            return _damaged(self.database, "the database file is missing but its write-ahead "
                                           "log is there")
        if state is DirState.LOST_DATABASE:
            return _damaged(self.database, "the database file is missing (the store had made "
                                           "one)")
        return GraphStoreError(str(d), f"not a graph store (no {sch.DATABASE}); a store is "
                                       "only created in a missing or empty directory")

    def _open_read_only(self) -> None:
        state = classify(self.directory)
        if state is DirState.LEGACY:
            self.legacy = read_legacy_store(self.directory)
            self.graph = self.legacy.graph
        elif state is DirState.DATABASE:
            self._conn = self._open_database(read_only=True)
        else:
            raise self._not_a_store(state)

    def _open_writable(self) -> None:
        state = classify(self.directory)
        if state not in (DirState.MISSING, DirState.NEW, DirState.DATABASE, DirState.LEGACY):
            raise self._not_a_store(state)
        self.directory.mkdir(parents=True, exist_ok=True)
        self._lock()
        state = classify(self.directory)  # again, now that no other writer can change it
        if state is DirState.LEGACY:
            self._migrate()
        self._conn = self._open_database(read_only=False)
        self._mark_database_made()
        self._finish_migration()

    def _lock(self) -> None:
        self._lock_fd = os.open(self.directory / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._lock_fd)
            self._lock_fd = None
            raise GraphError(
                f"graph store {self.directory} is in use by another process") from None

    def _mark_database_made(self) -> None:
        assert self._lock_fd is not None
        if os.pread(self._lock_fd, len(DATABASE_MADE), 0) != DATABASE_MADE:
            os.pwrite(self._lock_fd, DATABASE_MADE, 0)
            os.fsync(self._lock_fd)

    def _open_database(self, read_only: bool) -> sqlite3.Connection:
        path = self.database
        conn = _connect(path, read_only)
        try:
            new = _header(conn, path)
            if new and read_only:
                raise GraphStoreError(str(path), "an empty database, not a graph store")
            if not new:  # checked before anything is written to it
                _check_integrity(conn, path, self.config.full_integrity_check)
                if not read_only:
                    sch.migrate_schema(conn, conn.execute("PRAGMA user_version").fetchone()[0])
                islands, edges = read_rows(conn)
                self.graph = TopoGraph.from_parts(islands, edges)
            if not read_only:
                self._configure(conn, new)
        except sch.RowError as exc:
            conn.close()
            raise _damaged(path, str(exc)) from exc
        except GraphError as exc:
            conn.close()
            raise _damaged(path, f"the rows are not a valid graph: {exc}") from exc
        except sqlite3.DatabaseError as exc:
            conn.close()
            raise _damaged(path, f"SQLite: {exc}") from exc
        except BaseException:
            conn.close()
            raise
        return conn

    def _configure(self, conn: sqlite3.Connection, new: bool) -> None:
        mode = conn.execute("PRAGMA journal_mode = WAL").fetchone()[0]
        if mode != "wal":
            raise GraphStoreError(str(self.database), f"cannot use WAL journaling (got {mode})")
        conn.execute(f"PRAGMA synchronous = {'FULL' if self.config.fsync else 'NORMAL'}")
        conn.execute("PRAGMA foreign_keys = ON")
        if new:
            conn.execute("BEGIN IMMEDIATE")
            sch.create_schema(conn, {})
            conn.execute("COMMIT")

    # --- migration from the old format ---------------------------------------------------------

    def _migrate(self) -> None:
        """Import snapshot.json + changes.jsonl into a new database (written whole, then
        renamed into place); the old files are moved aside by `_finish_migration`."""
        self.legacy = read_legacy_store(self.directory)
        tmp = self.directory / (sch.DATABASE + IMPORTING_SUFFIX)
        write_new_database(tmp, self.legacy.graph, {
            "migrated_from": f"{' + '.join(LEGACY_FILES)} (seq {self.legacy.seq})"})
        os.replace(tmp, self.database)
        fsync_dir(self.directory)
        self.migrated = True

    def _finish_migration(self) -> None:
        """Move the old-format files aside once their import is in place (also after a crash
        between the rename and the move); refuse a database beside files it did not import."""
        present = [n for n in LEGACY_FILES if (self.directory / n).exists()]
        leftover = self.directory / (sch.DATABASE + IMPORTING_SUFFIX)
        if leftover.exists():
            leftover.unlink()
        if not present:
            return
        assert self._conn is not None
        row = self._conn.execute("SELECT value FROM meta WHERE key = 'migrated_from'").fetchone()
        if row is None:
            raise GraphStoreError(str(self.directory), f"holds both {sch.DATABASE} and "
                                  f"old-format files {present}: move one of them away")
        aside = self.directory / LEGACY_ASIDE
        k = 1
        while aside.exists() and any((aside / n).exists() for n in present):
            aside, k = self.directory / f"{LEGACY_ASIDE}.{k}", k + 1
        aside.mkdir(exist_ok=True)
        for name in present:
            os.replace(self.directory / name, aside / name)
        fsync_dir(aside)
        fsync_dir(self.directory)

    # --- changes -------------------------------------------------------------------------------

    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        """One transaction, committed (durably) on leaving, rolled back on any error."""
        if self.read_only or self._conn is None:
            raise GraphError(f"graph store {self.directory} is open read-only")
        conn = self._conn
        conn.execute("BEGIN IMMEDIATE")
        try:
            yield conn
            conn.execute("COMMIT")
        except BaseException:
            if conn.in_transaction:
                conn.execute("ROLLBACK")
            raise

    @staticmethod
    def _write_exits(conn: sqlite3.Connection, islands: Iterable[Island]) -> None:
        for island in islands:
            conn.execute("DELETE FROM exits WHERE island = ?", (island.id,))
            conn.executemany(sch.INSERT_EXIT, [sch.exit_row(island.id, e) for e in island.exits])

    def put_island(self, island: Island) -> bool:
        """Validate, write (durably), apply. True when it replaced an existing island."""
        checked = self.graph.check_island(island, PutMode.PUT)
        with self._transaction() as conn:
            conn.execute(sch.UPSERT_ISLAND, sch.island_row(checked))
            self._write_exits(conn, [checked])
        return self.graph.put_island(checked)

    def put_edge(self, edge: Edge) -> bool:
        """Validate, write (durably), apply. True when it replaced an existing edge."""
        self.graph.check_edge(edge, PutMode.PUT)
        with self._transaction() as conn:
            conn.execute("DELETE FROM edges WHERE source = ? AND target = ?",
                         (edge.source, edge.target))
            conn.execute(sch.INSERT_EDGE, sch.edge_row(edge))
        return self.graph.put_edge(edge)

    def apply_exit_update(self, update: ExitUpdate) -> Island:
        """Set one exit's state (one transaction); returns the changed island."""
        changed = self.graph.check_exit_update(update)
        new = next(e for e in changed.exits if e.index == update.index)
        with self._transaction() as conn:
            conn.execute("DELETE FROM exits WHERE island = ? AND idx = ?",
                         (update.island, update.index))
            conn.execute(sch.INSERT_EXIT, sch.exit_row(update.island, new))
        return self.graph.apply_exit_update(update)

    def add_exit(self, item: NewExit) -> Island:
        """Add an exit to an island (one transaction); returns the changed island."""
        self.graph.check_new_exit(item)
        with self._transaction() as conn:
            conn.execute(sch.INSERT_EXIT, sch.exit_row(item.island, item.exit))
        return self.graph.add_exit(item)

    def set_exit(self, island_id: int, index: int, state: ExitState,
                 edge: tuple[int, int] | None = None) -> Island:
        """`TopoGraph.set_exit`, persisted as one transaction."""
        return self.apply_exit_update(ExitUpdate(island_id, index, state, edge))

    def remove_island(self, island_id: int) -> list[Edge]:
        """Remove an island, its edges and its exits, and reset the exits those edges explored
        on other islands (one transaction)."""
        if island_id not in self.graph:
            raise GraphError(f"cannot remove unknown island {island_id}")
        touching = [e for e in self.graph.iter_edges() if island_id in (e.source, e.target)]
        reset = self.graph.exits_reset_by(((e.source, e.target) for e in touching), island_id)
        with self._transaction() as conn:
            self._write_exits(conn, reset)
            conn.execute("DELETE FROM edges WHERE source = ? OR target = ?",
                         (island_id, island_id))
            conn.execute("DELETE FROM islands WHERE id = ?", (island_id,))
        return self.graph.remove_island(island_id)

    def remove_edge(self, source: int, target: int) -> Edge:
        """Remove an edge and reset the exits it explored (one transaction)."""
        self.graph.get_edge(source, target)
        reset = self.graph.exits_reset_by([(source, target)])
        with self._transaction() as conn:
            self._write_exits(conn, reset)
            conn.execute("DELETE FROM edges WHERE source = ? AND target = ?", (source, target))
        return self.graph.remove_edge(source, target)

    # --- closing -------------------------------------------------------------------------------

    def close(self) -> None:
        """Close the database (a writable one checkpoints its log) and release the lock."""
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # releases the flock
            self._lock_fd = None

    def __del__(self) -> None:
        if getattr(self, "_lock_fd", None) is not None or getattr(self, "_conn", None) is not None:
            self.close()

    def __enter__(self) -> GraphStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
