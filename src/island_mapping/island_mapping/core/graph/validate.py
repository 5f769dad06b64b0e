"""Checks of one island or edge on its own (fields, bounds); the graph checks how they fit."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from island_msgs_py.types import Edge, Island, LineModel, ModelType

from island_mapping.core.graph.errors import GraphError


def checked_island(island: Island) -> Island:
    """Re-validate an island (arrays are mutable) and return a copy with a read-only model."""
    if not isinstance(island, Island):
        raise GraphError(f"expected an Island, got {type(island).__name__}")
    if isinstance(island.id, bool) or not isinstance(island.id, int | np.integer) or island.id < 0:
        raise GraphError(f"island id must be an integer >= 0, got {island.id!r}")
    segs = np.array(island.model.segments, dtype=np.float64, copy=True)
    if segs.size and (segs.ndim != 2 or segs.shape[1] != 4):
        raise GraphError(f"island {island.id}: segments must be (N, 4), got {segs.shape}")
    if not np.all(np.isfinite(segs)):
        bad = int(np.argwhere(~np.isfinite(segs.reshape(-1, 4)))[0][0])
        raise GraphError(f"island {island.id}: segment {bad} has a NaN or infinite coordinate")
    for name in ("r", "built_at_s"):
        if not math.isfinite(float(getattr(island, name))):
            raise GraphError(f"island {island.id}: {name} is not finite")
    if not isinstance(island.model_type, ModelType):
        raise GraphError(f"island {island.id}: unknown model type {island.model_type!r}")
    segs.setflags(write=False)
    model = LineModel(segs)
    model.segments.setflags(write=False)
    return dataclasses.replace(island, id=int(island.id), model=model)


def checked_edge_fields(edge: Edge) -> Edge:
    """An edge's own fields: an Edge, not a self-edge, finite non-negative weights."""
    if not isinstance(edge, Edge):
        raise GraphError(f"expected an Edge, got {type(edge).__name__}")
    name = f"edge {edge.source}->{edge.target}"
    if edge.source == edge.target:
        raise GraphError(f"{name}: an edge from an island to itself")
    for attr in ("weight", "length_m", "expected_error_m"):
        v = float(getattr(edge, attr))
        if not math.isfinite(v) or v < 0:
            raise GraphError(f"{name}: {attr} must be finite and >= 0, got {v}")
    return edge
