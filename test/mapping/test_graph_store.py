"""GraphStore: every accepted change is on disk before it is acknowledged; reload rebuilds it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from island_mapping.core.graph import GraphError, GraphStore, GraphStoreConfig, TopoGraph
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType


def island(i: int, r: float = 0.5) -> Island:
    rng = np.random.default_rng(i)
    return Island(i, LineModel(rng.uniform(-3, 3, (4, 4))), ModelType.LINE, r, float(i))


def edge(a: int, b: int, w: float = 1.0) -> Edge:
    return Edge(a, b, ControlStrategy.parse("Go 125, Rot 270, Go 652"), w, length_m=w)


def _fill(store: GraphStore, n: int) -> None:
    for i in range(n):
        store.put_island(island(i))
        if i:
            store.put_edge(edge(i - 1, i, float(i)))


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


def test_compaction_keeps_everything_and_resets_the_log(tmp_path: Path) -> None:
    cfg = GraphStoreConfig(compact_every=10)
    with GraphStore(tmp_path, cfg) as store:
        _fill(store, 30)  # 59 changes: 5 compactions
        want = store.graph.to_json()
    lines = (tmp_path / GraphStore.LOG).read_text().splitlines()
    assert len(lines) == 59 % 10
    snap = json.loads((tmp_path / GraphStore.SNAPSHOT).read_text())
    assert snap["seq"] == 50 and len(snap["graph"]["islands"]) == 26
    with GraphStore(tmp_path, cfg) as again:
        assert again.graph.to_json() == want


def test_crash_between_snapshot_and_log_reset_replays_nothing_twice(tmp_path: Path) -> None:
    with GraphStore(tmp_path, GraphStoreConfig(compact_every=1000)) as store:
        _fill(store, 5)
        store.remove_island(4)
        store.put_island(island(4, r=0.25))  # re-added after removal: a replay would break it
        log_before = (tmp_path / GraphStore.LOG).read_bytes()
        store.compact()
        want = store.graph.to_json()
    (tmp_path / GraphStore.LOG).write_bytes(log_before)  # the log reset never happened
    with GraphStore(tmp_path) as again:
        assert again.graph.to_json() == want


def test_torn_last_line_is_cut_and_appends_continue(tmp_path: Path) -> None:
    with GraphStore(tmp_path) as store:
        _fill(store, 3)
        want = store.graph.to_json()
    with open(tmp_path / GraphStore.LOG, "ab") as f:
        f.write(b'{"seq": 6, "op": "put_island", "island": {"id": 9, "mod')  # killed mid-write
    with GraphStore(tmp_path) as again:
        assert again.dropped_torn_tail
        assert again.graph.to_json() == want
        again.put_island(island(7))
    with GraphStore(tmp_path) as third:
        assert third.graph.island_ids() == [0, 1, 2, 7]


def test_corrupt_middle_line_is_an_error_naming_the_line(tmp_path: Path) -> None:
    with GraphStore(tmp_path) as store:
        _fill(store, 3)
    lines = (tmp_path / GraphStore.LOG).read_text().splitlines()
    lines[1] = "garbage"
    (tmp_path / GraphStore.LOG).write_text("\n".join(lines) + "\n")
    with pytest.raises(GraphFormatError, match=r"changes\.jsonl:2: corrupt change record"):
        GraphStore(tmp_path)


def test_rejected_changes_are_not_logged(tmp_path: Path) -> None:
    with GraphStore(tmp_path) as store:
        _fill(store, 2)
        size = (tmp_path / GraphStore.LOG).stat().st_size
        with pytest.raises(GraphError, match="unknown target island 5"):
            store.put_edge(edge(0, 5))
        with pytest.raises(GraphError, match="unknown island 8"):
            store.remove_island(8)
        assert (tmp_path / GraphStore.LOG).stat().st_size == size


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
    with open(tmp_path / GraphStore.LOG, "ab") as f:
        f.write(b'{"seq": 9, "op"')
    size = (tmp_path / GraphStore.LOG).stat().st_size
    ro = GraphStore(tmp_path, read_only=True)
    assert ro.dropped_torn_tail and ro.graph.island_ids() == [0, 1, 2]
    assert (tmp_path / GraphStore.LOG).stat().st_size == size  # torn tail left alone
    with pytest.raises(GraphError, match="read-only"):
        ro.put_island(island(5))
    assert ro.graph.island_ids() == [0, 1, 2]
    with pytest.raises(GraphFormatError, match="no such graph store"):
        GraphStore.read(tmp_path / "missing")


def test_malformed_records_are_errors_naming_the_line(tmp_path: Path) -> None:
    with GraphStore(tmp_path) as store:
        _fill(store, 2)
    log = tmp_path / GraphStore.LOG
    good = log.read_text()
    for bad, message in [
        ('{"seq": 9, "op": "remove_island"}', r"changes\.jsonl:4: malformed remove_island"),
        ('{"seq": 9, "op": "fly"}', r"changes\.jsonl:4\.op: unknown operation 'fly'"),
        ('{"op": "put_edge"}', r"changes\.jsonl:4: change record without an integer seq"),
        ('{"seq": 9, "op": "remove_edge", "source": 0, "target": 7}', "cannot replay: no edge"),
    ]:
        log.write_text(good + bad + "\n")
        with pytest.raises(GraphFormatError, match=message):
            GraphStore(tmp_path)


def test_a_failed_append_is_not_applied_and_leaves_no_partial_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import os

    store = GraphStore(tmp_path)
    _fill(store, 2)
    size = (tmp_path / GraphStore.LOG).stat().st_size

    def disk_full(fd: int) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", disk_full)
    with pytest.raises(OSError, match="No space left"):
        store.put_island(island(5))
    monkeypatch.undo()
    assert 5 not in store.graph
    assert (tmp_path / GraphStore.LOG).stat().st_size == size
    store.put_island(island(6))
    store.close()
    assert GraphStore.read(tmp_path).island_ids() == [0, 1, 6]
