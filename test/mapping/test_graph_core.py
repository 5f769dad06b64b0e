"""TopoGraph: add/replace/reject, route planning, strategies, layout and the three file formats."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import networkx as nx
import numpy as np
import pytest
from island_mapping.core.graph import (
    GraphError,
    NoRouteError,
    TopoGraph,
    normalize_strategy,
    reverse_strategy,
    strategy_displacement,
)
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Island,
    LineModel,
    ModelType,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
)

S = ControlStrategy.parse


def island(i: int, n_seg: int = 3, seed: int = 0, **kw: Any) -> Island:
    rng = np.random.default_rng(seed + i)
    return Island(i, LineModel(rng.uniform(-3, 3, (n_seg, 4))), ModelType.LINE, 0.5 + i / 100,
                  float(i), **kw)


def edge(a: int, b: int, w: float, text: str = "Go 100") -> Edge:
    return Edge(a, b, S(text), w, length_m=w)


def small_graph() -> TopoGraph:
    """0 -> 1 -> 2 -> 3 cheap, 0 -> 3 expensive, 3 -> 0 back; island 9 isolated."""
    g = TopoGraph()
    for i in (0, 1, 2, 3, 9):
        g.add_island(island(i))
    for e in (edge(0, 1, 1.0), edge(1, 2, 1.0, "Rot 90, Go 250"), edge(2, 3, 1.5),
              edge(0, 3, 5.0, "Go 500, Rot 270"), edge(3, 0, 2.0, "Rot 180, Go 300")):
        g.add_edge(e)
    return g


# ----------------------------------------------------------------------------- changes


def test_add_replace_put_and_remove() -> None:
    g = small_graph()
    assert len(g) == 5 and g.num_edges == 5
    newer = dataclasses.replace(island(1), r=0.99)
    g.replace_island(newer)
    assert g.get_island(1).r == 0.99
    assert g.has_edge(0, 1) and g.has_edge(1, 2)  # edges survive a replace
    assert g.put_island(island(5)) is False and g.put_island(island(5, n_seg=1)) is True
    assert len(g.get_island(5).model) == 1
    assert g.put_edge(edge(5, 0, 3.0)) is False and g.put_edge(edge(5, 0, 4.0)) is True
    assert g.get_edge(5, 0).weight == 4.0
    g.replace_edge(edge(0, 1, 0.5))
    assert g.get_edge(0, 1).weight == 0.5
    removed = g.remove_island(3)
    assert {(e.source, e.target) for e in removed} == {(2, 3), (0, 3), (3, 0)}
    assert 3 not in g and not g.has_edge(0, 3)
    assert g.remove_edge(0, 1).weight == 0.5 and not g.has_edge(0, 1)
    assert g.island_by_frame("island_2") == 2 and g.island_by_frame("island_3") is None


def _bad_edge(**changes: Any) -> Edge:
    e = edge(0, 1, 1.0)
    for k, v in changes.items():
        object.__setattr__(e, k, v)  # bypass the dataclass checks, as a buggy caller might
    return e


@pytest.mark.parametrize(
    ("action", "message"),
    [
        (lambda g: g.add_island(island(2)), "island 2 already exists"),
        (lambda g: g.replace_island(island(42)), "cannot replace unknown island 42"),
        (lambda g: g.add_island(island(7, frame_id="island_1")), "frame 'island_1' already used"),
        (lambda g: g.add_edge(edge(0, 42, 1.0)), "edge 0->42: unknown target island 42"),
        (lambda g: g.put_edge(edge(42, 0, 1.0)), "edge 42->0: unknown source island 42"),
        (lambda g: g.add_edge(edge(0, 1, 1.0)), "edge 0->1 already exists"),
        (lambda g: g.replace_edge(edge(1, 0, 1.0)), "cannot replace unknown edge 1->0"),
        (lambda g: g.put_edge(_bad_edge(target=0)), "edge 0->0: an edge from an island to itself"),
        (lambda g: g.put_edge(_bad_edge(weight=math.nan)), "edge 0->1: weight must be finite"),
        (lambda g: g.put_edge(_bad_edge(length_m=-1.0)), "edge 0->1: length_m must be finite"),
        (lambda g: g.remove_island(42), "cannot remove unknown island 42"),
        (lambda g: g.remove_edge(1, 0), "no edge 1->0"),
        (lambda g: g.put_island("island"), "expected an Island"),
    ],
)
def test_rejected_requests_change_nothing(action: Any, message: str) -> None:
    g = small_graph()
    before, version = g.to_json(), g.version
    with pytest.raises(GraphError, match=message):
        action(g)
    assert g.to_json() == before and g.version == version


def test_nan_written_into_a_model_after_construction_is_rejected() -> None:
    g = small_graph()
    bad = island(1)
    bad.model.segments[1, 2] = np.nan  # arrays are mutable: the graph re-checks
    with pytest.raises(GraphError, match="island 1: segment 1 has a NaN"):
        g.put_island(bad)
    ok = island(6)
    g.add_island(ok)
    ok.model.segments[0, 0] = 123.0  # the graph stored a read-only copy
    assert g.get_island(6).model.segments[0, 0] != 123.0
    with pytest.raises(ValueError):
        g.get_island(6).model.segments[0, 0] = 1.0


# ----------------------------------------------------------------------------- planning


@pytest.mark.parametrize("backend", ["networkx", "scipy", "auto"])
def test_plan_route_takes_the_cheapest_directed_path(backend: str) -> None:
    g = small_graph()
    r = g.plan_route(0, 3, backend=backend)
    assert r.islands == (0, 1, 2, 3)
    assert [(e.source, e.target) for e in r.edges] == [(0, 1), (1, 2), (2, 3)]
    assert r.cost == pytest.approx(3.5)
    assert str(r.edges[1].strategy) == "Rot 90, Go 250"
    back = g.plan_route(2, 1, backend=backend)  # only via 3 -> 0 -> 1
    assert back.islands == (2, 3, 0, 1) and back.cost == pytest.approx(4.5)
    with pytest.raises(NoRouteError, match="no route from island 0 to island 9"):
        g.plan_route(0, 9, backend=backend)
    with pytest.raises(GraphError, match="unknown target island 77"):
        g.plan_route(0, 77, backend=backend)
    assert g.plan_route(2, 2, backend=backend).islands == (2,)


def test_scipy_cache_follows_changes() -> None:
    g = small_graph()
    assert g.plan_route(0, 3, backend="scipy").cost == pytest.approx(3.5)
    g.replace_edge(edge(0, 3, 1.0))
    assert g.plan_route(0, 3, backend="scipy").islands == (0, 3)
    g.remove_edge(0, 3)
    g.remove_island(2)
    with pytest.raises(NoRouteError):
        g.plan_route(0, 3, backend="scipy")


def test_backends_agree_on_random_graphs_with_zero_weights() -> None:
    rng = np.random.default_rng(11)
    g = TopoGraph()
    n = 300
    ids = rng.choice(10_000, n, replace=False)  # non-contiguous ids
    for i in ids:
        g.add_island(Island(int(i), LineModel(), ModelType.LINE, 0.1, 0.0))
    for _ in range(900):
        a, b = (int(x) for x in rng.choice(ids, 2, replace=False))
        w = 0.0 if rng.random() < 0.1 else float(rng.uniform(0.5, 10))
        g.put_edge(Edge(a, b, S("Go 10"), w))
    reference = nx.DiGraph(g.nx_graph)
    for _ in range(40):
        s, t = (int(x) for x in rng.choice(ids, 2, replace=False))
        try:
            want = nx.dijkstra_path_length(reference, s, t)
        except nx.NetworkXNoPath:
            for backend in ("networkx", "scipy"):
                with pytest.raises(NoRouteError):
                    g.plan_route(s, t, backend=backend)
            continue
        for backend in ("networkx", "scipy"):
            r = g.plan_route(s, t, backend=backend)
            assert r.cost == pytest.approx(want)
            assert r.islands[0] == s and r.islands[-1] == t
            assert sum(e.weight for e in r.edges) == pytest.approx(want)
            assert all(e.target == e2.source for e, e2 in zip(r.edges, r.edges[1:], strict=False))


# ----------------------------------------------------------------------------- strategies


def test_reverse_strategy_of_table_1() -> None:
    rev = reverse_strategy(S("Go 125, Rot 270, Go 652"))
    assert str(rev) == "Rot 180, Go 652, Rot 90, Go 125, Rot 180"
    assert str(reverse_strategy(S("Rot 270, Go 28, Rot 90, Go 832"))) == (
        "Rot 180, Go 832, Rot 270, Go 28, Rot 270"
    )
    assert str(reverse_strategy(ControlStrategy(()))) == ""  # two half turns cancel


def test_normalize_merges_and_drops() -> None:
    assert str(normalize_strategy(S("Go 5, Rot 0, Go 3, Rot 90, Rot 270, Go 0, Go 2"))) == "Go 10"
    assert str(normalize_strategy(S("Rot 200, Rot 200"))) == "Rot 40"


def test_reverse_drives_back_and_is_an_involution() -> None:
    rng = np.random.default_rng(5)
    for _ in range(50):
        steps = [
            StrategyPrimitive(PrimitiveKind.GO, int(rng.integers(0, 900))) if rng.random() < 0.5
            else StrategyPrimitive(PrimitiveKind.ROT, int(rng.integers(0, 360)))
            for _ in range(int(rng.integers(0, 7)))
        ]
        s = ControlStrategy(tuple(steps))
        there = strategy_displacement(s)
        back = there.compose(strategy_displacement(reverse_strategy(s)))
        assert back.x == pytest.approx(0, abs=1e-9) and back.y == pytest.approx(0, abs=1e-9)
        assert math.cos(back.theta) == pytest.approx(1.0)
        assert reverse_strategy(reverse_strategy(s)) == normalize_strategy(s)


def test_display_layout_chains_strategies_or_uses_truth() -> None:
    g = TopoGraph()
    for i in range(3):
        g.add_island(island(i, n_seg=0))
    g.add_island(island(5, n_seg=0))  # a second component
    g.add_edge(edge(0, 1, 1.0, "Go 100"))
    g.add_edge(edge(2, 1, 1.0, "Rot 270, Go 200, Rot 90"))  # 2 is reached backwards
    lay = g.display_layout(margin_m=2.0)
    rel1 = lay[1].relative_to(lay[0])
    assert (rel1.x, rel1.y) == pytest.approx((1.0, 0.0), abs=1e-9)
    rel2 = lay[2].relative_to(lay[0])
    assert (rel2.x, rel2.y) == pytest.approx((1.0, 2.0), abs=1e-9)
    assert lay[5].x == pytest.approx(max(p.x for k, p in lay.items() if k != 5) + 2.0)
    truth = TopoGraph.from_parts(
        [island(i, origin_truth=Pose2D(10.0 * i, 1.0, 0.5)) for i in range(3)], []
    )
    assert truth.display_layout()[2] == Pose2D(20.0, 1.0, 0.5)


# ----------------------------------------------------------------------------- formats


def test_json_round_trip(tmp_path: Path) -> None:
    g = small_graph()
    g.put_island(island(4, origin_truth=Pose2D(1.5, -2.0, 0.25)))
    assert TopoGraph.from_json(g.to_json()) == g
    path = g.save_json(tmp_path / "g.json")
    assert TopoGraph.load_json(path) == g


def _no_nested_lists(obj: Any) -> bool:
    """Nav2's GeoJSON loader takes objects, primitives and arrays of primitives; no nulls."""
    if isinstance(obj, dict):
        return all(_no_nested_lists(v) for v in obj.values())
    if isinstance(obj, list):
        return all(isinstance(v, int | float | str | bool) for v in obj)
    return obj is not None


def test_geojson_is_nav2_shaped_and_round_trips(tmp_path: Path) -> None:
    g = small_graph()
    g.put_island(island(4, origin_truth=Pose2D(1.5, -2.0, 0.25)))
    doc = g.to_geojson()
    assert doc["type"] == "FeatureCollection"
    points = [f for f in doc["features"] if f["geometry"]["type"] == "Point"]
    lines = [f for f in doc["features"] if f["geometry"]["type"] == "MultiLineString"]
    ids = [f["properties"]["id"] for f in doc["features"]]
    assert len(ids) == len(set(ids)), "ids must be unique across nodes and edges"
    assert sorted(p["properties"]["id"] for p in points) == g.island_ids()
    for p in points:
        props = p["properties"]
        assert props["frame"] == f"island_{props['id']}"
        assert len(p["geometry"]["coordinates"]) == 2
        assert len(props["metadata"]["segments"]) == 4 * props["metadata"]["num_segments"]
        assert _no_nested_lists(props["metadata"])  # Nav2 metadata arrays hold primitives only
    pairs = {(f["properties"]["startid"], f["properties"]["endid"]) for f in lines}
    for e in g.edges():
        assert (e.source, e.target) in pairs and (e.target, e.source) in pairs
    assert all(_no_nested_lists(f["properties"]["metadata"]) for f in lines)
    derived = [f for f in lines if f["properties"]["metadata"]["derived"]]
    # 0<->3 exist both ways: 4 real edges without a reverse get a derived one
    assert len(lines) == 5 + 3 and len(derived) == 3
    d12 = next(f for f in derived if f["properties"]["startid"] == 2)
    # reverse of "Rot 90, Go 250": Rot 180, Go 250, Rot 270, Rot 180 -> merged
    assert d12["properties"]["metadata"]["strategy"] == "Rot 180, Go 250, Rot 90"
    fwd_id = d12["properties"]["metadata"]["reverse_of"]
    fwd = next(f for f in lines if f["properties"]["id"] == fwd_id)
    assert (fwd["properties"]["startid"], fwd["properties"]["endid"]) == (1, 2)
    assert d12["properties"]["cost"] == fwd["properties"]["cost"]
    path = g.save_geojson(tmp_path / "g.geojson")
    assert TopoGraph.load_geojson(path) == g
    assert TopoGraph.from_geojson(json.loads(path.read_text())) == g


def test_geojson_import_errors_name_the_feature() -> None:
    doc = small_graph().to_geojson()
    doc["features"][1]["properties"]["metadata"]["r"] = "high"
    with pytest.raises(GraphFormatError,
                       match=r"^features\[1\]\.properties\.metadata\.r: expected a number"):
        TopoGraph.from_geojson(doc)
    doc = small_graph().to_geojson()
    doc["features"][2]["properties"]["metadata"]["segments"][5] = math.nan
    with pytest.raises(GraphFormatError,
                       match=r"^features\[2\]\.properties\.metadata\.segments\[4:8\]: NaN"):
        TopoGraph.from_geojson(doc)
    doc = small_graph().to_geojson()
    k = next(k for k, f in enumerate(doc["features"])
             if f["geometry"]["type"] != "Point" and not f["properties"]["metadata"]["derived"])
    doc["features"][k]["properties"]["endid"] = 99
    with pytest.raises(GraphFormatError, match="unknown target island 99"):
        TopoGraph.from_geojson(doc)
    doc["features"][k]["properties"]["cost"] = -2.0
    with pytest.raises(GraphFormatError, match=rf"^features\[{k}\]\.properties\.cost: must be"):
        TopoGraph.from_geojson(doc)
    with pytest.raises(GraphFormatError, match="FeatureCollection"):
        TopoGraph.from_geojson({"type": "Feature"})


def test_graphml_round_trip_with_string_attributes(tmp_path: Path) -> None:
    g = small_graph()
    g.put_island(island(4, origin_truth=Pose2D(1.5, -2.0, 0.25)))
    path = g.save_graphml(tmp_path / "g.graphml")
    assert TopoGraph.load_graphml(path) == g
    root = ET.parse(path).getroot()
    keys = {k.get("attr.name"): k.get("attr.type") for k in root.iter() if k.tag.endswith("key")}
    assert keys["segments"] == "string" and keys["strategy"] == "string"
    assert nx.read_graphml(path).number_of_edges() == g.num_edges
    (tmp_path / "bad.graphml").write_text("<graphml><oops")
    with pytest.raises(GraphFormatError, match="GraphML"):
        TopoGraph.load_graphml(tmp_path / "bad.graphml")


def test_save_all_and_load_any(tmp_path: Path) -> None:
    g = small_graph()
    paths = g.save_all(tmp_path / "out")
    names = sorted(p.name for p in paths.values())
    assert names == ["graph.geojson", "graph.graphml", "graph.json"]
    for p in paths.values():
        assert TopoGraph.load_any(p) == g
    with pytest.raises(GraphFormatError, match="unknown graph file extension"):
        TopoGraph.load_any(tmp_path / "g.txt")


def test_graph_core_does_not_import_rclpy() -> None:
    code = (
        "import sys, island_mapping.core.graph\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'std_msgs')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
