"""Saver of the Nav2 Route Server graph format (a GeoJSON FeatureCollection).

Point features are islands: properties `id` (the island id), `frame` (its frame) and `metadata`
(model_type, r, built_at_s, origin_truth, and the line model as a flat list `segments`
[x1, y1, x2, y2, ...] [m] with `num_segments`, because Nav2's metadata parser takes arrays of
primitives only), and `exits`: an object keyed by the exit index (`"1": {"heading_rad": ..,
"width_m": .., "state": "explored", "edge": [3, 5]}`, `edge` only when explored; Nav2 takes
nested objects but no arrays of objects and no nulls). MultiLineString features are edges with
`id`, `startid`, `endid`, `cost` (W [m]) and `metadata` (`strategy` as Table 1 text, and
`source_exit`/`target_exit` when known). Every edge is exported in both directions: when
the graph has no edge back, a derived reverse edge (`metadata.derived = true`,
`metadata.reverse_of` = the forward feature id, strategy = `reverse_strategy`) is added, with
the same cost, leaving by the exit the forward edge entered by and entering by the one it left
by. Edge ids start after the largest island id, so ids are unique across nodes and
edges. Coordinates are the display layout (`display_layout`), not a metric frame.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from island_msgs_py.types import Edge, Exit, Island, Pose2D

from island_mapping.core.graph.formats.common import GraphView
from island_mapping.core.graph.strategy import reverse_strategy
from island_msgs_py import json_io

GEOJSON_FORMAT = "islands-graph-geojson"


def exit_metadata(e: Exit) -> dict[str, Any]:
    """One exit as Nav2 metadata (no nulls: `edge` only when explored)."""
    meta: dict[str, Any] = {"heading_rad": e.heading_rad, "width_m": e.width_m,
                            "state": e.state.value}
    if e.edge is not None:
        meta["edge"] = list(e.edge)
    if e.prefix is not None and e.side is not None:  # a side exit: its way and turn
        meta["prefix"] = str(e.prefix)
        meta["side"] = e.side.value
    return meta


def _island_feature(island: Island, p: Pose2D) -> dict[str, Any]:
    meta: dict[str, Any] = {
        "model_type": island.model_type.value,
        "r": island.r,
        "built_at_s": island.built_at_s,
        "num_segments": len(island.model),
        "segments": island.model.segments.reshape(-1).tolist(),
        "layout_theta_rad": p.theta,
        "exits": {str(e.index): exit_metadata(e) for e in island.exits},
    }
    if island.origin_truth is not None:
        meta["origin_truth"] = json_io.pose_to_dict(island.origin_truth)
    return {
        "type": "Feature",
        "geometry": {"type": "Point", "coordinates": [p.x, p.y]},
        "properties": {"id": island.id, "frame": island.frame_id, "metadata": meta},
    }


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
    for end in ("source_exit", "target_exit"):
        if getattr(edge, end) is not None:
            meta[end] = getattr(edge, end)
    return {
        "type": "Feature",
        "geometry": {"type": "MultiLineString", "coordinates": [[[a.x, a.y], [b.x, b.y]]]},
        "properties": {
            "id": fid, "startid": edge.source, "endid": edge.target,
            "cost": edge.weight, "metadata": meta,
        },
    }


def graph_to_geojson(graph: GraphView) -> dict[str, Any]:
    """The FeatureCollection of `graph` (see the module docstring)."""
    layout = graph.display_layout()
    features = [_island_feature(island, layout[island.id]) for island in graph.islands()]
    next_id = (max(graph.island_ids()) + 1) if len(graph) else 0
    for edge in graph.edges():
        fid = next_id
        next_id += 1
        features.append(_edge_feature(fid, edge, layout, derived_from=None))
        if not graph.has_edge(edge.target, edge.source):
            back = dataclasses.replace(
                edge, source=edge.target, target=edge.source,
                strategy=reverse_strategy(edge.strategy),
                source_exit=edge.target_exit, target_exit=edge.source_exit,
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


def save_geojson(graph: GraphView, path: str | os.PathLike[str]) -> Path:
    """Write `graph_to_geojson(graph)` atomically."""
    return json_io.atomic_write_text(path, json_io.dumps(graph_to_geojson(graph), indent=1) + "\n")
