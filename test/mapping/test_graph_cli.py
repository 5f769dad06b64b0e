"""`islands graph`: info, convert, plan, strategies, and clear errors (exit 2) on bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from island_mapping.cli import main
from island_mapping.core.graph import GraphStore, TopoGraph
from island_msgs_py.types import ControlStrategy, Edge, Island, LineModel, ModelType


def _graph() -> TopoGraph:
    rng = np.random.default_rng(0)
    g = TopoGraph()
    for i in range(4):
        mt = ModelType.FISHER if i == 3 else ModelType.LINE
        g.add_island(Island(i, LineModel(rng.uniform(-2, 2, (2, 4))), mt, 0.5, float(i)))
    g.add_edge(Edge(0, 1, ControlStrategy.parse("Go 125, Rot 270, Go 652"), 8.0))
    g.add_edge(Edge(1, 2, ControlStrategy.parse("Rot 270, Go 28, Rot 90, Go 832"), 9.0))
    return g


def test_info_convert_plan_strategies(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    g = _graph()
    src = g.save_json(tmp_path / "graph.json")
    assert main(["graph", "info", str(src)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["islands"] == 4 and info["edges"] == 2
    assert info["weakly_connected_components"] == 2
    assert info["model_types"] == {"fisher": 1, "line": 3}
    assert info["exits"] == {"unexplored": 0, "explored": 0, "blocked": 0}
    for ext in ("geojson", "graphml"):
        assert main(["graph", "convert", str(src), str(tmp_path / f"g.{ext}")]) == 0
        assert TopoGraph.load_any(tmp_path / f"g.{ext}") == g
    capsys.readouterr()
    assert main(["graph", "plan", str(tmp_path / "g.geojson"), "--from", "0", "--to", "2"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["islands"] == [0, 1, 2] and out["cost"] == 17.0
    assert out["edges"][1]["strategy"] == "Rot 270, Go 28, Rot 90, Go 832"
    assert main(["graph", "plan", str(src), "--from", "2", "--to", "0"]) == 1
    assert "no route" in json.loads(capsys.readouterr().out)["error"]
    assert main(["graph", "strategies", str(src)]) == 0
    table = capsys.readouterr().out.splitlines()
    assert table[1] == "0\t0->1\tGo 125, Rot 270, Go 652"


def test_storage_directory_is_read_in_place(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with GraphStore(tmp_path / "store") as store:
        for i in _graph().islands():
            store.put_island(i)
        assert main(["graph", "info", str(tmp_path / "store")]) == 0  # even while in use
    assert json.loads(capsys.readouterr().out)["islands"] == 4


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["graph", "info", "{d}/missing.json"], "no such file"),
        (["graph", "info", "{d}/bad.json"], "islands[0].r: NaN"),
        (["graph", "convert", "{d}/good.json", "{d}/out.txt"], "unknown graph file extension"),
        (["graph", "plan", "{d}/good.json", "--from", "0", "--to", "9"], "unknown target island 9"),
    ],
)
def test_bad_input_exits_2_with_a_clear_message(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    good = _graph().save_json(tmp_path / "good.json")
    doc = json.loads(good.read_text())
    doc["islands"][0]["r"] = float("nan")
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    assert main([a.format(d=tmp_path) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("islands graph: error:") and message in err


def test_a_directory_that_is_not_a_store_is_an_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["graph", "info", "/etc"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("islands graph: error: /etc: not a graph store")
    assert main(["graph", "info", str(tmp_path)]) == 2  # an empty directory is no store either
    assert "not a graph store" in capsys.readouterr().err


def test_salvage_of_a_damaged_store(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import sqlite3

    with GraphStore(tmp_path / "store") as store:
        for i in _graph().islands():
            store.put_island(i)
    conn = sqlite3.connect(tmp_path / "store" / "graph.sqlite3")
    conn.execute("UPDATE islands SET r = 0.25 WHERE id = 1")  # changed outside the store
    conn.commit()
    conn.close()
    assert main(["graph", "info", str(tmp_path / "store")]) == 2
    err = capsys.readouterr().err
    assert "damaged store" in err and "checksum mismatch" in err and "salvage" in err
    assert main(["graph", "salvage", str(tmp_path / "store"), "--out", str(tmp_path / "new")]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["islands"] == 3 and len(report["lost"]) == 1
    assert main(["graph", "info", str(tmp_path / "new")]) == 0
    assert json.loads(capsys.readouterr().out)["islands"] == 3
    assert main(["graph", "salvage", str(tmp_path / "nothing"), "--out", str(tmp_path / "x")]) == 2
