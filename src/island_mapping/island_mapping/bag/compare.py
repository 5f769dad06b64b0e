"""A replayed run against its recording: graphs compared island by island and edge by edge,
builder event streams compared in order (pure: numpy only; used by `islands replay` and tests).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from island_msgs_py.types import Edge, Island

from island_mapping.core.graph import TopoGraph

__all__ = ["GraphComparison", "compare_events", "compare_graphs"]


@dataclass(frozen=True)
class GraphComparison:
    """Differences between an expected and an actual graph (empty = identical)."""

    differences: tuple[str, ...]
    expected_islands: int
    actual_islands: int
    expected_edges: int
    actual_edges: int

    @property
    def identical(self) -> bool:
        return not self.differences

    def to_dict(self) -> dict[str, Any]:
        return {
            "identical": self.identical,
            "expected": {"islands": self.expected_islands, "edges": self.expected_edges},
            "actual": {"islands": self.actual_islands, "edges": self.actual_edges},
            "differences": list(self.differences),
        }


def _close(a: float, b: float, tol: float) -> bool:
    return abs(a - b) <= tol * max(1.0, abs(a), abs(b))


def _island_diffs(e: Island, a: Island, tol: float) -> list[str]:
    out: list[str] = []
    where = f"island {e.id}"
    if e.model_type != a.model_type:
        out.append(f"{where}: model type {e.model_type.value} != {a.model_type.value}")
    es, as_ = e.model.segments, a.model.segments
    if es.shape != as_.shape:
        out.append(f"{where}: {es.shape[0]} segments != {as_.shape[0]}")
    elif es.size and float(np.max(np.abs(es - as_))) > tol:
        out.append(f"{where}: segments differ by up to {float(np.max(np.abs(es - as_))):.3g} m")
    if not _close(e.r, a.r, tol):
        out.append(f"{where}: r {e.r!r} != {a.r!r}")
    if not _close(e.built_at_s, a.built_at_s, tol):
        out.append(f"{where}: built_at_s {e.built_at_s!r} != {a.built_at_s!r}")
    if e.frame_id != a.frame_id:
        out.append(f"{where}: frame {e.frame_id!r} != {a.frame_id!r}")
    if (e.origin_truth is None) != (a.origin_truth is None):
        out.append(f"{where}: origin_truth {e.origin_truth} != {a.origin_truth}")
    elif e.origin_truth is not None and a.origin_truth is not None:
        pe, pa = e.origin_truth, a.origin_truth
        if not all(_close(x, y, tol) for x, y in
                   ((pe.x, pa.x), (pe.y, pa.y), (pe.theta, pa.theta))):
            out.append(f"{where}: origin_truth {pe} != {pa}")
    return out


def _edge_diffs(e: Edge, a: Edge, tol: float) -> list[str]:
    out: list[str] = []
    where = f"edge {e.source}->{e.target}"
    if str(e.strategy) != str(a.strategy):
        out.append(f"{where}: strategy {str(e.strategy)!r} != {str(a.strategy)!r}")
    for name in ("weight", "length_m", "expected_error_m"):
        ve, va = float(getattr(e, name)), float(getattr(a, name))
        if not _close(ve, va, tol):
            out.append(f"{where}: {name} {ve!r} != {va!r}")
    return out


def compare_graphs(expected: TopoGraph, actual: TopoGraph, tol: float = 1e-9) -> GraphComparison:
    """Compare island by island (id, type, segments [m], r, time, frame, origin_truth) and edge
    by edge (source, target, strategy text, weight, length, expected error), to `tol` (absolute
    for values up to 1, relative above)."""
    if not (math.isfinite(tol) and tol >= 0):
        raise ValueError(f"compare_graphs: tol must be a finite number >= 0, got {tol}")
    diffs: list[str] = []
    e_ids, a_ids = set(expected.island_ids()), set(actual.island_ids())
    for i in sorted(e_ids - a_ids):
        diffs.append(f"island {i}: missing from the replay")
    for i in sorted(a_ids - e_ids):
        diffs.append(f"island {i}: only in the replay")
    for i in sorted(e_ids & a_ids):
        diffs.extend(_island_diffs(expected.get_island(i), actual.get_island(i), tol))
    e_edges = {(x.source, x.target): x for x in expected.edges()}
    a_edges = {(x.source, x.target): x for x in actual.edges()}
    for k in sorted(e_edges.keys() - a_edges.keys()):
        diffs.append(f"edge {k[0]}->{k[1]}: missing from the replay")
    for k in sorted(a_edges.keys() - e_edges.keys()):
        diffs.append(f"edge {k[0]}->{k[1]}: only in the replay")
    for k in sorted(e_edges.keys() & a_edges.keys()):
        diffs.extend(_edge_diffs(e_edges[k], a_edges[k], tol))
    return GraphComparison(tuple(diffs), len(expected), len(actual),
                           expected.num_edges, actual.num_edges)


def compare_events(
    recorded: list[dict[str, Any]], replayed: list[dict[str, Any]]
) -> dict[str, Any]:
    """Event streams compared in order (JSON values, so floats must be bit-identical)."""
    first = next((k for k, (a, b) in enumerate(zip(recorded, replayed, strict=False))
                  if a != b), None)
    if first is None and len(recorded) != len(replayed):
        first = min(len(recorded), len(replayed))
    out: dict[str, Any] = {
        "identical": first is None,
        "recorded": len(recorded),
        "replayed": len(replayed),
    }
    if first is not None:
        out["first_difference_index"] = first
        out["recorded_kind"] = recorded[first].get("kind") if first < len(recorded) else None
        out["replayed_kind"] = replayed[first].get("kind") if first < len(replayed) else None
    return out
