"""Recovery of a damaged graph store: copy every intact row into a new store, list what is lost.

`salvage_store(damaged_dir, new_dir)` never changes the damaged store. It reads each table row
by row (a scan that hits an unreadable page stops there and says so), keeps the rows whose
checksum and values are valid, and makes them a consistent map before writing it: edges whose
islands are gone are dropped, exits explored by a dropped edge go back to unexplored, an edge's
source/target exit that is gone becomes unknown. Everything dropped or changed is listed.
"""

from __future__ import annotations

import dataclasses
import os
import sqlite3
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from island_msgs_py.json_io import fsync_dir
from island_msgs_py.types import Edge, Exit, ExitState, Island

from island_mapping.core.graph import store_schema as sch
from island_mapping.core.graph.errors import GraphError
from island_mapping.core.graph.model import TopoGraph
from island_mapping.core.graph.store import (
    IMPORTING_SUFFIX,
    DirState,
    GraphStoreError,
    classify,
    write_new_database,
)

T = TypeVar("T")


@dataclass
class SalvageReport:
    """What a salvage kept, and each row it dropped or changed, with why."""

    islands: int = 0
    edges: int = 0
    exits: int = 0
    lost: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _scan(conn: sqlite3.Connection, table: str, columns: tuple[str, ...],
          report: SalvageReport) -> Iterator[tuple[Any, ...]]:
    """The rows of `table` in storage order, until the first unreadable page (reported)."""
    n = 0
    try:
        for row in conn.execute(f"SELECT {', '.join(columns)} FROM {table}"):
            n += 1
            yield tuple(row)
    except sqlite3.DatabaseError as exc:
        report.lost.append(f"table {table}: reading stopped after {n} rows: {exc}")


def _keep(rows: Iterator[tuple[Any, ...]], decode: Callable[[tuple[Any, ...]], T],
          report: SalvageReport) -> list[T]:
    out = []
    for row in rows:
        try:
            out.append(decode(row))
        except sch.RowError as exc:
            report.lost.append(str(exc))
    return out


def _consistent(islands: list[Island], edges: list[Edge],
                report: SalvageReport) -> tuple[list[Island], list[Edge]]:
    ids = {i.id for i in islands}
    kept = []
    for e in edges:
        if e.source in ids and e.target in ids:
            kept.append(e)
        else:
            report.lost.append(f"edge {e.source}->{e.target}: an island of it is lost")
    pairs = {(e.source, e.target) for e in kept}
    fixed_islands = []
    for i in islands:
        exits = []
        for x in i.exits:
            if x.edge is not None and x.edge not in pairs:
                report.lost.append(f"island {i.id} exit {x.index}: its edge {x.edge} is lost, "
                                   "set back to unexplored")
                x = dataclasses.replace(x, state=ExitState.UNEXPLORED, edge=None)
            exits.append(x)
        fixed_islands.append(dataclasses.replace(i, exits=tuple(exits)))
    exits_of = {i.id: {x.index for x in i.exits} for i in fixed_islands}
    fixed_edges = []
    for e in kept:
        for end, island_id in (("source_exit", e.source), ("target_exit", e.target)):
            index = getattr(e, end)
            if index is not None and index not in exits_of[island_id]:
                report.lost.append(f"edge {e.source}->{e.target}: {end} {index} is lost")
                e = (dataclasses.replace(e, source_exit=None) if end == "source_exit"
                     else dataclasses.replace(e, target_exit=None))
        fixed_edges.append(e)
    return fixed_islands, fixed_edges


def _read(conn: sqlite3.Connection, src: Path, report: SalvageReport) -> TopoGraph:
    exits: dict[int, list[Exit]] = {}
    for island_id, x in _keep(_scan(conn, "exits", sch.exits_select(conn), report),
                              sch.exit_from_row, report):
        exits.setdefault(island_id, []).append(x)
    islands_rows = list(_scan(conn, "islands", sch.ISLAND_COLUMNS, report))
    islands = _keep(iter(islands_rows), lambda r: sch.island_from_row(r, exits.get(r[0], [])),
                    report)
    edges = _keep(_scan(conn, "edges", sch.EDGE_COLUMNS, report), sch.edge_from_row, report)
    islands, edges = _consistent(islands, edges, report)
    try:
        return TopoGraph.from_parts(islands, edges)
    except GraphError as exc:
        raise GraphStoreError(str(src), f"salvage: the intact rows do not form a map: {exc}") \
            from exc


def salvage_store(damaged: str | os.PathLike[str], out: str | os.PathLike[str]) -> SalvageReport:
    """Copy what is intact of the store in `damaged` into a new store in `out` (a missing or
    empty directory); the damaged store is only read."""
    src = Path(damaged).expanduser() / sch.DATABASE
    dst = Path(out).expanduser()
    if not src.is_file():
        raise GraphStoreError(str(src), "no database to salvage")
    if classify(dst) not in (DirState.MISSING, DirState.NEW):
        raise GraphStoreError(str(dst), "salvage writes a new store: give a missing or empty "
                                        "directory")
    report = SalvageReport()
    try:
        conn = sqlite3.connect(f"{src.absolute().as_uri()}?mode=ro", uri=True,
                               isolation_level=None)
    except sqlite3.DatabaseError as exc:
        raise GraphStoreError(str(src), f"cannot open at all: {exc}") from exc
    try:
        graph = _read(conn, src, report)
    finally:
        conn.close()
    dst.mkdir(parents=True, exist_ok=True)
    tmp = dst / (sch.DATABASE + IMPORTING_SUFFIX)
    write_new_database(tmp, graph, {"salvaged_from": str(src)})
    os.replace(tmp, dst / sch.DATABASE)
    fsync_dir(dst)
    report.islands, report.edges = len(graph), graph.num_edges
    report.exits = sum(len(i.exits) for i in graph.islands())
    return report
