"""Loader of the Nav2 Route Server graph format written by `geojson_saver` (derived reverse
edges are skipped: they were never driven). Errors name the feature and its GeoJSON field."""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
from collections.abc import Iterator, Mapping
from typing import Any

from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.limits import MAX_EXITS_PER_ISLAND
from island_msgs_py.types import Edge, Exit, Island, IslandTypeError

from island_mapping.core.graph.formats.common import Parts, read_json_file
from island_msgs_py import json_io

# Where the fields of our island/edge JSON live in a Nav2 GeoJSON feature's properties.
_NODE_KEYS = {
    "frame_id": "frame", "model_type": "metadata.model_type", "r": "metadata.r",
    "built_at_s": "metadata.built_at_s", "origin_truth": "metadata.origin_truth",
    "model": "metadata.segments",
}
_EDGE_KEYS = {
    "source": "startid", "target": "endid", "weight": "cost", "strategy": "metadata.strategy",
    "length_m": "metadata.length_m", "expected_error_m": "metadata.expected_error_m",
    "source_exit": "metadata.source_exit", "target_exit": "metadata.target_exit",
}
_EXIT_KEY_RE = re.compile(r"^(0|[1-9][0-9]{0,9})$")  # an exit index written as an object key
SEGMENT_COLUMNS = 4  # x1, y1, x2, y2 per segment in the flat `segments` list


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
                    p += f"[{SEGMENT_COLUMNS * row}:{SEGMENT_COLUMNS * row + SEGMENT_COLUMNS}]"
                elif tail:
                    p += "." + tail
        raise GraphFormatError(p, exc.problem) from exc


def _exits(value: Any, path: str) -> tuple[Exit, ...]:
    """`metadata.exits`: an object keyed by exit index (see geojson_saver)."""
    if not isinstance(value, Mapping):
        raise GraphFormatError(path, "expected an object keyed by exit index")
    if len(value) > MAX_EXITS_PER_ISLAND:
        raise GraphFormatError(path, f"{len(value)} exits (the limit is {MAX_EXITS_PER_ISLAND})")
    out = []
    for key, item in value.items():
        if not isinstance(key, str) or not _EXIT_KEY_RE.match(key):
            raise GraphFormatError(f"{path}.{str(key)[:20]}", "an exit key must be its index")
        if not isinstance(item, Mapping):
            raise GraphFormatError(f"{path}.{key}", "expected an object")
        if "index" in item:
            raise GraphFormatError(f"{path}.{key}.index", "unknown key (the key is the index)")
        out.append(json_io.exit_from_dict({**item, "index": int(key)}, f"{path}.{key}"))
    return tuple(out)


def _island(path: str, props: Mapping[str, Any], meta: Mapping[str, Any]) -> Island:
    num = meta.get("num_segments")
    flat = meta.get("segments")
    if not isinstance(flat, list) or not isinstance(num, int) or len(flat) != 4 * num:
        raise GraphFormatError(
            f"{path}.properties.metadata.segments",
            "expected a flat list of 4 * num_segments numbers",
        )
    rows = [flat[4 * j: 4 * j + 4] for j in range(num)]
    exits = _exits(meta.get("exits", {}), f"{path}.properties.metadata.exits")
    with _geojson_paths(f"{path}.properties", _NODE_KEYS):
        island = json_io.island_from_dict({
            "id": props.get("id"),
            "frame_id": props.get("frame", ""),
            "model_type": meta.get("model_type"),
            "r": meta.get("r"),
            "built_at_s": meta.get("built_at_s"),
            "model": {"segments": rows},
            "origin_truth": meta.get("origin_truth"),
        }, f"{path}.properties")
    try:
        return dataclasses.replace(island, exits=exits)
    except IslandTypeError as exc:
        raise GraphFormatError(f"{path}.properties.metadata.exits", str(exc)) from exc


def _edge(path: str, props: Mapping[str, Any], meta: Mapping[str, Any]) -> Edge:
    with _geojson_paths(f"{path}.properties", _EDGE_KEYS):
        return json_io.edge_from_dict({
            "source": props.get("startid"),
            "target": props.get("endid"),
            "strategy": meta.get("strategy", ""),
            "weight": props.get("cost", 0.0),
            "length_m": meta.get("length_m", 0.0),
            "expected_error_m": meta.get("expected_error_m", 0.0),
            "source_exit": meta.get("source_exit"),
            "target_exit": meta.get("target_exit"),
        }, f"{path}.properties")


def _props_and_meta(path: str, feat: Any) -> tuple[Any, Mapping[str, Any], Mapping[str, Any]]:
    """(geometry type, properties, properties.metadata) of one feature, shapes checked."""
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
    return gtype, props, meta


def geojson_to_parts(doc: Any) -> Parts:
    """The islands and (driven) edges of a FeatureCollection written by `geojson_saver`."""
    if not isinstance(doc, Mapping) or doc.get("type") != "FeatureCollection":
        raise GraphFormatError("", "expected a GeoJSON FeatureCollection")
    feats = doc.get("features")
    if not isinstance(feats, list):
        raise GraphFormatError("features", "expected a list")
    islands: list[Island] = []
    edges: list[Edge] = []
    for k, feat in enumerate(feats):
        path = f"features[{k}]"
        gtype, props, meta = _props_and_meta(path, feat)
        if gtype == "Point":
            islands.append(_island(path, props, meta))
        elif gtype in ("MultiLineString", "LineString"):
            if not meta.get("derived", False):
                edges.append(_edge(path, props, meta))
        else:
            raise GraphFormatError(f"{path}.geometry.type", f"unsupported geometry {gtype!r}")
    return islands, edges


def load_geojson(path: str | os.PathLike[str]) -> Parts:
    """Read a GeoJSON graph file (see `geojson_to_parts`); errors start with the file name."""
    doc = read_json_file(path)
    try:
        return geojson_to_parts(doc)
    except GraphFormatError as exc:
        raise GraphFormatError(f"{path}: {exc.path}" if exc.path else str(path),
                               exc.problem) from exc
