"""Versioned JSON forms of islands, edges, exits and the whole map M = {V, E} (numpy only, no ROS).

Graph document (format "islands-graph", version 2; version 1, without exits, is still read)::

    {"format": "islands-graph", "version": 2,
     "islands": [{"id": 0, "frame_id": "island_0", "model_type": "line", "r": 0.71,
                  "built_at_s": 12.5, "model": {"segments": [[x1, y1, x2, y2], ...]},
                  "origin_truth": null | {"x": .., "y": .., "theta": ..},
                  "exits": [{"index": 0, "heading_rad": 1.57, "width_m": 1.2,
                             "state": "unexplored" | "explored" | "blocked",
                             "edge": null | [source, target],
                             "prefix": "Go 540", "side": "left" | "right"}, ...]}, ...],
     "edges": [{"source": 0, "target": 1, "strategy": "Go 125, Rot 270, Go 652",
                "weight": 8.1, "length_m": 7.77, "expected_error_m": 0.33,
                "source_exit": null | 0, "target_exit": null | 2}, ...]}

`exits`, `source_exit` and `target_exit` are optional and written only when set, so a map
without exits reads and writes as in version 1 (but for the version number). An exit's
`prefix` and `side` (a side exit: an opening beside an edge, reached from the island's origin
by the strategy `prefix`, then a turn to `side`) are written only for a side exit; an exit
without them is a plain exit at the island's origin (files written before side exits load as
they did).

An exit added to an island (an item of the graph server's `/topo_graph/add`, `new_exit`)::

    {"island": 3, "exit": {"index": 4, "heading_rad": 1.57, "width_m": 1.2,
                           "state": "unexplored", "edge": null, "prefix": "Go 540",
                           "side": "left"}}

An exit change (an item of the graph server's `/topo_graph/add`)::

    {"island": 3, "exit": 1, "state": "explored", "edge": [3, 5]}

Units: segments and poses in metres (theta and headings in radians) in the island's own frame;
`built_at_s` in seconds; the strategy in the paper's Table 1 units (Go in cm, Rot in degrees
CCW); weights, lengths, errors and widths in metres.

Loading validates everything and raises `GraphFormatError` whose message starts with the path of
the bad field, e.g. ``islands[3].model.segments[2]: NaN``. Unknown keys are rejected (they are
most often typos). Bounds (`island_msgs_py.limits`): ids, coordinates, lengths, list lengths,
nesting depth, integer literal length and text size; a value outside one is an error naming the
field and the bound. Files are written atomically: a temporary file in the same directory,
flushed and fsynced, then `os.replace`, then the directory is fsynced.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from enum import StrEnum
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from island_msgs_py import json_checks as jc
from island_msgs_py.json_checks import GraphFormatError as GraphFormatError
from island_msgs_py.json_checks import json_depth as json_depth
from island_msgs_py.json_checks import loads as loads
from island_msgs_py.json_checks import read_json_file as read_json_file
from island_msgs_py.limits import (
    MAX_COORD_M,
    MAX_EXIT_INDEX,
    MAX_EXITS_PER_ISLAND,
    MAX_ITEM_JSON_BYTES,
    MAX_SEGMENTS_PER_ISLAND,
)
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitSide,
    ExitState,
    ExitUpdate,
    Island,
    IslandTypeError,
    LineModel,
    ModelType,
    NewExit,
    Pose2D,
)

FORMAT_NAME = "islands-graph"
FORMAT_VERSION = 2
SUPPORTED_VERSIONS = (1, 2)  # versions this module can read
EXITS_SINCE_VERSION = 2  # islands' `exits` and edges' `source_exit`/`target_exit`
FILE_MODE = 0o644  # permissions of written files (rw owner, readable by all)

_ISLAND_KEYS_V1 = {"id", "frame_id", "model_type", "r", "built_at_s", "model", "origin_truth"}
_ISLAND_KEYS = _ISLAND_KEYS_V1 | {"exits"}
_ISLAND_REQUIRED = {"id", "model_type", "r", "built_at_s", "model"}
_EDGE_KEYS_V1 = {"source", "target", "strategy", "weight", "length_m", "expected_error_m"}
_EDGE_KEYS = _EDGE_KEYS_V1 | {"source_exit", "target_exit"}
_EDGE_REQUIRED = {"source", "target", "strategy", "weight"}
_EXIT_KEYS = {"index", "heading_rad", "width_m", "state", "edge", "prefix", "side"}
_EXIT_REQUIRED = {"index", "heading_rad", "width_m", "state"}
_EXIT_UPDATE_KEYS = {"island", "exit", "state", "edge"}
_EXIT_UPDATE_REQUIRED = {"island", "exit", "state"}
_GRAPH_KEYS = {"format", "version", "islands", "edges"}


# ----------------------------------------------------------------------------- poses


def pose_to_dict(pose: Pose2D) -> dict[str, float]:
    """{"x": m, "y": m, "theta": rad}."""
    return {"x": pose.x, "y": pose.y, "theta": pose.theta}


def pose_from_dict(d: Any, path: str = "pose") -> Pose2D:
    """A pose; |x|, |y| <= MAX_COORD_M [m], theta finite [rad]."""
    obj = jc.obj(d, path, {"x", "y", "theta"}, {"x", "y", "theta"})
    return Pose2D(
        jc.float_(obj["x"], f"{path}.x", bound=MAX_COORD_M),
        jc.float_(obj["y"], f"{path}.y", bound=MAX_COORD_M),
        jc.float_(obj["theta"], f"{path}.theta"),
    )


# ----------------------------------------------------------------------------- islands


def segments_from_json(value: Any, path: str) -> np.ndarray:
    """A list of [x1, y1, x2, y2] rows [m] -> (N, 4) float64 array, each coordinate checked
    (finite, |v| <= MAX_COORD_M), at most MAX_SEGMENTS_PER_ISLAND rows."""
    rows = jc.list_(value, path, MAX_SEGMENTS_PER_ISLAND)
    out = np.zeros((len(rows), 4), dtype=np.float64)
    for i, row in enumerate(rows):
        rp = f"{path}[{i}]"
        vals = jc.list_(row, rp)
        if len(vals) != 4:
            raise GraphFormatError(rp, f"expected 4 numbers (x1, y1, x2, y2), got {len(vals)}")
        for j, v in enumerate(vals):
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise GraphFormatError(rp, f"coordinate {j} is not a number: {jc.describe(v)}")
            try:
                f = float(v)
            except OverflowError:
                raise GraphFormatError(rp, f"coordinate {j} is out of range") from None
            if not math.isfinite(f):
                raise GraphFormatError(rp, f"{jc.describe(f)} at coordinate {j}")
            if abs(f) > MAX_COORD_M:
                raise GraphFormatError(
                    rp, f"coordinate {j} is {f:g}: |value| must be <= {MAX_COORD_M:g} m")
            out[i, j] = f
    return out


_E = TypeVar("_E", bound=StrEnum)


def _enum(cls: type[_E], value: Any, path: str, what: str) -> _E:
    """The member of string enum `cls` named by `value`; a GraphFormatError naming `what`
    and the known values otherwise."""
    text = jc.str_(value, path)
    try:
        return cls(text)
    except ValueError:
        known = ", ".join(m.value for m in cls)
        raise GraphFormatError(path, f"unknown {what} {text!r} (known: {known})") from None


def exit_to_dict(e: Exit) -> dict[str, Any]:
    d: dict[str, Any] = {
        "index": e.index,
        "heading_rad": e.heading_rad,
        "width_m": e.width_m,
        "state": e.state.value,
        "edge": None if e.edge is None else list(e.edge),
    }
    if e.prefix is not None and e.side is not None:
        d["prefix"] = str(e.prefix)
        d["side"] = e.side.value
    return d


def side_fields(obj: Mapping[str, Any], path: str
                ) -> tuple[ControlStrategy | None, ExitSide | None]:
    """A side exit's `prefix` (a strategy, `Go 540, Rot 90, Go 120`) and `side`; both absent:
    a plain exit (None, None)."""
    if "prefix" not in obj and "side" not in obj:
        return None, None
    if "prefix" not in obj or "side" not in obj:
        missing = "prefix" if "prefix" not in obj else "side"
        raise GraphFormatError(f"{path}.{missing}", "a side exit needs both prefix and side")
    try:
        prefix = ControlStrategy.parse(jc.str_(obj["prefix"], f"{path}.prefix"))
    except IslandTypeError as exc:
        raise GraphFormatError(f"{path}.prefix", f"not a strategy: {exc}") from exc
    return prefix, _enum(ExitSide, obj["side"], f"{path}.side", "side")


def _edge_ref(value: Any, path: str) -> tuple[int, int] | None:
    if value is None:
        return None
    pair = jc.list_(value, path)
    if len(pair) != 2:
        raise GraphFormatError(path, f"expected [source, target], got {len(pair)} values")
    return jc.island_id(pair[0], f"{path}[0]"), jc.island_id(pair[1], f"{path}[1]")


def exit_from_dict(d: Any, path: str = "exit") -> Exit:
    obj = jc.obj(d, path, _EXIT_KEYS, _EXIT_REQUIRED)
    heading = jc.float_(obj["heading_rad"], f"{path}.heading_rad")
    if not -math.pi <= heading <= math.pi:
        raise GraphFormatError(f"{path}.heading_rad", f"must be in [-pi, pi], got {heading}")
    width = jc.length(obj["width_m"], f"{path}.width_m")
    if width <= 0.0:
        raise GraphFormatError(f"{path}.width_m", f"must be > 0, got {width}")
    state = _enum(ExitState, obj["state"], f"{path}.state", "exit state")
    edge = _edge_ref(obj.get("edge"), f"{path}.edge")
    prefix, side = side_fields(obj, path)
    try:
        return Exit(jc.int_(obj["index"], f"{path}.index", 0, MAX_EXIT_INDEX), heading, width,
                    state, edge, prefix, side)
    except IslandTypeError as exc:
        raise GraphFormatError(path, str(exc)) from exc


def _exits_from_json(value: Any, path: str, island_id: int) -> tuple[Exit, ...]:
    exits: list[Exit] = []
    seen: dict[int, int] = {}
    for k, item in enumerate(jc.list_(value, path, MAX_EXITS_PER_ISLAND)):
        e = exit_from_dict(item, f"{path}[{k}]")
        if e.index in seen:
            raise GraphFormatError(
                f"{path}[{k}].index", f"duplicate exit index {e.index} (also at [{seen[e.index]}])")
        if e.edge is not None and island_id not in e.edge:
            raise GraphFormatError(
                f"{path}[{k}].edge",
                f"edge {e.edge[0]}->{e.edge[1]} does not touch island {island_id}")
        seen[e.index] = k
        exits.append(e)
    return tuple(exits)


def island_to_dict(island: Island) -> dict[str, Any]:
    """The island's JSON object; `exits` only when it has some (an island without exits is
    written as version 1 wrote it, so recorded streams of islands compare equal)."""
    d = {
        "id": island.id,
        "frame_id": island.frame_id,
        "model_type": island.model_type.value,
        "r": island.r,
        "built_at_s": island.built_at_s,
        "model": {"segments": island.model.segments.tolist()},
        "origin_truth": None if island.origin_truth is None else pose_to_dict(island.origin_truth),
    }
    if island.exits:
        d["exits"] = [exit_to_dict(e) for e in island.exits]
    return d


def island_from_dict(d: Any, path: str = "island", version: int = FORMAT_VERSION) -> Island:
    """An island of a document of `version` (version 1 has no `exits`)."""
    keys = _ISLAND_KEYS if version >= EXITS_SINCE_VERSION else _ISLAND_KEYS_V1
    obj = jc.obj(d, path, keys, _ISLAND_REQUIRED)
    island_id = jc.island_id(obj["id"], f"{path}.id")
    frame_id = jc.str_(obj.get("frame_id", ""), f"{path}.frame_id")
    model_type = _enum(ModelType, obj["model_type"], f"{path}.model_type", "model type")
    model = jc.obj(obj["model"], f"{path}.model", {"segments"}, {"segments"})
    segments = segments_from_json(model["segments"], f"{path}.model.segments")
    origin = obj.get("origin_truth")
    origin_truth = None if origin is None else pose_from_dict(origin, f"{path}.origin_truth")
    exits = _exits_from_json(obj.get("exits", []), f"{path}.exits", island_id)
    try:
        return Island(
            id=island_id,
            model=LineModel(segments),
            model_type=model_type,
            r=jc.float_(obj["r"], f"{path}.r"),
            built_at_s=jc.float_(obj["built_at_s"], f"{path}.built_at_s"),
            frame_id=frame_id,
            origin_truth=origin_truth,
            exits=exits,
        )
    except IslandTypeError as exc:  # pragma: no cover - every field was checked above
        raise GraphFormatError(path, str(exc)) from exc


# ----------------------------------------------------------------------------- edges


def edge_to_dict(edge: Edge) -> dict[str, Any]:
    """The edge's JSON object; `source_exit`/`target_exit` only when known."""
    d: dict[str, Any] = {
        "source": edge.source,
        "target": edge.target,
        "strategy": str(edge.strategy),
        "weight": edge.weight,
        "length_m": edge.length_m,
        "expected_error_m": edge.expected_error_m,
    }
    for end in ("source_exit", "target_exit"):
        if getattr(edge, end) is not None:
            d[end] = getattr(edge, end)
    return d


def _exit_index(value: Any, path: str) -> int | None:
    return None if value is None else jc.int_(value, path, 0, MAX_EXIT_INDEX)


def edge_from_dict(d: Any, path: str = "edge", version: int = FORMAT_VERSION) -> Edge:
    """An edge of a document of `version` (version 1 has no `source_exit`/`target_exit`)."""
    keys = _EDGE_KEYS if version >= EXITS_SINCE_VERSION else _EDGE_KEYS_V1
    obj = jc.obj(d, path, keys, _EDGE_REQUIRED)
    source = jc.island_id(obj["source"], f"{path}.source")
    target = jc.island_id(obj["target"], f"{path}.target")
    if source == target:
        raise GraphFormatError(path, f"an edge from island {source} to itself")
    text = jc.str_(obj["strategy"], f"{path}.strategy")
    try:
        strategy = ControlStrategy.parse(text)
    except IslandTypeError as exc:
        raise GraphFormatError(f"{path}.strategy", str(exc)) from exc
    return Edge(
        source=source,
        target=target,
        strategy=strategy,
        weight=jc.length(obj["weight"], f"{path}.weight"),
        length_m=jc.length(obj.get("length_m", 0.0), f"{path}.length_m"),
        expected_error_m=jc.length(obj.get("expected_error_m", 0.0), f"{path}.expected_error_m"),
        source_exit=_exit_index(obj.get("source_exit"), f"{path}.source_exit"),
        target_exit=_exit_index(obj.get("target_exit"), f"{path}.target_exit"),
    )


# ----------------------------------------------------------------------------- exit updates


def exit_update_to_dict(update: ExitUpdate) -> dict[str, Any]:
    return {
        "island": update.island,
        "exit": update.index,
        "state": update.state.value,
        "edge": None if update.edge is None else list(update.edge),
    }


def exit_update_from_dict(d: Any, path: str = "exit") -> ExitUpdate:
    obj = jc.obj(d, path, _EXIT_UPDATE_KEYS, _EXIT_UPDATE_REQUIRED)
    island = jc.island_id(obj["island"], f"{path}.island")
    index = jc.int_(obj["exit"], f"{path}.exit", 0, MAX_EXIT_INDEX)
    state = _enum(ExitState, obj["state"], f"{path}.state", "exit state")
    edge = _edge_ref(obj.get("edge"), f"{path}.edge")
    try:
        return ExitUpdate(island, index, state, edge)
    except IslandTypeError as exc:
        raise GraphFormatError(path, str(exc)) from exc


_NEW_EXIT_KEYS = {"island", "exit"}


def new_exit_to_dict(item: NewExit) -> dict[str, Any]:
    return {"island": item.island, "exit": exit_to_dict(item.exit)}


def new_exit_from_dict(d: Any, path: str = "new_exit") -> NewExit:
    obj = jc.obj(d, path, _NEW_EXIT_KEYS, _NEW_EXIT_KEYS)
    island = jc.island_id(obj["island"], f"{path}.island")
    ex = exit_from_dict(obj["exit"], f"{path}.exit")
    if ex.edge is not None and island not in ex.edge:
        raise GraphFormatError(f"{path}.exit.edge",
                               f"edge {ex.edge[0]}->{ex.edge[1]} does not touch island {island}")
    return NewExit(island, ex)


def new_exit_to_json(item: NewExit) -> str:
    return dumps(new_exit_to_dict(item))


def new_exit_from_json(text: str | bytes, path: str = "new_exit") -> NewExit:
    return new_exit_from_dict(loads(text, path, MAX_ITEM_JSON_BYTES), path)


# ----------------------------------------------------------------------------- whole graph


def graph_to_dict(islands: Iterable[Island], edges: Iterable[Edge]) -> dict[str, Any]:
    """The versioned graph document; islands sorted by id, edges by (source, target)."""
    return {
        "format": FORMAT_NAME,
        "version": FORMAT_VERSION,
        "islands": [island_to_dict(i) for i in sorted(islands, key=lambda i: i.id)],
        "edges": [edge_to_dict(e) for e in sorted(edges, key=lambda e: (e.source, e.target))],
    }


def _version(d: Mapping[str, Any], p: Any) -> int:
    if d.get("format") != FORMAT_NAME:
        raise GraphFormatError(p("format"), f"expected {FORMAT_NAME!r}, got {d.get('format')!r}")
    version = d.get("version")
    if isinstance(version, bool) or version not in SUPPORTED_VERSIONS:
        raise GraphFormatError(
            p("version"),
            f"unsupported version {jc.describe(version)} "
            f"(this build reads {list(SUPPORTED_VERSIONS)})",
        )
    return int(version)


def check_exit_references(
    islands: Sequence[Island], edges: Sequence[Edge], path: str = ""
) -> None:
    """Exits and edges agree: an explored exit's edge is in the graph, and an edge's
    source_exit/target_exit names an exit of its source/target island."""
    p = (lambda k: f"{path}.{k}") if path else (lambda k: k)
    pairs = {(e.source, e.target) for e in edges}
    exits_of = {i.id: {e.index for e in i.exits} for i in islands}
    for k, island in enumerate(islands):
        for j, ex in enumerate(island.exits):
            if ex.edge is not None and ex.edge not in pairs:
                raise GraphFormatError(
                    f"{p('islands')}[{k}].exits[{j}].edge",
                    f"exit {ex.index} of island {island.id} explored by edge "
                    f"{ex.edge[0]}->{ex.edge[1]}, which is not in the graph")
    for k, edge in enumerate(edges):
        for end, island_id in (("source_exit", edge.source), ("target_exit", edge.target)):
            index = getattr(edge, end)
            if index is not None and index not in exits_of.get(island_id, set()):
                raise GraphFormatError(
                    f"{p('edges')}[{k}].{end}", f"island {island_id} has no exit {index}")


def graph_from_dict(d: Any, path: str = "") -> tuple[list[Island], list[Edge]]:
    """Validate a graph document: fields, unique island ids, edges between known islands,
    at most one edge per ordered pair, exits that agree with the edges."""
    p = (lambda k: f"{path}.{k}") if path else (lambda k: k)
    if not isinstance(d, Mapping):
        raise GraphFormatError(path, f"expected a JSON object, got {type(d).__name__}")
    version = _version(d, p)
    obj = jc.obj(d, path, _GRAPH_KEYS, _GRAPH_KEYS)
    islands: list[Island] = []
    seen: dict[int, int] = {}
    for k, item in enumerate(jc.list_(obj["islands"], p("islands"))):
        island = island_from_dict(item, f"{p('islands')}[{k}]", version)
        if island.id in seen:
            raise GraphFormatError(
                f"{p('islands')}[{k}].id",
                f"duplicate island id {island.id} (also at [{seen[island.id]}])",
            )
        seen[island.id] = k
        islands.append(island)
    edges: list[Edge] = []
    pairs: set[tuple[int, int]] = set()
    for k, item in enumerate(jc.list_(obj["edges"], p("edges"))):
        ep = f"{p('edges')}[{k}]"
        edge = edge_from_dict(item, ep, version)
        for end in ("source", "target"):
            if getattr(edge, end) not in seen:
                raise GraphFormatError(f"{ep}.{end}", f"unknown island {getattr(edge, end)}")
        if (edge.source, edge.target) in pairs:
            raise GraphFormatError(ep, f"duplicate edge {edge.source}->{edge.target}")
        pairs.add((edge.source, edge.target))
        edges.append(edge)
    check_exit_references(islands, edges, path)
    return islands, edges


def dumps(obj: Any, indent: int | None = None) -> str:
    """Strict JSON text (no NaN/Infinity tokens)."""
    return json.dumps(obj, indent=indent, allow_nan=False)


def island_to_json(island: Island) -> str:
    return dumps(island_to_dict(island))


def island_from_json(text: str | bytes, path: str = "island") -> Island:
    return island_from_dict(loads(text, path, MAX_ITEM_JSON_BYTES), path)


def edge_to_json(edge: Edge) -> str:
    return dumps(edge_to_dict(edge))


def edge_from_json(text: str | bytes, path: str = "edge") -> Edge:
    return edge_from_dict(loads(text, path, MAX_ITEM_JSON_BYTES), path)


def exit_update_to_json(update: ExitUpdate) -> str:
    return dumps(exit_update_to_dict(update))


def exit_update_from_json(text: str | bytes, path: str = "exit") -> ExitUpdate:
    return exit_update_from_dict(loads(text, path, MAX_ITEM_JSON_BYTES), path)


def graph_to_json(
    islands: Iterable[Island], edges: Iterable[Edge], indent: int | None = None
) -> str:
    return dumps(graph_to_dict(islands, edges), indent=indent)


def graph_from_json(text: str | bytes) -> tuple[list[Island], list[Edge]]:
    return graph_from_dict(loads(text, ""))


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
    doc = read_json_file(p)
    try:
        return graph_from_dict(doc)
    except GraphFormatError as exc:
        raise GraphFormatError(f"{p}: {exc.path}" if exc.path else str(p), exc.problem) from exc
