"""Exits of islands and how they agree with the edges (the data model; no exploration here).

An exit is a direction, in its island's frame, in which free space leads away (`Exit`); it is
`unexplored`, `explored` by one edge that touches its island, or `blocked`. An edge may say
by which exit it leaves its source (`source_exit`) and enters its target (`target_exit`).
What must hold in a graph, and what these functions check or keep:
- an explored exit's edge is in the graph (it touches the island by construction of `Island`);
- an edge's `source_exit`/`target_exit` names an exit of its source/target island;
- removing an edge sets the exits it explored back to `unexplored` (the map no longer knows
  where they lead), so a removal never leaves the graph inconsistent.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Collection, Iterable

from island_msgs_py.types import Edge, ExitState, ExitUpdate, Island, IslandTypeError, NewExit

from island_mapping.core.graph.errors import GraphError

HasEdge = Callable[[int, int], bool]


def check_explored_edges(island: Island, has_edge: HasEdge) -> None:
    """Every explored exit of `island` names an edge of the graph."""
    for e in island.exits:
        if e.edge is not None and not has_edge(*e.edge):
            raise GraphError(
                f"island {island.id}: exit {e.index} explored by edge {e.edge[0]}->{e.edge[1]}, "
                "which is not in the graph")


def check_edge_exits(edge: Edge, source: Island, target: Island) -> None:
    """`edge.source_exit`/`target_exit` name exits of its source/target island."""
    for end, island in (("source_exit", source), ("target_exit", target)):
        index = getattr(edge, end)
        if index is not None and all(e.index != index for e in island.exits):
            raise GraphError(
                f"edge {edge.source}->{edge.target}: {end} {index}: island {island.id} has no "
                f"exit {index}")


def check_kept_exits(island: Island, touching: Iterable[Edge]) -> None:
    """A replacement `island` keeps every exit that the edges touching it name."""
    indices = {e.index for e in island.exits}
    for edge in touching:
        for end, island_id in (("source_exit", edge.source), ("target_exit", edge.target)):
            index = getattr(edge, end)
            if island_id == island.id and index is not None and index not in indices:
                raise GraphError(
                    f"island {island.id}: exit {index} is named by edge "
                    f"{edge.source}->{edge.target} ({end}) and cannot be dropped")


def with_exit_update(island: Island, update: ExitUpdate, has_edge: HasEdge) -> Island:
    """`island` with exit `update.index` set to the new state and edge (validated)."""
    where = f"island {island.id}: exit {update.index}"
    found = [e for e in island.exits if e.index == update.index]
    if not found:
        known = [e.index for e in island.exits]
        raise GraphError(f"{where}: no such exit (the island has exits {known})")
    try:
        new = dataclasses.replace(found[0], state=update.state, edge=update.edge)
        changed = dataclasses.replace(
            island, exits=tuple(new if e.index == update.index else e for e in island.exits))
    except IslandTypeError as exc:
        raise GraphError(f"{where}: {exc}") from exc
    check_explored_edges(changed, has_edge)
    return changed


def with_new_exit(island: Island, item: NewExit, has_edge: HasEdge) -> Island:
    """`island` with the exit `item.exit` added (its index must be free; validated)."""
    where = f"new exit {item.exit.index} of island {island.id}"
    if any(e.index == item.exit.index for e in island.exits):
        raise GraphError(f"{where}: the island already has exit {item.exit.index}")
    try:
        changed = dataclasses.replace(island, exits=(*island.exits, item.exit))
    except IslandTypeError as exc:
        raise GraphError(f"{where}: {exc}") from exc
    check_explored_edges(changed, has_edge)
    return changed


def reset_exits(island: Island, removed: Collection[tuple[int, int]]) -> Island | None:
    """`island` with the exits explored by a removed edge set back to unexplored; None when no
    exit of it was explored by one of them."""
    if not any(e.edge in removed for e in island.exits):
        return None
    exits = tuple(
        dataclasses.replace(e, state=ExitState.UNEXPLORED, edge=None) if e.edge in removed
        else e for e in island.exits
    )
    return dataclasses.replace(island, exits=exits)


def exit_state_counts(islands: Iterable[Island]) -> dict[str, int]:
    """How many exits of the islands are in each state (every state listed, 0 included)."""
    counts = {s.value: 0 for s in ExitState}
    for island in islands:
        for e in island.exits:
            counts[e.state.value] += 1
    return counts
