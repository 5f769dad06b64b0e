"""The global topological map M = {V, E} (paper eq. 1) held in a networkx DiGraph (no rclpy).

A node is an `Island` (its line model L in its own frame, the model type T that accepted it); a
directed edge is an `Edge` (the control strategy S from the source island's origin to the target
island's origin, and the weight W [m] used for planning). There is at most one edge per ordered
pair of islands.

Route planning is Dijkstra on W. A* would need an admissible heuristic, i.e. a metric position
of every island in one frame; the map deliberately has no global frame (positions derived from
chained strategies carry unbounded drift and are not admissible), so A* has nothing to offer.
Small graphs use networkx's bidirectional Dijkstra; from `SCIPY_MIN_ISLANDS` islands on, a
cached CSR matrix and scipy's C Dijkstra are used, with the shortest-path tree of recent
sources cached until the graph changes (see bench/bench_route_planning.py for the numbers).

Exports: the project's JSON document (island_msgs_py.json_io), the Nav2 Route Server GeoJSON
graph format, and GraphML; each imports back to an identical graph. `GraphStore` persists every
accepted change with a write-ahead log (fsync per change) plus atomic snapshots.
"""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import itertools
import json
import math
import os
from collections import OrderedDict
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

import networkx as nx
import numpy as np
import scipy.sparse as sp
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
from scipy.sparse.csgraph import dijkstra

from island_msgs_py import json_io

# From this many islands on, plan on a cached CSR matrix with scipy (C Dijkstra). Measured
# (bench/bench_route_planning.py): at 1,000 islands a CSR rebuild + query costs about what one
# networkx bidirectional query does and later queries are 5x faster; below it networkx wins
# because every change would force a rebuild.
SCIPY_MIN_ISLANDS = 1000
# Shortest-path trees of this many recent sources are kept until the graph changes.
ROUTE_TREE_CACHE_SIZE = 8
GEOJSON_FORMAT = "islands-graph-geojson"
GRAPHML_FORMAT = "islands-graph-graphml"
TURN_AROUND_DEG = 180  # the reverse of a strategy starts and ends with a half turn


class GraphError(ValueError):
    """A request on the map was rejected (the message names the island/edge and the problem)."""


class NoRouteError(GraphError):
    """Both islands exist but no directed path joins them."""


@dataclass(frozen=True)
class Route:
    """A planned route: island ids in travel order, the edges between them, total weight [m]."""

    islands: tuple[int, ...]
    edges: tuple[Edge, ...]
    cost: float


# ----------------------------------------------------------------------------- strategies


def normalize_strategy(strategy: ControlStrategy) -> ControlStrategy:
    """Drop Go 0 and Rot 0, merge consecutive rotations (mod 360) and consecutive Go steps."""
    steps: list[StrategyPrimitive] = []
    for s in strategy.steps:
        if s.value == 0:
            continue
        if steps and steps[-1].kind is s.kind:
            value = steps.pop().value + s.value
            if s.kind is PrimitiveKind.ROT:
                value %= 360
            if value == 0:
                continue
            s = StrategyPrimitive(s.kind, value)
        steps.append(s)
    return ControlStrategy(tuple(steps))


def reverse_strategy(strategy: ControlStrategy) -> ControlStrategy:
    """The strategy that drives back from the target origin (heading 0) to the source origin.

    Turn around (Rot 180), replay the steps in reverse order with Go unchanged and every
    Rot a replaced by Rot (360 - a) % 360, then turn around again (Rot 180) so the robot faces
    the source frame's heading 0. Adjacent rotations are merged (`normalize_strategy`), so
    reversing twice gives back the normalized strategy.
    """
    turn = StrategyPrimitive(PrimitiveKind.ROT, TURN_AROUND_DEG)
    mirrored = [
        StrategyPrimitive(s.kind, (360 - s.value) % 360 if s.kind is PrimitiveKind.ROT else s.value)
        for s in reversed(strategy.steps)
    ]
    return normalize_strategy(ControlStrategy((turn, *mirrored, turn)))


def strategy_displacement(strategy: ControlStrategy) -> Pose2D:
    """Where the strategy ends, in the frame it starts from (ideal execution) [m, rad]."""
    pose = Pose2D(0.0, 0.0, 0.0)
    for s in strategy.steps:
        pose = pose.compose(Pose2D(s.metres, 0.0, s.radians))
    return pose


# ----------------------------------------------------------------------------- the graph


def _check_island(island: Island) -> Island:
    """Re-validate an island (arrays are mutable) and return a copy with a read-only model."""
    if not isinstance(island, Island):
        raise GraphError(f"expected an Island, got {type(island).__name__}")
    if isinstance(island.id, bool) or not isinstance(island.id, int | np.integer) or island.id < 0:
        raise GraphError(f"island id must be an integer >= 0, got {island.id!r}")
    segs = np.array(island.model.segments, dtype=np.float64, copy=True)
    if segs.size and (segs.ndim != 2 or segs.shape[1] != 4):
        raise GraphError(f"island {island.id}: segments must be (N, 4), got {segs.shape}")
    if not np.all(np.isfinite(segs)):
        bad = int(np.argwhere(~np.isfinite(segs.reshape(-1, 4)))[0][0])
        raise GraphError(f"island {island.id}: segment {bad} has a NaN or infinite coordinate")
    for name in ("r", "built_at_s"):
        if not math.isfinite(float(getattr(island, name))):
            raise GraphError(f"island {island.id}: {name} is not finite")
    if not isinstance(island.model_type, ModelType):
        raise GraphError(f"island {island.id}: unknown model type {island.model_type!r}")
    segs.setflags(write=False)
    model = LineModel(segs)
    model.segments.setflags(write=False)
    return dataclasses.replace(island, id=int(island.id), model=model)


class TopoGraph:
    """M = {V, E}: islands keyed by id, at most one directed edge per ordered pair of islands.

    Every mutating method validates its request first and raises `GraphError` without changing
    anything when it is rejected.
    """

    def __init__(self) -> None:
        self._g: nx.DiGraph = nx.DiGraph()
        self._version = 0  # bumped on every change; invalidates the planning caches
        self._csr_version = -1
        self._csr: sp.csr_array | None = None
        self._ids = np.zeros(0, dtype=np.int64)  # sorted island ids = CSR row order
        self._trees: OrderedDict[int, tuple[np.ndarray, np.ndarray]] = OrderedDict()
        self._frames: dict[str, int] = {}  # frame id -> island id
        self._weights: dict[tuple[int, int], float] = {}  # (source, target) -> W, for the CSR

    # --- construction / inspection -----------------------------------------------------------

    @classmethod
    def from_parts(cls, islands: Iterable[Island], edges: Iterable[Edge]) -> TopoGraph:
        g = cls()
        for island in islands:
            g.add_island(island)
        for edge in edges:
            g.add_edge(edge)
        return g

    def __len__(self) -> int:
        return int(self._g.number_of_nodes())

    def __contains__(self, island_id: object) -> bool:
        return island_id in self._g

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, TopoGraph):
            return NotImplemented
        return self.islands() == other.islands() and self.edges() == other.edges()

    __hash__ = None  # type: ignore[assignment]

    def __repr__(self) -> str:
        return f"TopoGraph({len(self)} islands, {self.num_edges} edges)"

    @property
    def num_edges(self) -> int:
        return int(self._g.number_of_edges())

    @property
    def version(self) -> int:
        """A counter bumped by every accepted change."""
        return self._version

    @property
    def nx_graph(self) -> nx.DiGraph:
        """The DiGraph (node attr `island`, edge attrs `edge` and `weight`); read only."""
        return self._g

    def island_ids(self) -> list[int]:
        return sorted(self._g.nodes)

    def islands(self) -> list[Island]:
        """All islands sorted by id."""
        return [self._g.nodes[i]["island"] for i in sorted(self._g.nodes)]

    def edges(self) -> list[Edge]:
        """All edges sorted by (source, target)."""
        return [self._g.edges[u, v]["edge"] for u, v in sorted(self._g.edges)]

    def iter_edges(self) -> Iterator[Edge]:
        for _, _, data in self._g.edges(data=True):
            yield data["edge"]

    def get_island(self, island_id: int) -> Island:
        if island_id not in self._g:
            raise GraphError(f"unknown island {island_id}")
        island: Island = self._g.nodes[island_id]["island"]
        return island

    def get_edge(self, source: int, target: int) -> Edge:
        if not self._g.has_edge(source, target):
            raise GraphError(f"no edge {source}->{target}")
        edge: Edge = self._g.edges[source, target]["edge"]
        return edge

    def has_edge(self, source: int, target: int) -> bool:
        return bool(self._g.has_edge(source, target))

    def island_by_frame(self, frame_id: str) -> int | None:
        """The id of the island whose frame is `frame_id` (`island_<id>` or its custom frame)."""
        return self._frames.get(frame_id)

    # --- validation (no change) ---------------------------------------------------------------

    def check_island(self, island: Island, mode: str = "put") -> Island:
        """Validate an 'add', 'replace' or either ('put'); returns the copy to store."""
        checked = _check_island(island)
        exists = checked.id in self._g
        if mode == "add" and exists:
            raise GraphError(f"island {checked.id} already exists (use replace)")
        if mode == "replace" and not exists:
            raise GraphError(f"cannot replace unknown island {checked.id}")
        owner = self._frames.get(checked.frame_id)
        if owner is not None and owner != checked.id:
            raise GraphError(
                f"island {checked.id}: frame {checked.frame_id!r} already used by island {owner}"
            )
        return checked

    def _store_island(self, island: Island) -> None:
        if island.id in self._g:
            del self._frames[self._g.nodes[island.id]["island"].frame_id]
        self._g.add_node(island.id, island=island)
        self._frames[island.frame_id] = island.id
        self._changed()

    def check_edge(self, edge: Edge, mode: str = "put") -> Edge:
        """Validate an edge add/replace/put request (ids known, no self-edge, finite weights)."""
        if not isinstance(edge, Edge):
            raise GraphError(f"expected an Edge, got {type(edge).__name__}")
        name = f"edge {edge.source}->{edge.target}"
        if edge.source == edge.target:
            raise GraphError(f"{name}: an edge from an island to itself")
        for end in ("source", "target"):
            if getattr(edge, end) not in self._g:
                raise GraphError(f"{name}: unknown {end} island {getattr(edge, end)}")
        for attr in ("weight", "length_m", "expected_error_m"):
            v = float(getattr(edge, attr))
            if not math.isfinite(v) or v < 0:
                raise GraphError(f"{name}: {attr} must be finite and >= 0, got {v}")
        exists = self._g.has_edge(edge.source, edge.target)
        if mode == "add" and exists:
            raise GraphError(f"{name} already exists (use replace)")
        if mode == "replace" and not exists:
            raise GraphError(f"cannot replace unknown {name}")
        return edge

    # --- changes -------------------------------------------------------------------------------

    def _changed(self) -> None:
        self._version += 1
        self._trees.clear()

    def add_island(self, island: Island) -> None:
        self._store_island(self.check_island(island, "add"))

    def replace_island(self, island: Island) -> None:
        self._store_island(self.check_island(island, "replace"))

    def put_island(self, island: Island) -> bool:
        """Add or replace; True when an existing island was replaced."""
        checked = self.check_island(island, "put")
        replaced = checked.id in self._g
        self._store_island(checked)
        return replaced

    def _store_edge(self, edge: Edge) -> None:
        self._g.add_edge(edge.source, edge.target, edge=edge, weight=float(edge.weight))
        self._weights[edge.source, edge.target] = float(edge.weight)
        self._changed()

    def add_edge(self, edge: Edge) -> None:
        self.check_edge(edge, "add")
        self._store_edge(edge)

    def replace_edge(self, edge: Edge) -> None:
        self.check_edge(edge, "replace")
        self._store_edge(edge)

    def put_edge(self, edge: Edge) -> bool:
        """Add or replace; True when an existing edge was replaced."""
        self.check_edge(edge, "put")
        replaced = self._g.has_edge(edge.source, edge.target)
        self._store_edge(edge)
        return replaced

    def remove_island(self, island_id: int) -> list[Edge]:
        """Remove an island and its edges; returns the removed edges."""
        if island_id not in self._g:
            raise GraphError(f"cannot remove unknown island {island_id}")
        removed = [d["edge"] for _, _, d in self._g.in_edges(island_id, data=True)]
        removed += [d["edge"] for _, _, d in self._g.out_edges(island_id, data=True)]
        for e in removed:
            del self._weights[e.source, e.target]
        del self._frames[self._g.nodes[island_id]["island"].frame_id]
        self._g.remove_node(island_id)
        self._changed()
        return removed

    def remove_edge(self, source: int, target: int) -> Edge:
        edge = self.get_edge(source, target)
        self._g.remove_edge(source, target)
        del self._weights[source, target]
        self._changed()
        return edge

    # --- planning ------------------------------------------------------------------------------

    def plan_route(self, source: int, target: int, backend: str = "auto") -> Route:
        """Least-weight directed route (Dijkstra on W [m]).

        backend: "auto" (networkx below SCIPY_MIN_ISLANDS islands, else scipy), "networkx", or
        "scipy". Raises GraphError for unknown islands and NoRouteError when unreachable.
        """
        for name, i in (("source", source), ("target", target)):
            if i not in self._g:
                raise GraphError(f"plan: unknown {name} island {i}")
        if source == target:
            return Route((source,), (), 0.0)
        if backend == "auto":
            backend = "scipy" if len(self) >= SCIPY_MIN_ISLANDS else "networkx"
        if backend == "networkx":
            try:
                cost, path = nx.bidirectional_dijkstra(self._g, source, target, weight="weight")
            except nx.NetworkXNoPath:
                msg = f"plan: no route from island {source} to island {target}"
                raise NoRouteError(msg) from None
            nodes = [int(n) for n in path]
        elif backend == "scipy":
            nodes, cost = self._plan_scipy(source, target)
        else:
            raise GraphError(f"plan: unknown backend {backend!r} (auto, networkx, scipy)")
        edges = tuple(self._g.edges[u, v]["edge"] for u, v in itertools.pairwise(nodes))
        return Route(tuple(nodes), edges, float(cost))

    def clear_planning_cache(self) -> None:
        """Forget the CSR matrix and the cached shortest-path trees (as a change would)."""
        self._csr = None
        self._trees.clear()

    def _matrix(self) -> sp.csr_array:
        if self._csr is None or self._csr_version != self._version:
            ids = np.array(sorted(self._g.nodes), dtype=np.int64)
            n = len(ids)
            m = len(self._weights)
            flat = itertools.chain.from_iterable(self._weights)
            uv = np.fromiter(flat, dtype=np.int64, count=2 * m).reshape(m, 2)
            rows, cols = uv[:, 0], uv[:, 1]
            w = np.fromiter(self._weights.values(), dtype=np.float64, count=m)
            # explicit zero weights stay edges in scipy's csgraph (they are not eliminated)
            self._csr = sp.csr_array(
                (w, (np.searchsorted(ids, rows), np.searchsorted(ids, cols))), shape=(n, n)
            )
            self._ids = ids
            self._csr_version = self._version
            self._trees.clear()
        return self._csr

    def _plan_scipy(self, source: int, target: int) -> tuple[list[int], float]:
        csr = self._matrix()
        s = int(np.searchsorted(self._ids, source))
        t = int(np.searchsorted(self._ids, target))
        tree = self._trees.get(source)
        if tree is None:
            dist, pred = dijkstra(csr, directed=True, indices=s, return_predecessors=True)
            tree = (dist, pred)
            self._trees[source] = tree
            while len(self._trees) > ROUTE_TREE_CACHE_SIZE:
                self._trees.popitem(last=False)
        else:
            self._trees.move_to_end(source)
        dist, pred = tree
        if not math.isfinite(float(dist[t])):
            raise NoRouteError(f"plan: no route from island {source} to island {target}")
        path = [t]
        while path[-1] != s:
            path.append(int(pred[path[-1]]))
        return [int(self._ids[k]) for k in reversed(path)], float(dist[t])

    # --- display layout ------------------------------------------------------------------------

    def display_layout(self, margin_m: float = 2.0) -> dict[int, Pose2D]:
        """A pose per island for DISPLAY only (there is no global frame).

        When every island knows its simulator `origin_truth`, that is used. Otherwise each
        weakly connected component is laid out by chaining ideal executions of the edge
        strategies from its lowest id (backwards along reversed edges), and components are
        placed side by side, `margin_m` apart. Drift makes this picture wrong at large scale;
        nothing may use it for computation.
        """
        islands = {i.id: i for i in self.islands()}
        if islands and all(i.origin_truth is not None for i in islands.values()):
            return {k: v.origin_truth for k, v in islands.items() if v.origin_truth is not None}
        layout: dict[int, Pose2D] = {}
        und = self._g.to_undirected(as_view=True)
        x_offset = 0.0
        for comp in sorted(nx.connected_components(und), key=min):
            root = min(comp)
            local: dict[int, Pose2D] = {root: Pose2D(0.0, 0.0, 0.0)}
            stack = [root]
            while stack:
                u = stack.pop()
                for v in sorted(und.neighbors(u)):
                    if v in local:
                        continue
                    if self._g.has_edge(u, v):
                        step = strategy_displacement(self._g.edges[u, v]["edge"].strategy)
                    else:
                        step = strategy_displacement(self._g.edges[v, u]["edge"].strategy).inverse()
                    local[v] = local[u].compose(step)
                    stack.append(v)
            xs: list[float] = []
            ys: list[float] = []
            for i, p in local.items():
                pts = _model_points(islands[i].model.segments, p)
                xs.extend(pts[:, 0])
                ys.extend(pts[:, 1])
            shift = x_offset - min(xs)
            for i, p in local.items():
                layout[i] = Pose2D(p.x + shift, p.y - min(ys), p.theta)
            x_offset += (max(xs) - min(xs)) + margin_m
        return layout

    # --- JSON ----------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        return json_io.graph_to_dict(self.islands(), self.edges())

    def to_json(self, indent: int | None = None) -> str:
        return json_io.graph_to_json(self.islands(), self.edges(), indent=indent)

    @classmethod
    def from_dict(cls, doc: Any) -> TopoGraph:
        islands, edges = json_io.graph_from_dict(doc)
        return cls.from_parts(islands, edges)

    @classmethod
    def from_json(cls, text: str | bytes) -> TopoGraph:
        islands, edges = json_io.graph_from_json(text)
        return cls.from_parts(islands, edges)

    def save_json(self, path: str | os.PathLike[str]) -> Path:
        return json_io.save_graph_json(path, self.islands(), self.edges())

    @classmethod
    def load_json(cls, path: str | os.PathLike[str]) -> TopoGraph:
        islands, edges = json_io.load_graph_json(path)
        return cls.from_parts(islands, edges)

    # --- Nav2 Route Server GeoJSON -------------------------------------------------------------

    def to_geojson(self) -> dict[str, Any]:
        """The Nav2 Route Server graph format (a GeoJSON FeatureCollection).

        Point features are islands: properties `id` (the island id), `frame` (its frame) and
        `metadata` (model_type, r, built_at_s, origin_truth, and the line model as a flat list
        `segments` [x1, y1, x2, y2, ...] [m] with `num_segments`, because Nav2's metadata parser
        takes arrays of primitives only). MultiLineString features are edges with `id`,
        `startid`, `endid`, `cost` (W [m]) and `metadata.strategy` (Table 1 text). Every edge
        is exported in both directions: when the graph has no edge back, a derived reverse edge
        (`metadata.derived = true`, `metadata.reverse_of` = the forward feature id, strategy =
        `reverse_strategy`) is added, with the same cost. Edge ids start after the largest
        island id, so ids are unique across nodes and edges. Coordinates are the display layout
        (`display_layout`), not a metric frame.
        """
        layout = self.display_layout()
        features: list[dict[str, Any]] = []
        for island in self.islands():
            p = layout[island.id]
            features.append({
                "type": "Feature",
                "geometry": {"type": "Point", "coordinates": [p.x, p.y]},
                "properties": {
                    "id": island.id,
                    "frame": island.frame_id,
                    "metadata": {
                        "model_type": island.model_type.value,
                        "r": island.r,
                        "built_at_s": island.built_at_s,
                        "num_segments": len(island.model),
                        "segments": island.model.segments.reshape(-1).tolist(),
                        "layout_theta_rad": p.theta,
                        **(
                            {"origin_truth": json_io.pose_to_dict(island.origin_truth)}
                            if island.origin_truth is not None else {}
                        ),
                    },
                },
            })
        next_id = (max(self._g.nodes) + 1) if len(self) else 0
        for edge in self.edges():
            fid = next_id
            next_id += 1
            features.append(_edge_feature(fid, edge, layout, derived_from=None))
            if not self._g.has_edge(edge.target, edge.source):
                back = dataclasses.replace(
                    edge, source=edge.target, target=edge.source,
                    strategy=reverse_strategy(edge.strategy),
                )
                features.append(_edge_feature(next_id, back, layout, derived_from=fid))
                next_id += 1
        return {
            "type": "FeatureCollection",
            "name": "islands_graph",
            "islands_graph": {
                "format": GEOJSON_FORMAT,
                "version": json_io.FORMAT_VERSION,
                "coordinates": "display layout only: islands have no common metric frame",
            },
            "features": features,
        }

    @classmethod
    def from_geojson(cls, doc: Any) -> TopoGraph:
        """Import a GeoJSON written by `to_geojson` (derived reverse edges are skipped)."""
        if not isinstance(doc, Mapping) or doc.get("type") != "FeatureCollection":
            raise GraphFormatError("", "expected a GeoJSON FeatureCollection")
        feats = doc.get("features")
        if not isinstance(feats, list):
            raise GraphFormatError("features", "expected a list")
        islands: list[Island] = []
        edges: list[Edge] = []
        for k, feat in enumerate(feats):
            path = f"features[{k}]"
            if not isinstance(feat, Mapping):
                raise GraphFormatError(path, "expected an object")
            geom = feat.get("geometry")
            gtype = geom.get("type") if isinstance(geom, Mapping) else None
            props = feat.get("properties")
            if not isinstance(props, Mapping):
                raise GraphFormatError(f"{path}.properties", "expected an object")
            meta = props.get("metadata", {})
            if not isinstance(meta, Mapping):
                raise GraphFormatError(f"{path}.properties.metadata", "expected an object")
            mp = f"{path}.properties.metadata"
            if gtype == "Point":
                num = meta.get("num_segments")
                flat = meta.get("segments")
                if not isinstance(flat, list) or not isinstance(num, int) or len(flat) != 4 * num:
                    raise GraphFormatError(
                        f"{mp}.segments", "expected a flat list of 4 * num_segments numbers"
                    )
                rows = [flat[4 * j: 4 * j + 4] for j in range(num)]
                with _geojson_paths(f"{path}.properties", _NODE_KEYS):
                    islands.append(json_io.island_from_dict({
                        "id": props.get("id"),
                        "frame_id": props.get("frame", ""),
                        "model_type": meta.get("model_type"),
                        "r": meta.get("r"),
                        "built_at_s": meta.get("built_at_s"),
                        "model": {"segments": rows},
                        "origin_truth": meta.get("origin_truth"),
                    }, f"{path}.properties"))
            elif gtype in ("MultiLineString", "LineString"):
                if meta.get("derived", False):
                    continue
                with _geojson_paths(f"{path}.properties", _EDGE_KEYS):
                    edges.append(json_io.edge_from_dict({
                        "source": props.get("startid"),
                        "target": props.get("endid"),
                        "strategy": meta.get("strategy", ""),
                        "weight": props.get("cost", 0.0),
                        "length_m": meta.get("length_m", 0.0),
                        "expected_error_m": meta.get("expected_error_m", 0.0),
                    }, f"{path}.properties"))
            else:
                raise GraphFormatError(f"{path}.geometry.type", f"unsupported geometry {gtype!r}")
        try:
            return cls.from_parts(islands, edges)
        except GraphError as exc:
            raise GraphFormatError("features", str(exc)) from exc

    def save_geojson(self, path: str | os.PathLike[str]) -> Path:
        return json_io.atomic_write_text(path, json_io.dumps(self.to_geojson(), indent=1) + "\n")

    @classmethod
    def load_geojson(cls, path: str | os.PathLike[str]) -> TopoGraph:
        return cls.from_geojson(_read_json_file(path))

    # --- GraphML -------------------------------------------------------------------------------

    def to_graphml_graph(self) -> nx.DiGraph:
        """A DiGraph with only GraphML-representable attributes (strings and doubles)."""
        g = nx.DiGraph(format=GRAPHML_FORMAT, version=json_io.FORMAT_VERSION)
        for island in self.islands():
            g.add_node(
                island.id,
                frame_id=island.frame_id,
                model_type=island.model_type.value,
                r=float(island.r),
                built_at_s=float(island.built_at_s),
                segments=json_io.dumps(island.model.segments.tolist()),
                origin_truth="" if island.origin_truth is None
                else json_io.dumps(json_io.pose_to_dict(island.origin_truth)),
            )
        for e in self.edges():
            g.add_edge(
                e.source, e.target, strategy=str(e.strategy), weight=float(e.weight),
                length_m=float(e.length_m), expected_error_m=float(e.expected_error_m),
            )
        return g

    def save_graphml(self, path: str | os.PathLike[str]) -> Path:
        text = "\n".join(nx.generate_graphml(self.to_graphml_graph())) + "\n"
        return json_io.atomic_write_text(path, text)

    @classmethod
    def load_graphml(cls, path: str | os.PathLike[str]) -> TopoGraph:
        try:
            g = nx.read_graphml(os.fspath(path), node_type=int)
        except (OSError, ValueError, nx.NetworkXError) as exc:
            raise GraphFormatError(str(path), f"cannot read GraphML: {exc}") from exc
        except Exception as exc:  # xml.etree ParseError and friends
            raise GraphFormatError(str(path), f"not GraphML: {exc}") from exc
        islands = []
        for n, d in g.nodes(data=True):
            np_ = f"{path}: node {n}"
            origin = d.get("origin_truth", "")
            islands.append(json_io.island_from_dict({
                "id": n,
                "frame_id": d.get("frame_id", ""),
                "model_type": d.get("model_type"),
                "r": d.get("r"),
                "built_at_s": d.get("built_at_s"),
                "model": {"segments": _json_attr(d.get("segments", "[]"), f"{np_}.segments")},
                "origin_truth": _json_attr(origin, f"{np_}.origin_truth") if origin else None,
            }, np_))
        edges = [
            json_io.edge_from_dict({
                "source": u, "target": v, "strategy": d.get("strategy", ""),
                "weight": d.get("weight"), "length_m": d.get("length_m", 0.0),
                "expected_error_m": d.get("expected_error_m", 0.0),
            }, f"{path}: edge {u}->{v}")
            for u, v, d in g.edges(data=True)
        ]
        try:
            return cls.from_parts(islands, edges)
        except GraphError as exc:
            raise GraphFormatError(str(path), str(exc)) from exc

    # --- all exports ---------------------------------------------------------------------------

    def save_all(self, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
        """Write graph.json, graph.geojson and graph.graphml into `out_dir` (atomically each)."""
        d = Path(out_dir)
        return {
            "json": self.save_json(d / "graph.json"),
            "geojson": self.save_geojson(d / "graph.geojson"),
            "graphml": self.save_graphml(d / "graph.graphml"),
        }

    @classmethod
    def load_any(cls, path: str | os.PathLike[str]) -> TopoGraph:
        """Load by extension: .json (graph document), .geojson, .graphml."""
        suffix = Path(path).suffix.lower()
        if suffix == ".json":
            return cls.load_json(path)
        if suffix == ".geojson":
            return cls.load_geojson(path)
        if suffix == ".graphml":
            return cls.load_graphml(path)
        raise GraphFormatError(str(path), f"unknown graph file extension {suffix!r} "
                               "(.json, .geojson, .graphml)")

    def save_any(self, path: str | os.PathLike[str]) -> Path:
        suffix = Path(path).suffix.lower()
        if suffix == ".json":
            return self.save_json(path)
        if suffix == ".geojson":
            return self.save_geojson(path)
        if suffix == ".graphml":
            return self.save_graphml(path)
        raise GraphFormatError(str(path), f"unknown graph file extension {suffix!r} "
                               "(.json, .geojson, .graphml)")


# Where the fields of our island/edge JSON live in a Nav2 GeoJSON feature's properties.
_NODE_KEYS = {
    "frame_id": "frame", "model_type": "metadata.model_type", "r": "metadata.r",
    "built_at_s": "metadata.built_at_s", "origin_truth": "metadata.origin_truth",
    "model": "metadata.segments",
}
_EDGE_KEYS = {
    "source": "startid", "target": "endid", "weight": "cost", "strategy": "metadata.strategy",
    "length_m": "metadata.length_m", "expected_error_m": "metadata.expected_error_m",
}


@contextlib.contextmanager
def _geojson_paths(prefix: str, keys: Mapping[str, str]) -> Iterator[None]:
    """Rename field paths in GraphFormatErrors from our JSON names to the GeoJSON ones."""
    try:
        yield
    except GraphFormatError as exc:
        p = exc.path
        if p.startswith(prefix + "."):
            head, _, tail = p[len(prefix) + 1:].partition(".")
            key = head.split("[")[0]
            if key in keys:
                p = f"{prefix}.{keys[key]}"
                if key == "model" and tail.startswith("segments["):
                    row = int(tail[len("segments["):].split("]")[0])
                    p += f"[{4 * row}:{4 * row + 4}]"
                elif tail:
                    p += "." + tail
        raise GraphFormatError(p, exc.problem) from exc


def _model_points(segments: np.ndarray, pose: Pose2D) -> np.ndarray:
    """Segment endpoints and the origin, transformed by `pose` into the layout frame, (K, 2) [m]."""
    pts = np.vstack([np.zeros((1, 2)), segments.reshape(-1, 2)])
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    rot = np.array([[c, -s], [s, c]])
    out: np.ndarray = pts @ rot.T + np.array([pose.x, pose.y])
    return out


def _edge_feature(
    fid: int, edge: Edge, layout: Mapping[int, Pose2D], derived_from: int | None
) -> dict[str, Any]:
    a, b = layout[edge.source], layout[edge.target]
    meta: dict[str, Any] = {
        "strategy": str(edge.strategy),
        "length_m": edge.length_m,
        "expected_error_m": edge.expected_error_m,
        "derived": derived_from is not None,
    }
    if derived_from is not None:
        meta["reverse_of"] = derived_from
    return {
        "type": "Feature",
        "geometry": {"type": "MultiLineString", "coordinates": [[[a.x, a.y], [b.x, b.y]]]},
        "properties": {
            "id": fid, "startid": edge.source, "endid": edge.target,
            "cost": edge.weight, "metadata": meta,
        },
    }


def _read_json_file(path: str | os.PathLike[str]) -> Any:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise GraphFormatError(str(path), f"cannot read: {exc}") from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise GraphFormatError(str(path), f"not valid JSON: {exc}") from exc


def _json_attr(text: Any, path: str) -> Any:
    if not isinstance(text, str):
        raise GraphFormatError(path, "expected a JSON string attribute")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise GraphFormatError(path, f"not valid JSON: {exc}") from exc


# ----------------------------------------------------------------------------- persistence


@dataclass(frozen=True)
class GraphStoreConfig:
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


class GraphStore:
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
        config: GraphStoreConfig | None = None,
        read_only: bool = False,
    ) -> None:
        """Open (creating it when missing) and load the store. A writable store holds an
        exclusive lock on `directory/.lock` (released by the OS even on SIGKILL), so two
        writers never interleave; `read_only=True` only reads and changes nothing on disk."""
        self.config = config or GraphStoreConfig()
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
            doc = _read_json_file(snap)
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

    def __enter__(self) -> GraphStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ----------------------------------------------------------------------------- server config


@dataclass(frozen=True)
class GraphServerConfig:
    """Parameters of topo_graph_server_node (declared as top-level ROS parameters)."""

    storage_path: str = field(
        default="~/.ros/islands/topo_graph",
        metadata={"help": "directory holding the persisted graph (snapshot.json + changes.jsonl); "
                          "reloaded on start; empty = in memory only [path]"},
    )
    output_dir: str = field(
        default="",
        metadata={"help": "where /topo_graph/save writes graph.json, graph.geojson, "
                          "graph.graphml; empty = <storage_path>/export, or ./topo_graph_export "
                          "when in memory [path]"},
    )
    compact_every: int = field(
        default=200,
        metadata={"help": "snapshot the graph and reset the change log every N changes [changes]"},
    )
    display_frame: str = field(
        default="islands_layout",
        metadata={"help": "frame of the display layout the markers are drawn in (no metric "
                          "meaning: islands share no global frame) [frame id]"},
    )
    markers_in_island_frames: bool = field(
        default=False,
        metadata={"help": "draw each island's model in its own frame island_<id> (needs TF from "
                          "elsewhere) instead of placing it in display_frame [bool]"},
    )
