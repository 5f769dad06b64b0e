"""The global topological map M = {V, E} (paper eq. 1) held in a networkx DiGraph (no rclpy).

A node is an `Island` (its line model L in its own frame, the model type T that accepted it); a
directed edge is an `Edge` (the control strategy S from the source island's origin to the target
island's origin, and the weight W [m] used for planning). There is at most one edge per ordered
pair of islands. Every mutating method validates its request first and raises `GraphError`
without changing anything when it is rejected. Islands' exits and the edges agree at all times
(`exits.py`): an explored exit names an edge of the graph, an edge's source/target exit names an
exit of its island, and removing an edge sets the exits it explored back to unexplored.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from enum import StrEnum
from pathlib import Path
from typing import Any

import networkx as nx
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import Edge, ExitState, ExitUpdate, Island, NewExit, Pose2D

from island_mapping.core.graph import exits, formats
from island_mapping.core.graph.errors import GraphError
from island_mapping.core.graph.layout import DEFAULT_MARGIN_M, display_layout
from island_mapping.core.graph.planning import Backend, Route, RoutePlanner
from island_mapping.core.graph.validate import checked_edge_fields, checked_island
from island_msgs_py import json_io


class PutMode(StrEnum):
    """What a put request may do: only add, only replace, or either."""

    ADD = "add"
    REPLACE = "replace"
    PUT = "put"


class TopoGraph:
    """M = {V, E}: islands keyed by id, at most one directed edge per ordered pair of islands."""

    def __init__(self) -> None:
        self._g: nx.DiGraph = nx.DiGraph()
        self._version = 0  # bumped on every change; invalidates the planning caches
        self._planner = RoutePlanner()
        self._frames: dict[str, int] = {}  # frame id -> island id
        self._weights: dict[tuple[int, int], float] = {}  # (source, target) -> W, for the CSR

    # --- construction / inspection -----------------------------------------------------------

    @classmethod
    def from_parts(cls, islands: Iterable[Island], edges: Iterable[Edge]) -> TopoGraph:
        """A graph of these islands and edges, validated as a whole (an explored exit may name
        an edge that comes later in `edges`)."""
        g = cls()
        listed = list(islands)
        for island in listed:
            g._store_island(g._checked_island(island, PutMode.ADD, explored_edges=False))
        for edge in edges:
            g.add_edge(edge)
        for island in listed:
            exits.check_explored_edges(island, g.has_edge)
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

    def check_island(self, island: Island, mode: str = PutMode.PUT) -> Island:
        """Validate an 'add', 'replace' or either ('put'); returns the copy to store."""
        return self._checked_island(island, mode, explored_edges=True)

    def _checked_island(self, island: Island, mode: str, explored_edges: bool) -> Island:
        checked = checked_island(island)
        exists = checked.id in self._g
        if mode == PutMode.ADD and exists:
            raise GraphError(f"island {checked.id} already exists (use replace)")
        if mode == PutMode.REPLACE and not exists:
            raise GraphError(f"cannot replace unknown island {checked.id}")
        owner = self._frames.get(checked.frame_id)
        if owner is not None and owner != checked.id:
            raise GraphError(
                f"island {checked.id}: frame {checked.frame_id!r} already used by island {owner}"
            )
        if explored_edges:
            exits.check_explored_edges(checked, self.has_edge)
        if exists:
            exits.check_kept_exits(checked, self._touching(checked.id))
        return checked

    def _touching(self, island_id: int) -> list[Edge]:
        return [d["edge"] for _, _, d in self._g.in_edges(island_id, data=True)] + [
            d["edge"] for _, _, d in self._g.out_edges(island_id, data=True)]

    def check_edge(self, edge: Edge, mode: str = PutMode.PUT) -> Edge:
        """Validate an edge add/replace/put request (ids known, no self-edge, finite weights)."""
        checked_edge_fields(edge)
        name = f"edge {edge.source}->{edge.target}"
        for end in ("source", "target"):
            if getattr(edge, end) not in self._g:
                raise GraphError(f"{name}: unknown {end} island {getattr(edge, end)}")
        exists = self._g.has_edge(edge.source, edge.target)
        if mode == PutMode.ADD and exists:
            raise GraphError(f"{name} already exists (use replace)")
        if mode == PutMode.REPLACE and not exists:
            raise GraphError(f"cannot replace unknown {name}")
        if edge.source_exit is not None or edge.target_exit is not None:
            exits.check_edge_exits(edge, self.get_island(edge.source),
                                   self.get_island(edge.target))
        return edge

    def check_exit_update(self, update: ExitUpdate) -> Island:
        """Validate a change of one exit's state; returns the island to store."""
        if not isinstance(update, ExitUpdate):
            raise GraphError(f"expected an ExitUpdate, got {type(update).__name__}")
        if update.island not in self._g:
            raise GraphError(f"exit update: unknown island {update.island}")
        return exits.with_exit_update(self.get_island(update.island), update, self.has_edge)

    def check_new_exit(self, item: NewExit) -> Island:
        """Validate an exit added to an existing island; returns the island to store."""
        if not isinstance(item, NewExit):
            raise GraphError(f"expected a NewExit, got {type(item).__name__}")
        if item.island not in self._g:
            raise GraphError(f"new exit: unknown island {item.island}")
        return exits.with_new_exit(self.get_island(item.island), item, self.has_edge)

    def exits_reset_by(
        self, removed: Iterable[tuple[int, int]], dropped: int | None = None
    ) -> list[Island]:
        """The islands whose exits a removal of the edges `removed` sets back to unexplored, as
        they will be stored (not the island `dropped`, which goes too)."""
        pairs = set(removed)
        ids = sorted({i for pair in pairs for i in pair if i != dropped and i in self._g})
        changed = [exits.reset_exits(self.get_island(i), pairs) for i in ids]
        return [i for i in changed if i is not None]

    # --- changes -------------------------------------------------------------------------------

    def _changed(self) -> None:
        self._version += 1
        self._planner.changed()

    def _store_island(self, island: Island) -> None:
        if island.id in self._g:
            del self._frames[self._g.nodes[island.id]["island"].frame_id]
        self._g.add_node(island.id, island=island)
        self._frames[island.frame_id] = island.id
        self._changed()

    def _store_edge(self, edge: Edge) -> None:
        self._g.add_edge(edge.source, edge.target, edge=edge, weight=float(edge.weight))
        self._weights[edge.source, edge.target] = float(edge.weight)
        self._changed()

    def add_island(self, island: Island) -> None:
        self._store_island(self.check_island(island, PutMode.ADD))

    def replace_island(self, island: Island) -> None:
        self._store_island(self.check_island(island, PutMode.REPLACE))

    def put_island(self, island: Island) -> bool:
        """Add or replace; True when an existing island was replaced."""
        checked = self.check_island(island, PutMode.PUT)
        replaced = checked.id in self._g
        self._store_island(checked)
        return replaced

    def add_edge(self, edge: Edge) -> None:
        self._store_edge(self.check_edge(edge, PutMode.ADD))

    def replace_edge(self, edge: Edge) -> None:
        self._store_edge(self.check_edge(edge, PutMode.REPLACE))

    def put_edge(self, edge: Edge) -> bool:
        """Add or replace; True when an existing edge was replaced."""
        self.check_edge(edge, PutMode.PUT)
        replaced = self._g.has_edge(edge.source, edge.target)
        self._store_edge(edge)
        return replaced

    def set_exit(
        self,
        island_id: int,
        index: int,
        state: ExitState,
        edge: tuple[int, int] | None = None,
    ) -> Island:
        """Set exit `index` of island `island_id` to `state` (explored: by the edge
        (source, target), which must exist and touch the island); returns the changed island."""
        return self.apply_exit_update(ExitUpdate(island_id, index, state, edge))

    def apply_exit_update(self, update: ExitUpdate) -> Island:
        """`set_exit` from an ExitUpdate; returns the changed island."""
        island = self.check_exit_update(update)
        self._store_island(island)
        return island

    def add_exit(self, item: NewExit) -> Island:
        """Add exit `item.exit` to island `item.island` (a side opening); returns the island."""
        island = self.check_new_exit(item)
        self._store_island(island)
        return island

    def remove_island(self, island_id: int) -> list[Edge]:
        """Remove an island and its edges (exits they explored on other islands go back to
        unexplored); returns the removed edges."""
        if island_id not in self._g:
            raise GraphError(f"cannot remove unknown island {island_id}")
        removed = self._touching(island_id)
        reset = self.exits_reset_by(((e.source, e.target) for e in removed), dropped=island_id)
        for e in removed:
            del self._weights[e.source, e.target]
        del self._frames[self._g.nodes[island_id]["island"].frame_id]
        self._g.remove_node(island_id)
        for island in reset:
            self._g.nodes[island.id]["island"] = island
        self._changed()
        return removed

    def remove_edge(self, source: int, target: int) -> Edge:
        """Remove an edge (exits it explored go back to unexplored); returns it."""
        edge = self.get_edge(source, target)
        reset = self.exits_reset_by([(source, target)])
        self._g.remove_edge(source, target)
        del self._weights[source, target]
        for island in reset:
            self._g.nodes[island.id]["island"] = island
        self._changed()
        return edge

    # --- planning and layout -------------------------------------------------------------------

    def plan_route(self, source: int, target: int, backend: str = Backend.AUTO) -> Route:
        """Least-weight directed route (Dijkstra on W [m]).

        backend: "auto" (networkx below SCIPY_MIN_ISLANDS islands, else scipy), "networkx", or
        "scipy". Raises GraphError for unknown islands and NoRouteError when unreachable.
        """
        return self._planner.plan(self._g, self._weights, self._version, source, target, backend)

    def clear_planning_cache(self) -> None:
        """Forget the CSR matrix and the cached shortest-path trees (as a change would)."""
        self._planner.clear()

    def display_layout(self, margin_m: float = DEFAULT_MARGIN_M) -> dict[int, Pose2D]:
        """A pose per island for DISPLAY only (see `layout.display_layout`)."""
        return display_layout(self._g, margin_m)

    # --- formats -------------------------------------------------------------------------------

    def to_dict(self) -> dict[str, Any]:
        return json_io.graph_to_dict(self.islands(), self.edges())

    def to_json(self, indent: int | None = None) -> str:
        return json_io.graph_to_json(self.islands(), self.edges(), indent=indent)

    @classmethod
    def from_dict(cls, doc: Any) -> TopoGraph:
        return cls.from_parts(*json_io.graph_from_dict(doc))

    @classmethod
    def from_json(cls, text: str | bytes) -> TopoGraph:
        return cls.from_parts(*json_io.graph_from_json(text))

    @classmethod
    def _from_file_parts(cls, parts: formats.Parts, where: str) -> TopoGraph:
        try:
            return cls.from_parts(*parts)
        except GraphError as exc:
            raise GraphFormatError(where, str(exc)) from exc

    def save_json(self, path: str | os.PathLike[str]) -> Path:
        return formats.save_json(self, path)

    @classmethod
    def load_json(cls, path: str | os.PathLike[str]) -> TopoGraph:
        return cls._from_file_parts(formats.load_json(path), str(path))

    def to_geojson(self) -> dict[str, Any]:
        """The Nav2 Route Server graph format (see `formats.geojson_saver`)."""
        return formats.graph_to_geojson(self)

    @classmethod
    def from_geojson(cls, doc: Any) -> TopoGraph:
        """Import a GeoJSON written by `to_geojson` (derived reverse edges are skipped)."""
        return cls._from_file_parts(formats.geojson_to_parts(doc), "features")

    def save_geojson(self, path: str | os.PathLike[str]) -> Path:
        return formats.save_geojson(self, path)

    @classmethod
    def load_geojson(cls, path: str | os.PathLike[str]) -> TopoGraph:
        return cls._from_file_parts(formats.load_geojson(path), str(path))

    def to_graphml_graph(self) -> nx.DiGraph:
        """A DiGraph with only GraphML-representable attributes (strings and doubles)."""
        return formats.graph_to_graphml(self)

    def save_graphml(self, path: str | os.PathLike[str]) -> Path:
        return formats.save_graphml(self, path)

    @classmethod
    def load_graphml(cls, path: str | os.PathLike[str]) -> TopoGraph:
        return cls._from_file_parts(formats.load_graphml(path), str(path))

    def save_all(self, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
        """Write graph.json, graph.geojson and graph.graphml into `out_dir` (atomically each)."""
        return formats.save_all(self, out_dir)

    @classmethod
    def load_any(cls, path: str | os.PathLike[str]) -> TopoGraph:
        """Load by extension: .json (graph document), .geojson, .graphml."""
        return cls._from_file_parts(formats.load_any(path), str(path))

    def save_any(self, path: str | os.PathLike[str]) -> Path:
        return formats.save_any(self, path)
