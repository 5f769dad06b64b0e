"""The graph store before SQLite (a JSONL write-ahead log + snapshots), kept verbatim from
island_mapping/core/graph.py as of commit 13850e0 so bench/bench_route_planning.py can measure
the SQLite store beside it in one run. Not used by the project.
"""

from __future__ import annotations

import fcntl
import json
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from island_mapping.core.graph import GraphError, TopoGraph
from island_msgs_py.json_io import GraphFormatError, read_json_file
from island_msgs_py.types import Edge, Island

from island_msgs_py import json_io


@dataclass(frozen=True)
class JsonlStoreConfig:
    """How the graph server persists accepted changes."""

    compact_every: int = field(
        default=200,
        metadata={"help": "rewrite the snapshot and empty the change log after this many "
                          "logged changes [changes]"},
    )
    fsync: bool = field(
        default=True,
        metadata={"help": "fsync the change log before acknowledging a change (needed to "
                          "survive power loss; a SIGKILL is survived either way) [bool]"},
    )

    def __post_init__(self) -> None:
        if self.compact_every < 1:
            raise ValueError(f"compact_every must be >= 1, got {self.compact_every}")


SNAPSHOT_FORMAT = "islands-graph-snapshot"
LOG_FORMAT = "islands-graph-changes"


class JsonlGraphStore:
    """A TopoGraph persisted in `directory`: `snapshot.json` + `changes.jsonl` (write-ahead log).

    Every accepted change is validated, appended as one JSON line `{"seq": n, "op": ..., ...}`,
    flushed and fsynced, and only then applied and acknowledged; so a process killed at any
    moment loses no acknowledged change. Every `compact_every` changes the whole graph is
    written atomically to `snapshot.json` (with the last seq it contains) and the log is
    replaced by an empty one. On load, the snapshot is read and log lines with a larger seq
    are replayed; a torn last line (a crash mid-append, never acknowledged) is cut off.
    """

    SNAPSHOT = "snapshot.json"
    LOG = "changes.jsonl"

    LOCK = ".lock"

    def __init__(
        self,
        directory: str | os.PathLike[str],
        config: JsonlStoreConfig | None = None,
        read_only: bool = False,
    ) -> None:
        """Open (creating it when missing) and load the store. A writable store holds an
        exclusive lock on `directory/.lock` (released by the OS even on SIGKILL), so two
        writers never interleave; `read_only=True` only reads and changes nothing on disk."""
        self.config = config or JsonlStoreConfig()
        self.directory = Path(directory).expanduser()
        self.read_only = read_only
        self.graph = TopoGraph()
        self._seq = 0
        self._logged = 0  # lines in the current log
        self.dropped_torn_tail = False
        self._lock_fd: int | None = None
        self._log: IO[bytes] | None = None
        if read_only:
            if not self.directory.is_dir():
                raise GraphFormatError(str(self.directory), "no such graph store directory")
            self._load()
            return
        self.directory.mkdir(parents=True, exist_ok=True)
        self._lock_fd = os.open(self.directory / self.LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(self._lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self._lock_fd)
            self._lock_fd = None
            raise GraphError(
                f"graph store {self.directory} is in use by another process"
            ) from None
        try:
            self._load()
            self._log = open(self.directory / self.LOG, "ab", buffering=0)
        except BaseException:
            self.close()
            raise

    @classmethod
    def read(cls, directory: str | os.PathLike[str]) -> TopoGraph:
        """The graph of a store directory, read without changing anything (even while in use)."""
        return cls(directory, read_only=True).graph

    # --- loading -------------------------------------------------------------------------------

    def _load(self) -> None:
        snap = self.directory / self.SNAPSHOT
        if snap.exists():
            doc = read_json_file(snap)
            if not isinstance(doc, Mapping) or doc.get("format") != SNAPSHOT_FORMAT:
                raise GraphFormatError(f"{snap}: format", f"expected {SNAPSHOT_FORMAT!r}")
            if doc.get("version") != 1:
                raise GraphFormatError(f"{snap}: version", f"unsupported {doc.get('version')!r}")
            try:
                self.graph = TopoGraph.from_dict(doc.get("graph"))
            except GraphFormatError as exc:
                raise GraphFormatError(f"{snap}: graph.{exc.path}", exc.problem) from exc
            self._seq = int(doc.get("seq", 0))
        log = self.directory / self.LOG
        if not log.exists():
            return
        data = log.read_bytes()
        good_end = 0
        pos = 0
        lineno = 0
        while pos < len(data):
            nl = data.find(b"\n", pos)
            line = data[pos: nl if nl >= 0 else len(data)]
            lineno += 1
            try:
                rec = json.loads(line) if nl >= 0 else None
            except (json.JSONDecodeError, UnicodeDecodeError):
                rec = None
            if rec is None:
                rest = data[(nl + 1) if nl >= 0 else len(data):]
                if rest.strip():
                    raise GraphFormatError(f"{log}:{lineno}", "corrupt change record")
                self.dropped_torn_tail = True  # a crash mid-append: never acknowledged
                break
            self._replay(rec, f"{log}:{lineno}")
            self._logged += 1
            pos = nl + 1
            good_end = pos
        if good_end < len(data) and not self.read_only:
            with open(log, "r+b") as f:
                f.truncate(good_end)
                f.flush()
                os.fsync(f.fileno())

    def _replay(self, rec: Any, where: str) -> None:
        if not isinstance(rec, Mapping) or not isinstance(rec.get("seq"), int):
            raise GraphFormatError(where, "change record without an integer seq")
        seq = int(rec["seq"])
        if seq <= self._seq:
            return  # already in the snapshot (a crash between snapshot and log reset)
        op = rec.get("op")
        try:
            if op == "put_island":
                island = json_io.island_from_dict(rec.get("island"), f"{where}.island")
                self.graph.put_island(island)
            elif op == "put_edge":
                self.graph.put_edge(json_io.edge_from_dict(rec.get("edge"), f"{where}.edge"))
            elif op == "remove_island":
                self.graph.remove_island(int(rec["id"]))
            elif op == "remove_edge":
                self.graph.remove_edge(int(rec["source"]), int(rec["target"]))
            else:
                raise GraphFormatError(f"{where}.op", f"unknown operation {op!r}")
        except GraphError as exc:
            raise GraphFormatError(where, f"cannot replay: {exc}") from exc
        except (KeyError, TypeError, ValueError) as exc:
            if isinstance(exc, GraphFormatError):
                raise
            raise GraphFormatError(where, f"malformed {op} record: {exc!r}") from exc
        self._seq = seq

    # --- changes -------------------------------------------------------------------------------

    def _append(self, record: dict[str, Any]) -> None:
        if self._log is None:
            raise GraphError(f"graph store {self.directory} is open read-only")
        record = {"seq": self._seq + 1, **record}
        line = (json_io.dumps(record) + "\n").encode("utf-8")
        fd = self._log.fileno()
        size = os.fstat(fd).st_size
        try:
            view = memoryview(line)
            while view:
                view = view[os.write(fd, view):]
            if self.config.fsync:
                os.fsync(fd)
        except BaseException:
            # e.g. disk full: cut a partial line so later appends do not follow garbage
            try:
                os.ftruncate(fd, size)
            except OSError:
                pass
            raise
        self._seq += 1
        self._logged += 1

    def _after(self) -> None:
        if self._logged >= self.config.compact_every:
            self.compact()

    def put_island(self, island: Island) -> bool:
        """Validate, log (durably), apply. True when it replaced an existing island."""
        checked = self.graph.check_island(island, "put")
        self._append({"op": "put_island", "island": json_io.island_to_dict(checked)})
        replaced = self.graph.put_island(checked)
        self._after()
        return replaced

    def put_edge(self, edge: Edge) -> bool:
        self.graph.check_edge(edge, "put")
        self._append({"op": "put_edge", "edge": json_io.edge_to_dict(edge)})
        replaced = self.graph.put_edge(edge)
        self._after()
        return replaced

    def remove_island(self, island_id: int) -> list[Edge]:
        self.graph.get_island(island_id)
        self._append({"op": "remove_island", "id": int(island_id)})
        removed = self.graph.remove_island(island_id)
        self._after()
        return removed

    def remove_edge(self, source: int, target: int) -> Edge:
        self.graph.get_edge(source, target)
        self._append({"op": "remove_edge", "source": int(source), "target": int(target)})
        edge = self.graph.remove_edge(source, target)
        self._after()
        return edge

    def compact(self) -> None:
        """Write the snapshot atomically, then start an empty log."""
        doc = {
            "format": SNAPSHOT_FORMAT, "version": 1, "seq": self._seq,
            "graph": self.graph.to_dict(),
        }
        if self._log is None:
            raise GraphError(f"graph store {self.directory} is open read-only")
        json_io.atomic_write_text(self.directory / self.SNAPSHOT, json_io.dumps(doc) + "\n")
        self._log.close()
        json_io.atomic_write_text(self.directory / self.LOG, "")
        self._log = open(self.directory / self.LOG, "ab", buffering=0)
        self._logged = 0

    def close(self) -> None:
        if self._log is not None and not self._log.closed:
            self._log.close()
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # releases the flock
            self._lock_fd = None

    def __del__(self) -> None:
        if getattr(self, "_lock_fd", None) is not None or getattr(self, "_log", None) is not None:
            self.close()

    def __enter__(self) -> JsonlGraphStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
