"""Loader of GraphML written by `graphml_saver` (errors name the file, the node or edge, and
the attribute). The file size is bounded (`MAX_GRAPH_FILE_BYTES`), node ids are parsed here
(at most `MAX_JSON_INT_DIGITS` digits, within the island id range), the JSON attributes within
the JSON limits; expat refuses entity-expansion bombs."""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import networkx as nx
from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.limits import MAX_GRAPH_FILE_BYTES, MAX_ISLAND_ID, MAX_JSON_INT_DIGITS
from island_msgs_py.types import Edge, Island

from island_mapping.core.graph.formats.common import Parts, json_attr
from island_mapping.core.graph.formats.graphml_saver import NO_EXIT
from island_msgs_py import json_io

_ID_RE = re.compile(rf"^[0-9]{{1,{MAX_JSON_INT_DIGITS}}}$")


def _read(path: str | os.PathLike[str]) -> nx.Graph[str]:
    try:
        size = Path(path).stat().st_size
    except OSError as exc:
        raise GraphFormatError(str(path), f"cannot read: {exc.strerror or exc}") from exc
    if size > MAX_GRAPH_FILE_BYTES:
        raise GraphFormatError(str(path), f"{size} bytes (the limit is {MAX_GRAPH_FILE_BYTES})")
    try:
        g: nx.Graph[str] = nx.read_graphml(os.fspath(path), node_type=str)
    except (OSError, ValueError, nx.NetworkXError) as exc:
        raise GraphFormatError(str(path), f"cannot read GraphML: {exc}") from exc
    except Exception as exc:  # xml.etree ParseError and friends
        raise GraphFormatError(str(path), f"not GraphML: {exc}") from exc
    return g


def _node_id(text: str, path: str) -> int:
    if not _ID_RE.match(text) or int(text) > MAX_ISLAND_ID:
        raise GraphFormatError(
            f"{path}: node {text[:24]!r}", f"the node id must be an island id in "
            f"[0, {MAX_ISLAND_ID}]")
    return int(text)


def _exit_index(value: Any) -> Any:
    """GraphML's NO_EXIT means none; anything else goes to the JSON validation as it is."""
    return None if value is None or value == NO_EXIT else value


def _island(n: int, d: Mapping[str, Any], where: str) -> Island:
    origin = d.get("origin_truth", "")
    return json_io.island_from_dict({
        "id": n,
        "frame_id": d.get("frame_id", ""),
        "model_type": d.get("model_type"),
        "r": d.get("r"),
        "built_at_s": d.get("built_at_s"),
        "model": {"segments": json_attr(d.get("segments", "[]"), f"{where}.segments")},
        "origin_truth": json_attr(origin, f"{where}.origin_truth") if origin else None,
        "exits": json_attr(d.get("exits", "[]"), f"{where}.exits"),
    }, where)


def _edge(u: int, v: int, d: Mapping[str, Any], where: str) -> Edge:
    return json_io.edge_from_dict({
        "source": u, "target": v, "strategy": d.get("strategy", ""),
        "weight": d.get("weight"), "length_m": d.get("length_m", 0.0),
        "expected_error_m": d.get("expected_error_m", 0.0),
        "source_exit": _exit_index(d.get("source_exit")),
        "target_exit": _exit_index(d.get("target_exit")),
    }, where)


def load_graphml(path: str | os.PathLike[str]) -> Parts:
    """The islands and edges of a GraphML file."""
    g = _read(path)
    ids = {n: _node_id(n, str(path)) for n in g.nodes}
    islands = [_island(ids[n], d, f"{path}: node {ids[n]}") for n, d in g.nodes(data=True)]
    edges = [_edge(ids[u], ids[v], d, f"{path}: edge {ids[u]}->{ids[v]}")
             for u, v, d in g.edges(data=True)]
    return islands, edges
