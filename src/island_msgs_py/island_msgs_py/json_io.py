"""Versioned JSON forms of islands, edges and the whole map M = {V, E} (numpy only, no ROS).

Graph document (format "islands-graph", version 1)::

    {"format": "islands-graph", "version": 1,
     "islands": [{"id": 0, "frame_id": "island_0", "model_type": "line", "r": 0.71,
                  "built_at_s": 12.5, "model": {"segments": [[x1, y1, x2, y2], ...]},
                  "origin_truth": null | {"x": .., "y": .., "theta": ..}}, ...],
     "edges": [{"source": 0, "target": 1, "strategy": "Go 125, Rot 270, Go 652",
                "weight": 8.1, "length_m": 7.77, "expected_error_m": 0.33}, ...]}

Units: segments and poses in metres (theta in radians) in the island's own frame; `built_at_s`
in seconds; the strategy in the paper's Table 1 units (Go in cm, Rot in degrees CCW); weights,
lengths and errors in metres.

Loading validates everything and raises `GraphFormatError` whose message starts with the path of
the bad field, e.g. ``islands[3].model.segments[2]: NaN``. Unknown keys are rejected (they are
most often typos). Files are written atomically: a temporary file in the same directory,
flushed and fsynced, then `os.replace`, then the directory is fsynced.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Island,
    IslandTypeError,
    LineModel,
    ModelType,
    Pose2D,
)

FORMAT_NAME = "islands-graph"
FORMAT_VERSION = 1
SUPPORTED_VERSIONS = (1,)  # versions this module can read
FILE_MODE = 0o644  # permissions of written files (rw owner, readable by all)

_ISLAND_KEYS = {"id", "frame_id", "model_type", "r", "built_at_s", "model", "origin_truth"}
_ISLAND_REQUIRED = {"id", "model_type", "r", "built_at_s", "model"}
_EDGE_KEYS = {"source", "target", "strategy", "weight", "length_m", "expected_error_m"}
_EDGE_REQUIRED = {"source", "target", "strategy", "weight"}
_GRAPH_KEYS = {"format", "version", "islands", "edges"}


class GraphFormatError(ValueError):
    """A JSON document is not a valid island/edge/graph; the message starts with the field path."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"{path}: {problem}" if path else problem)
        self.path = path
        self.problem = problem


# ----------------------------------------------------------------------------- validation helpers


def _describe(value: Any) -> str:
    if isinstance(value, float) and math.isnan(value):
        return "NaN"
    if isinstance(value, float) and math.isinf(value):
        return "infinite value"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _obj(value: Any, path: str, keys: set[str], required: set[str]) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise GraphFormatError(path, f"expected an object, got {type(value).__name__}")
    unknown = sorted(set(value) - keys)
    if unknown:
        raise GraphFormatError(f"{path}.{unknown[0]}", "unknown key")
    missing = sorted(required - set(value))
    if missing:
        raise GraphFormatError(f"{path}.{missing[0]}", "missing")
    return value


def _int(value: Any, path: str, minimum: int | None = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise GraphFormatError(path, f"expected an integer, got {_describe(value)}")
    if minimum is not None and value < minimum:
        raise GraphFormatError(path, f"must be >= {minimum}, got {value}")
    return int(value)


def _float(value: Any, path: str, minimum: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise GraphFormatError(path, f"expected a number, got {_describe(value)}")
    f = float(value)
    if not math.isfinite(f):
        raise GraphFormatError(path, _describe(f))
    if minimum is not None and f < minimum:
        raise GraphFormatError(path, f"must be >= {minimum}, got {f}")
    return f


def _str(value: Any, path: str) -> str:
    if not isinstance(value, str):
        raise GraphFormatError(path, f"expected a string, got {_describe(value)}")
    return value


def _list(value: Any, path: str) -> Sequence[Any]:
    if not isinstance(value, list | tuple):
        raise GraphFormatError(path, f"expected a list, got {type(value).__name__}")
    return value


# ----------------------------------------------------------------------------- poses


def pose_to_dict(pose: Pose2D) -> dict[str, float]:
    """{"x": m, "y": m, "theta": rad}."""
    return {"x": pose.x, "y": pose.y, "theta": pose.theta}


def pose_from_dict(d: Any, path: str = "pose") -> Pose2D:
    obj = _obj(d, path, {"x", "y", "theta"}, {"x", "y", "theta"})
    return Pose2D(
        _float(obj["x"], f"{path}.x"), _float(obj["y"], f"{path}.y"),
        _float(obj["theta"], f"{path}.theta"),
    )


# ----------------------------------------------------------------------------- islands


def segments_from_json(value: Any, path: str) -> np.ndarray:
    """A list of [x1, y1, x2, y2] rows [m] -> (N, 4) float64 array, each coordinate checked."""
    rows = _list(value, path)
    out = np.zeros((len(rows), 4), dtype=np.float64)
    for i, row in enumerate(rows):
        rp = f"{path}[{i}]"
        vals = _list(row, rp)
        if len(vals) != 4:
            raise GraphFormatError(rp, f"expected 4 numbers (x1, y1, x2, y2), got {len(vals)}")
        for j, v in enumerate(vals):
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise GraphFormatError(rp, f"coordinate {j} is not a number: {_describe(v)}")
            if not math.isfinite(float(v)):
                raise GraphFormatError(rp, f"{_describe(float(v))} at coordinate {j}")
            out[i, j] = float(v)
    return out


def island_to_dict(island: Island) -> dict[str, Any]:
    return {
        "id": island.id,
        "frame_id": island.frame_id,
        "model_type": island.model_type.value,
        "r": island.r,
        "built_at_s": island.built_at_s,
        "model": {"segments": island.model.segments.tolist()},
        "origin_truth": None if island.origin_truth is None else pose_to_dict(island.origin_truth),
    }


def island_from_dict(d: Any, path: str = "island") -> Island:
    obj = _obj(d, path, _ISLAND_KEYS, _ISLAND_REQUIRED)
    island_id = _int(obj["id"], f"{path}.id")
    frame_id = _str(obj.get("frame_id", ""), f"{path}.frame_id")
    mt = _str(obj["model_type"], f"{path}.model_type")
    try:
        model_type = ModelType(mt)
    except ValueError:
        known = ", ".join(m.value for m in ModelType)
        raise GraphFormatError(
            f"{path}.model_type", f"unknown model type {mt!r} (known: {known})"
        ) from None
    model = _obj(obj["model"], f"{path}.model", {"segments"}, {"segments"})
    segments = segments_from_json(model["segments"], f"{path}.model.segments")
    origin = obj.get("origin_truth")
    origin_truth = None if origin is None else pose_from_dict(origin, f"{path}.origin_truth")
    try:
        return Island(
            id=island_id,
            model=LineModel(segments),
            model_type=model_type,
            r=_float(obj["r"], f"{path}.r"),
            built_at_s=_float(obj["built_at_s"], f"{path}.built_at_s"),
            frame_id=frame_id,
            origin_truth=origin_truth,
        )
    except IslandTypeError as exc:  # pragma: no cover - every field was checked above
        raise GraphFormatError(path, str(exc)) from exc


# ----------------------------------------------------------------------------- edges


def edge_to_dict(edge: Edge) -> dict[str, Any]:
    return {
        "source": edge.source,
        "target": edge.target,
        "strategy": str(edge.strategy),
        "weight": edge.weight,
        "length_m": edge.length_m,
        "expected_error_m": edge.expected_error_m,
    }


def edge_from_dict(d: Any, path: str = "edge") -> Edge:
    obj = _obj(d, path, _EDGE_KEYS, _EDGE_REQUIRED)
    source = _int(obj["source"], f"{path}.source")
    target = _int(obj["target"], f"{path}.target")
    if source == target:
        raise GraphFormatError(path, f"an edge from island {source} to itself")
    text = _str(obj["strategy"], f"{path}.strategy")
    try:
        strategy = ControlStrategy.parse(text)
    except IslandTypeError as exc:
        raise GraphFormatError(f"{path}.strategy", str(exc)) from exc
    return Edge(
        source=source,
        target=target,
        strategy=strategy,
        weight=_float(obj["weight"], f"{path}.weight", minimum=0.0),
        length_m=_float(obj.get("length_m", 0.0), f"{path}.length_m", minimum=0.0),
        expected_error_m=_float(
            obj.get("expected_error_m", 0.0), f"{path}.expected_error_m", minimum=0.0
        ),
    )


# ----------------------------------------------------------------------------- whole graph


def graph_to_dict(islands: Iterable[Island], edges: Iterable[Edge]) -> dict[str, Any]:
    """The versioned graph document; islands sorted by id, edges by (source, target)."""
    return {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "islands": [island_to_dict(i) for i in sorted(islands, key=lambda i: i.id)],
        "edges": [edge_to_dict(e) for e in sorted(edges, key=lambda e: (e.source, e.target))],
    }


def graph_from_dict(d: Any, path: str = "") -> tuple[list[Island], list[Edge]]:
    """Validate a graph document: fields, unique island ids, edges between known islands,
    at most one edge per ordered pair."""
    p = (lambda k: f"{path}.{k}") if path else (lambda k: k)
    if not isinstance(d, Mapping):
        raise GraphFormatError(path, f"expected a JSON object, got {type(d).__name__}")
    if d.get("format") != FORMAT_NAME:
        raise GraphFormatError(p("format"), f"expected {FORMAT_NAME!r}, got {d.get('format')!r}")
    version = d.get("version")
    if isinstance(version, bool) or version not in SUPPORTED_VERSIONS:
        raise GraphFormatError(
            p("version"),
            f"unsupported version {version!r} (this build reads {list(SUPPORTED_VERSIONS)})",
        )
    obj = _obj(d, path, _GRAPH_KEYS, _GRAPH_KEYS)
    islands: list[Island] = []
    seen: dict[int, int] = {}
    for k, item in enumerate(_list(obj["islands"], p("islands"))):
        island = island_from_dict(item, f"{p('islands')}[{k}]")
        if island.id in seen:
            raise GraphFormatError(
                f"{p('islands')}[{k}].id",
                f"duplicate island id {island.id} (also at [{seen[island.id]}])",
            )
        seen[island.id] = k
        islands.append(island)
    edges: list[Edge] = []
    pairs: set[tuple[int, int]] = set()
    for k, item in enumerate(_list(obj["edges"], p("edges"))):
        ep = f"{p('edges')}[{k}]"
        edge = edge_from_dict(item, ep)
        for end in ("source", "target"):
            if getattr(edge, end) not in seen:
                raise GraphFormatError(f"{ep}.{end}", f"unknown island {getattr(edge, end)}")
        if (edge.source, edge.target) in pairs:
            raise GraphFormatError(ep, f"duplicate edge {edge.source}->{edge.target}")
        pairs.add((edge.source, edge.target))
        edges.append(edge)
    return islands, edges


def _loads(text: str | bytes, path: str) -> Any:
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise GraphFormatError(path, f"not valid JSON: {exc}") from exc


def dumps(obj: Any, indent: int | None = None) -> str:
    """Strict JSON text (no NaN/Infinity tokens)."""
    return json.dumps(obj, indent=indent, allow_nan=False)


def island_to_json(island: Island) -> str:
    return dumps(island_to_dict(island))


def island_from_json(text: str | bytes, path: str = "island") -> Island:
    return island_from_dict(_loads(text, path), path)


def edge_to_json(edge: Edge) -> str:
    return dumps(edge_to_dict(edge))


def edge_from_json(text: str | bytes, path: str = "edge") -> Edge:
    return edge_from_dict(_loads(text, path), path)


def graph_to_json(
    islands: Iterable[Island], edges: Iterable[Edge], indent: int | None = None
) -> str:
    return dumps(graph_to_dict(islands, edges), indent=indent)


def graph_from_json(text: str | bytes) -> tuple[list[Island], list[Edge]]:
    return graph_from_dict(_loads(text, ""))


# ----------------------------------------------------------------------------- files


def fsync_dir(directory: str | os.PathLike[str]) -> None:
    """fsync a directory so a rename inside it survives a power cut (no-op where unsupported)."""
    try:
        fd = os.open(os.fspath(directory), os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write `text` to `path` atomically: temp file in the same dir, fsync, replace, fsync dir."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        os.fchmod(fd, FILE_MODE)  # mkstemp creates 0600; results are meant to be shared
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    fsync_dir(target.parent)
    return target


def save_graph_json(
    path: str | os.PathLike[str], islands: Iterable[Island], edges: Iterable[Edge]
) -> Path:
    """Write the graph document atomically (indented for reading and diffing)."""
    return atomic_write_text(path, graph_to_json(islands, edges, indent=1) + "\n")


def load_graph_json(path: str | os.PathLike[str]) -> tuple[list[Island], list[Edge]]:
    """Read and validate a graph document; errors name the file and the bad field."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise GraphFormatError(str(p), f"cannot read: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise GraphFormatError(str(p), f"not UTF-8 text: {exc}") from exc
    try:
        return graph_from_json(text)
    except GraphFormatError as exc:
        raise GraphFormatError(f"{p}: {exc.path}" if exc.path else str(p), exc.problem) from exc
