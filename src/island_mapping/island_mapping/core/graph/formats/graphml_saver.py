"""Saver of GraphML (`networkx.generate_graphml`): node attributes `frame_id`, `model_type`,
`segments` (JSON string), `origin_truth` (JSON string or empty), `exits` (JSON string: the
list of exits as in the JSON document), `r` and `built_at_s` (doubles); edge attributes
`strategy` (Table 1 string), `weight`, `length_m`, `expected_error_m` (doubles) and
`source_exit`, `target_exit` (ints, `NO_EXIT` = -1 when unknown)."""

from __future__ import annotations

import os
from pathlib import Path

import networkx as nx

from island_mapping.core.graph.formats.common import GraphView
from island_msgs_py import json_io

GRAPHML_FORMAT = "islands-graph-graphml"
NO_EXIT = -1  # GraphML has no null: an edge's unknown source/target exit


def graph_to_graphml(graph: GraphView) -> nx.DiGraph[int]:
    """A DiGraph with only GraphML-representable attributes (strings, doubles, ints)."""
    g: nx.DiGraph[int] = nx.DiGraph(format=GRAPHML_FORMAT, version=json_io.FORMAT_VERSION)
    for island in graph.islands():
        g.add_node(
            island.id,
            frame_id=island.frame_id,
            model_type=island.model_type.value,
            r=float(island.r),
            built_at_s=float(island.built_at_s),
            segments=json_io.dumps(island.model.segments.tolist()),
            origin_truth="" if island.origin_truth is None
            else json_io.dumps(json_io.pose_to_dict(island.origin_truth)),
            exits=json_io.dumps([json_io.exit_to_dict(e) for e in island.exits]),
        )
    for e in graph.edges():
        g.add_edge(
            e.source, e.target, strategy=str(e.strategy), weight=float(e.weight),
            length_m=float(e.length_m), expected_error_m=float(e.expected_error_m),
            source_exit=NO_EXIT if e.source_exit is None else int(e.source_exit),
            target_exit=NO_EXIT if e.target_exit is None else int(e.target_exit),
        )
    return g


def save_graphml(graph: GraphView, path: str | os.PathLike[str]) -> Path:
    """Write `graph_to_graphml(graph)` atomically."""
    text = "\n".join(nx.generate_graphml(graph_to_graphml(graph))) + "\n"
    return json_io.atomic_write_text(path, text)
