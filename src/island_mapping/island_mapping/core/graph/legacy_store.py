"""Reading a graph store of the format before SQLite, to migrate it (nothing here writes).

That format: a directory holding `snapshot.json` (`{"format": "islands-graph-snapshot",
"version": 1, "seq": S, "graph": {...}}`) and `changes.jsonl`, a write-ahead log with one JSON
line per accepted change (`{"seq": n, "op": "put_island" | "put_edge" | "remove_island" |
"remove_edge", ...}`); lines with a seq at or below the snapshot's are already in it. A torn
last line (a crash mid-append) was never acknowledged and is dropped; anything else that is not
a valid change is an error naming `changes.jsonl:<line>`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from island_msgs_py.json_io import GraphFormatError, read_json_file

from island_mapping.core.graph.errors import GraphError
from island_mapping.core.graph.model import TopoGraph
from island_msgs_py import json_checks, json_io

LEGACY_SNAPSHOT = "snapshot.json"
LEGACY_LOG = "changes.jsonl"
LEGACY_FILES = (LEGACY_SNAPSHOT, LEGACY_LOG)
SNAPSHOT_FORMAT = "islands-graph-snapshot"


@dataclass
class LegacyStore:
    """What an old-format store held: the graph, the last change's seq, and whether a torn
    (never acknowledged) last log line was dropped."""

    graph: TopoGraph
    seq: int
    dropped_torn_tail: bool


def is_legacy_store(directory: Path) -> bool:
    return any((directory / name).exists() for name in LEGACY_FILES)


def _snapshot(path: Path) -> tuple[TopoGraph, int]:
    doc = read_json_file(path)
    if not isinstance(doc, Mapping) or doc.get("format") != SNAPSHOT_FORMAT:
        raise GraphFormatError(f"{path}: format", f"expected {SNAPSHOT_FORMAT!r}")
    if doc.get("version") != 1:
        raise GraphFormatError(f"{path}: version", f"unsupported {doc.get('version')!r}")
    seq = doc.get("seq", 0)
    if isinstance(seq, bool) or not isinstance(seq, int) or seq < 0:
        raise GraphFormatError(f"{path}: seq", f"expected an integer >= 0, got {seq!r}")
    try:
        return TopoGraph.from_dict(doc.get("graph")), seq
    except GraphFormatError as exc:
        raise GraphFormatError(f"{path}: graph.{exc.path}", exc.problem) from exc
    except GraphError as exc:
        raise GraphFormatError(f"{path}: graph", str(exc)) from exc


def _replay(graph: TopoGraph, rec: Any, where: str) -> int:
    """Apply one log record; returns its seq."""
    if not isinstance(rec, Mapping) or isinstance(rec.get("seq"), bool) or \
            not isinstance(rec.get("seq"), int):
        raise GraphFormatError(where, "change record without an integer seq")
    op = rec.get("op")
    try:
        if op == "put_island":
            graph.put_island(json_io.island_from_dict(rec.get("island"), f"{where}.island"))
        elif op == "put_edge":
            graph.put_edge(json_io.edge_from_dict(rec.get("edge"), f"{where}.edge"))
        elif op == "remove_island":
            graph.remove_island(json_checks.island_id(rec.get("id"), f"{where}.id"))
        elif op == "remove_edge":
            graph.remove_edge(json_checks.island_id(rec.get("source"), f"{where}.source"),
                              json_checks.island_id(rec.get("target"), f"{where}.target"))
        else:
            raise GraphFormatError(f"{where}.op", f"unknown operation {str(op)[:40]!r}")
    except GraphError as exc:
        raise GraphFormatError(where, f"cannot replay: {exc}") from exc
    return int(rec["seq"])


def read_legacy_store(directory: Path) -> LegacyStore:
    """The graph of an old-format store directory (GraphFormatError naming the file/line)."""
    graph, seq = TopoGraph(), 0
    snap = directory / LEGACY_SNAPSHOT
    if snap.exists():
        graph, seq = _snapshot(snap)
    log = directory / LEGACY_LOG
    data = log.read_bytes() if log.exists() else b""
    lines = data.split(b"\n")
    for lineno, line in enumerate(lines, start=1):
        complete = lineno < len(lines)  # the part after the last newline was never finished
        try:
            rec = json_io.loads(line, f"{log}:{lineno}") if complete else None
        except GraphFormatError:
            rec = None
        if rec is None:
            if any(rest.strip() for rest in lines[lineno:]):
                raise GraphFormatError(f"{log}:{lineno}", "corrupt change record")
            return LegacyStore(graph, seq, bool(line.strip()))  # a torn append, never acked
        if isinstance(rec, Mapping) and isinstance(rec.get("seq"), int) and rec["seq"] <= seq:
            continue  # already in the snapshot (a crash between snapshot and log reset)
        seq = _replay(graph, rec, f"{log}:{lineno}")
    return LegacyStore(graph, seq, False)

