"""The graph store's SQLite schema and how islands, exits and edges become rows and back.

Every row carries `crc`, a CRC-32 of its other values (as Python writes them: `repr` of the
tuple), so a value changed on disk outside the store (a flipped digit that SQLite's own
checks cannot see, since the page is still well-formed) is found on open, not read as valid.
The invariants of the map are foreign keys too (deferred to the commit): an edge joins stored
islands, an edge's source/target exit is a stored exit of that island, an explored exit's edge
is a stored edge.
"""

from __future__ import annotations

import sqlite3
import zlib
from collections.abc import Sequence
from typing import Any

import numpy as np
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
    Pose2D,
)

DATABASE = "graph.sqlite3"  # the store's file in its directory (plus -wal/-shm while in use)
STORE_FORMAT = "islands-graph-store"
APPLICATION_ID = 0x49534C47  # "ISLG" in the SQLite header: this file is an islands graph store
SCHEMA_VERSION = 2  # PRAGMA user_version of the schema below (1: exits without prefix/side)
SEGMENT_DTYPE = "<f8"  # segments BLOB: N x 4 little-endian float64, row-major [m]
SEGMENT_ROW_BYTES = 4 * 8

SCHEMA = """
CREATE TABLE meta (
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
) STRICT;
CREATE TABLE islands (
    id INTEGER PRIMARY KEY CHECK (id BETWEEN 0 AND 2147483647),
    frame_id TEXT NOT NULL UNIQUE,
    model_type TEXT NOT NULL,
    r REAL NOT NULL,
    built_at_s REAL NOT NULL,
    segments BLOB NOT NULL,
    origin_x REAL,
    origin_y REAL,
    origin_theta REAL,
    crc INTEGER NOT NULL
) STRICT;
CREATE TABLE edges (
    source INTEGER NOT NULL REFERENCES islands (id) DEFERRABLE INITIALLY DEFERRED,
    target INTEGER NOT NULL REFERENCES islands (id) DEFERRABLE INITIALLY DEFERRED,
    strategy TEXT NOT NULL,
    weight REAL NOT NULL CHECK (weight >= 0),
    length_m REAL NOT NULL,
    expected_error_m REAL NOT NULL,
    source_exit INTEGER,
    target_exit INTEGER,
    crc INTEGER NOT NULL,
    PRIMARY KEY (source, target),
    FOREIGN KEY (source, source_exit) REFERENCES exits (island, idx)
        DEFERRABLE INITIALLY DEFERRED,
    FOREIGN KEY (target, target_exit) REFERENCES exits (island, idx)
        DEFERRABLE INITIALLY DEFERRED
) STRICT;
CREATE TABLE exits (
    island INTEGER NOT NULL REFERENCES islands (id) ON DELETE CASCADE
        DEFERRABLE INITIALLY DEFERRED,
    idx INTEGER NOT NULL CHECK (idx >= 0),
    heading_rad REAL NOT NULL,
    width_m REAL NOT NULL CHECK (width_m > 0),
    state TEXT NOT NULL,
    edge_source INTEGER,
    edge_target INTEGER,
    crc INTEGER NOT NULL,
    prefix TEXT,
    side TEXT,
    PRIMARY KEY (island, idx),
    FOREIGN KEY (edge_source, edge_target) REFERENCES edges (source, target)
        DEFERRABLE INITIALLY DEFERRED
) STRICT;
"""

ISLAND_COLUMNS = ("id", "frame_id", "model_type", "r", "built_at_s", "segments", "origin_x",
                  "origin_y", "origin_theta", "crc")
EDGE_COLUMNS = ("source", "target", "strategy", "weight", "length_m", "expected_error_m",
                "source_exit", "target_exit", "crc")
EXIT_COLUMNS = ("island", "idx", "heading_rad", "width_m", "state", "edge_source",
                "edge_target", "prefix", "side", "crc")
EXIT_COLUMNS_V1 = tuple("NULL" if c in ("prefix", "side") else c for c in EXIT_COLUMNS)
"""A schema-1 store's exits read as plain exits (no prefix, no side)."""
MIGRATE_1_TO_2 = ("ALTER TABLE exits ADD COLUMN prefix TEXT",
                  "ALTER TABLE exits ADD COLUMN side TEXT")
"""A schema-1 store made a schema-2 one: its rows stay valid (a plain exit's checksum covers
the first seven values, as in schema 1)."""


class RowError(ValueError):
    """A stored row is not a valid value (bad checksum, malformed field)."""


def _sql(table: str, columns: Sequence[str]) -> str:
    marks = ", ".join("?" for _ in columns)
    return f"INSERT INTO {table} ({', '.join(columns)}) VALUES ({marks})"


INSERT_EDGE = _sql("edges", EDGE_COLUMNS)
INSERT_EXIT = _sql("exits", EXIT_COLUMNS)
UPSERT_ISLAND = _sql("islands", ISLAND_COLUMNS) + " ON CONFLICT (id) DO UPDATE SET " + ", ".join(
    f"{c} = excluded.{c}" for c in ISLAND_COLUMNS[1:])
SELECT_ISLANDS = f"SELECT {', '.join(ISLAND_COLUMNS)} FROM islands ORDER BY id"
SELECT_EDGES = f"SELECT {', '.join(EDGE_COLUMNS)} FROM edges ORDER BY source, target"
SELECT_EXITS = f"SELECT {', '.join(EXIT_COLUMNS)} FROM exits ORDER BY island, idx"


def row_crc(values: Sequence[Any]) -> int:
    """CRC-32 of a row's values (everything but the crc column)."""
    return zlib.crc32(repr(tuple(values)).encode("utf-8"))


def _with_crc(values: tuple[Any, ...]) -> tuple[Any, ...]:
    return (*values, row_crc(values))


def _checked(row: Sequence[Any], what: str) -> tuple[Any, ...]:
    values = tuple(row[:-1])
    if row_crc(values) != row[-1]:
        raise RowError(f"{what}: checksum mismatch (the row was changed outside the store)")
    return values


# ----------------------------------------------------------------------------- to rows


def island_row(island: Island) -> tuple[Any, ...]:
    segs = np.ascontiguousarray(island.model.segments, dtype=SEGMENT_DTYPE)
    o = island.origin_truth
    return _with_crc((
        island.id, island.frame_id, island.model_type.value, float(island.r),
        float(island.built_at_s), segs.tobytes(),
        None if o is None else float(o.x), None if o is None else float(o.y),
        None if o is None else float(o.theta),
    ))


def exit_row(island_id: int, e: Exit) -> tuple[Any, ...]:
    """An exits row; a plain exit's checksum covers its first seven values (as in schema 1),
    a side exit's also its prefix and side."""
    src, dst = (None, None) if e.edge is None else e.edge
    values = (island_id, e.index, float(e.heading_rad), float(e.width_m), e.state.value, src,
              dst)
    if e.prefix is None or e.side is None:
        return (*values, None, None, row_crc(values))
    side = (str(e.prefix), e.side.value)
    return (*values, *side, row_crc(values + side))


def edge_row(edge: Edge) -> tuple[Any, ...]:
    return _with_crc((edge.source, edge.target, str(edge.strategy), float(edge.weight),
                      float(edge.length_m), float(edge.expected_error_m), edge.source_exit,
                      edge.target_exit))


# ----------------------------------------------------------------------------- from rows


def exit_from_row(row: Sequence[Any]) -> tuple[int, Exit]:
    """(island id, exit) of an exits row; RowError naming the row when it is not valid."""
    what = f"exits row (island {row[0]!r}, index {row[1]!r})"
    plain = row[7] is None and row[8] is None
    values = _checked((*row[:7], row[9]) if plain else row, what)
    island, idx, heading, width, state, src, dst = values[:7]
    try:
        edge = None if src is None and dst is None else (src, dst)
        prefix = None if plain else ControlStrategy.parse(row[7])
        side = None if plain else ExitSide(row[8])
        return int(island), Exit(idx, heading, width, ExitState(state), edge, prefix, side)
    except (IslandTypeError, ValueError, TypeError, AttributeError) as exc:
        raise RowError(f"{what}: {exc}") from exc


def island_from_row(row: Sequence[Any], exits: Sequence[Exit]) -> Island:
    """An island of an islands row and its exits; RowError naming the row when not valid."""
    what = f"islands row (id {row[0]!r})"
    iid, frame, model_type, r, built, blob, ox, oy, ot = _checked(row, what)
    if not isinstance(blob, bytes) or len(blob) % SEGMENT_ROW_BYTES:
        raise RowError(f"{what}: segments are not N x 4 float64")
    try:
        origin = None if ox is None and oy is None and ot is None else Pose2D(ox, oy, ot)
        segments = np.frombuffer(blob, dtype=SEGMENT_DTYPE).reshape(-1, 4).astype(np.float64)
        return Island(iid, LineModel(segments), ModelType(model_type), r, built, frame, origin,
                      tuple(exits))
    except (IslandTypeError, ValueError, TypeError) as exc:
        raise RowError(f"{what}: {exc}") from exc


def edge_from_row(row: Sequence[Any]) -> Edge:
    what = f"edges row ({row[0]!r}->{row[1]!r})"
    src, dst, strategy, weight, length, error, sx, tx = _checked(row, what)
    try:
        return Edge(src, dst, ControlStrategy.parse(strategy), weight, length, error, sx, tx)
    except (IslandTypeError, ValueError, TypeError, AttributeError) as exc:
        raise RowError(f"{what}: {exc}") from exc


def exits_select(conn: sqlite3.Connection) -> tuple[str, ...]:
    """The exits columns to select: a schema-1 table has no prefix and side (NULLs)."""
    have = {r[1] for r in conn.execute("PRAGMA table_info(exits)")}
    return EXIT_COLUMNS if "prefix" in have else EXIT_COLUMNS_V1


def migrate_schema(conn: sqlite3.Connection, version: int) -> None:
    """A writable store of an older schema brought to SCHEMA_VERSION (one transaction)."""
    if version >= SCHEMA_VERSION:
        return
    conn.execute("BEGIN IMMEDIATE")
    for statement in MIGRATE_1_TO_2:
        conn.execute(statement)
    conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
    conn.execute("COMMIT")


def create_schema(conn: sqlite3.Connection, meta: dict[str, str]) -> None:
    """The tables, the header's application id and schema version, and `meta`, in the open
    transaction of `conn`."""
    for statement in SCHEMA.split(";"):
        if statement.strip():
            conn.execute(statement)
    conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
    conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
    conn.executemany("INSERT INTO meta (key, value) VALUES (?, ?)",
                     [("format", STORE_FORMAT), *meta.items()])
