"""Checks of one island or edge on its own (fields, bounds); the graph checks how they fit.

The bounds are those of `island_msgs_py.limits`, the same the file loaders apply, so whatever
the graph accepts it can write and read back (a server restarts on its own store).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from island_msgs_py.limits import (
    MAX_COORD_M,
    MAX_EXIT_INDEX,
    MAX_FRAME_ID_CHARS,
    MAX_ISLAND_ID,
    MAX_LENGTH_M,
    MAX_SEGMENTS_PER_ISLAND,
    MAX_STRATEGY_STEPS,
)
from island_msgs_py.types import Edge, Island, IslandTypeError, LineModel, ModelType, Pose2D

from island_mapping.core.graph.errors import GraphError


def _is_int(value: object) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _checked_segments(island: Island) -> np.ndarray:
    segs = np.array(island.model.segments, dtype=np.float64, copy=True)
    if segs.size and (segs.ndim != 2 or segs.shape[1] != 4):
        raise GraphError(f"island {island.id}: segments must be (N, 4), got {segs.shape}")
    segs = segs.reshape(-1, 4)
    if len(segs) > MAX_SEGMENTS_PER_ISLAND:
        raise GraphError(f"island {island.id}: {len(segs)} segments (the limit is "
                         f"{MAX_SEGMENTS_PER_ISLAND})")
    if segs.size and not float(np.abs(segs).max()) <= MAX_COORD_M:  # NaN fails this too
        finite = np.isfinite(segs)
        if not finite.all():
            bad = int(np.argwhere(~finite)[0][0])
            raise GraphError(f"island {island.id}: segment {bad} has a NaN or infinite "
                             "coordinate")
        bad = int(np.argwhere(np.abs(segs) > MAX_COORD_M)[0][0])
        raise GraphError(f"island {island.id}: segment {bad} has a coordinate beyond "
                         f"{MAX_COORD_M:g} m (the limit)")
    return segs


def _check_origin(island: Island) -> None:
    o = island.origin_truth
    if o is None:
        return
    if not isinstance(o, Pose2D):
        raise GraphError(f"island {island.id}: origin_truth must be a Pose2D or None")
    if not all(math.isfinite(v) for v in (o.x, o.y, o.theta)) or max(abs(o.x), abs(o.y)) > \
            MAX_COORD_M:
        raise GraphError(f"island {island.id}: origin_truth must be finite with |x|, |y| <= "
                         f"{MAX_COORD_M:g} m (the limit)")


def checked_island(island: Island) -> Island:
    """Re-validate an island (arrays are mutable, frozen fields can be forced) and return a copy
    with a read-only model; GraphError naming the island, the field and the limit."""
    if not isinstance(island, Island):
        raise GraphError(f"expected an Island, got {type(island).__name__}")
    if not _is_int(island.id) or not 0 <= island.id <= MAX_ISLAND_ID:
        raise GraphError(f"island id must be an integer in [0, {MAX_ISLAND_ID}], "
                         f"got {island.id!r}")
    segs = _checked_segments(island)
    for name in ("r", "built_at_s"):
        if not math.isfinite(float(getattr(island, name))):
            raise GraphError(f"island {island.id}: {name} is not finite")
    if not isinstance(island.model_type, ModelType):
        raise GraphError(f"island {island.id}: unknown model type {island.model_type!r}")
    if not isinstance(island.frame_id, str) or len(island.frame_id) > MAX_FRAME_ID_CHARS:
        raise GraphError(f"island {island.id}: frame_id must be a string of at most "
                         f"{MAX_FRAME_ID_CHARS} characters")
    _check_origin(island)
    segs.setflags(write=False)
    model = LineModel(segs)
    model.segments.setflags(write=False)
    try:  # the constructor checks the exits again (indices, states, edges touching the island)
        return dataclasses.replace(island, id=int(island.id), model=model)
    except IslandTypeError as exc:
        raise GraphError(str(exc)) from exc


def checked_edge_fields(edge: Edge) -> Edge:
    """An edge's own fields: an Edge, ids in range, not a self-edge, finite non-negative
    weights within MAX_LENGTH_M, at most MAX_STRATEGY_STEPS strategy steps."""
    if not isinstance(edge, Edge):
        raise GraphError(f"expected an Edge, got {type(edge).__name__}")
    name = f"edge {edge.source}->{edge.target}"
    for end, v in (("source", edge.source), ("target", edge.target)):
        if not _is_int(v) or not 0 <= v <= MAX_ISLAND_ID:
            raise GraphError(f"{name}: {end} must be an island id in [0, {MAX_ISLAND_ID}]")
    if edge.source == edge.target:
        raise GraphError(f"{name}: an edge from an island to itself")
    for attr, w in (("weight", edge.weight), ("length_m", edge.length_m),
                    ("expected_error_m", edge.expected_error_m)):
        if not 0.0 <= w <= MAX_LENGTH_M:  # NaN fails this too
            if not math.isfinite(w) or w < 0:
                raise GraphError(f"{name}: {attr} must be finite and >= 0, got {float(w)}")
            raise GraphError(f"{name}: {attr} is {w:g} m, beyond {MAX_LENGTH_M:g} m (the limit)")
    if len(edge.strategy.steps) > MAX_STRATEGY_STEPS:
        raise GraphError(f"{name}: {len(edge.strategy.steps)} strategy steps (the limit is "
                         f"{MAX_STRATEGY_STEPS})")
    for end, x in (("source_exit", edge.source_exit), ("target_exit", edge.target_exit)):
        if x is not None and (not _is_int(x) or not 0 <= x <= MAX_EXIT_INDEX):
            raise GraphError(f"{name}: {end} must be an exit index in [0, {MAX_EXIT_INDEX}] "
                             f"or None, got {x!r}")
    return edge
