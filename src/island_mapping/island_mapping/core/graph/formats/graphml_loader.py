"""Loader of GraphML written by `graphml_saver` (errors name the file, the node or edge, and
the attribute)."""

from __future__ import annotations

import os

import networkx as nx
from island_msgs_py.json_io import GraphFormatError

from island_mapping.core.graph.formats.common import Parts, json_attr
from island_msgs_py import json_io


def load_graphml(path: str | os.PathLike[str]) -> Parts:
    """The islands and edges of a GraphML file."""
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
            "model": {"segments": json_attr(d.get("segments", "[]"), f"{np_}.segments")},
            "origin_truth": json_attr(origin, f"{np_}.origin_truth") if origin else None,
        }, np_))
    edges = [
        json_io.edge_from_dict({
            "source": u, "target": v, "strategy": d.get("strategy", ""),
            "weight": d.get("weight"), "length_m": d.get("length_m", 0.0),
            "expected_error_m": d.get("expected_error_m", 0.0),
        }, f"{path}: edge {u}->{v}")
        for u, v, d in g.edges(data=True)
    ]
    return islands, edges
