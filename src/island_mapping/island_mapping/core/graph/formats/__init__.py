"""Graph file formats, a loader and a saver per format (as Nav2's route server splits them).

Public API:
- `GraphFormat`, `format_of(path)`: the format of a file by its extension;
- `load_any(path) -> Parts`, `save_any(graph, path)`, `save_all(graph, out_dir)`;
- per format: `load_json`/`save_json` (the project's `islands-graph` document),
  `geojson_to_parts`/`load_geojson` and `graph_to_geojson`/`save_geojson` (Nav2 Route Server
  GeoJSON), `load_graphml` and `graph_to_graphml`/`save_graphml`.

Loaders return `Parts` (islands and edges, each validated); `GraphView.load_*` builds the graph.
Savers write atomically.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from enum import StrEnum
from pathlib import Path

from island_msgs_py.json_io import GraphFormatError

from island_mapping.core.graph.formats.common import GraphView, Parts
from island_mapping.core.graph.formats.geojson_loader import geojson_to_parts, load_geojson
from island_mapping.core.graph.formats.geojson_saver import (
    GEOJSON_FORMAT,
    graph_to_geojson,
    save_geojson,
)
from island_mapping.core.graph.formats.graphml_loader import load_graphml
from island_mapping.core.graph.formats.graphml_saver import (
    GRAPHML_FORMAT,
    graph_to_graphml,
    save_graphml,
)
from island_mapping.core.graph.formats.json_loader import load_json
from island_mapping.core.graph.formats.json_saver import save_json

__all__ = [
    "GEOJSON_FORMAT",
    "GRAPHML_FORMAT",
    "GraphFormat",
    "Parts",
    "format_of",
    "geojson_to_parts",
    "graph_to_geojson",
    "graph_to_graphml",
    "load_any",
    "load_geojson",
    "load_graphml",
    "load_json",
    "save_all",
    "save_any",
    "save_geojson",
    "save_graphml",
    "save_json",
]


class GraphFormat(StrEnum):
    """A graph file format, named by its file extension."""

    JSON = ".json"
    GEOJSON = ".geojson"
    GRAPHML = ".graphml"


_LOADERS: dict[GraphFormat, Callable[[str | os.PathLike[str]], Parts]] = {
    GraphFormat.JSON: load_json,
    GraphFormat.GEOJSON: load_geojson,
    GraphFormat.GRAPHML: load_graphml,
}
_SAVERS: dict[GraphFormat, Callable[[GraphView, str | os.PathLike[str]], Path]] = {
    GraphFormat.JSON: save_json,
    GraphFormat.GEOJSON: save_geojson,
    GraphFormat.GRAPHML: save_graphml,
}
EXPORT_NAMES = {"json": "graph.json", "geojson": "graph.geojson", "graphml": "graph.graphml"}


def format_of(path: str | os.PathLike[str]) -> GraphFormat:
    """The format of `path` by its extension; GraphFormatError for an unknown one."""
    suffix = Path(path).suffix.lower()
    try:
        return GraphFormat(suffix)
    except ValueError:
        known = ", ".join(f.value for f in GraphFormat)
        raise GraphFormatError(
            str(path), f"unknown graph file extension {suffix!r} ({known})"
        ) from None


def load_any(path: str | os.PathLike[str]) -> Parts:
    """Load by extension: .json (graph document), .geojson, .graphml."""
    return _LOADERS[format_of(path)](path)


def save_any(graph: GraphView, path: str | os.PathLike[str]) -> Path:
    """Save by extension: .json, .geojson, .graphml."""
    return _SAVERS[format_of(path)](graph, path)


def save_all(graph: GraphView, out_dir: str | os.PathLike[str]) -> dict[str, Path]:
    """Write graph.json, graph.geojson and graph.graphml into `out_dir` (atomically each)."""
    d = Path(out_dir)
    return {key: save_any(graph, d / name) for key, name in EXPORT_NAMES.items()}
