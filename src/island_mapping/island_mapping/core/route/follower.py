"""Following a route of islands by the map (paper section 8.2), as a motion generator.

1. localize at the source island (look around, localize from guesses around the estimate) and
   dock on its origin (0, 0, 0);
2. execute the edge's strategy: `Go d` follows the hallway for d of odometric travel, `Rot a`
   turns in place by a;
3. localize in the next island starting from the estimate (0, 0, 0) (the strategy ends at the
   target origin), dock, and repeat from 2.

Whoever runs the generator decides after each arrival whether the route goes on
(`RouteObserver.arrived`): the explorer goes on when the arrival's localization is trusted,
the simulated evaluation when it is also right by the simulator's truth.
"""

from __future__ import annotations

import itertools
from collections.abc import Generator, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import Protocol

from island_msgs_py.types import Edge, Island, Pose2D

from island_mapping.core.route.arrival import Fix, localize_and_dock
from island_mapping.core.route.config import NavigateError
from island_mapping.core.route.motion import (
    Command,
    Drive,
    RouteDeviationError,
    RouteTimeoutError,
    execute_strategy,
)


class RouteEnd(StrEnum):
    """How a followed route ended."""

    COMPLETED = "completed"
    ARRIVAL_REFUSED = "arrival_refused"  # the observer did not go on after an arrival
    TIMED_OUT = "timed_out"  # a leg ran out of time (looking, or driving)
    DEVIATED = "deviated"  # a Go step ended well short: a wall where the recorded way went on


class RouteObserver(Protocol):
    """Sees every arrival of a route and decides whether the route goes on."""

    def fixed(self, fix: Fix) -> None:
        """The arrival's localization is known (before docking)."""

    def arrived(self, edge: Edge | None, fix: Fix) -> bool:
        """Docked after `edge` (None: at the source); True = go on with the route."""


class TrustedArrivals:
    """Goes on while every arrival's localization is trusted (what a robot without truth does)."""

    def fixed(self, fix: Fix) -> None:
        del fix

    def arrived(self, edge: Edge | None, fix: Fix) -> bool:
        del edge
        return fix.trusted


@dataclass(frozen=True)
class RouteOutcome:
    """How a followed route ended: every edge followed and accepted, and where it stopped."""

    completed: bool
    edges_followed: int
    timed_out: bool
    last_fix: Fix | None
    end: RouteEnd = RouteEnd.COMPLETED


def route_edges(edges_by_pair: dict[tuple[int, int], Edge], route: Sequence[int]) -> list[Edge]:
    """The edges joining consecutive islands of `route`, or a NavigateError naming the gap."""
    if len(route) < 1:
        raise NavigateError("route: needs at least one island")
    out = []
    for a, b in itertools.pairwise(route):
        edge = edges_by_pair.get((a, b))
        if edge is None:
            raise NavigateError(f"route: no edge {a}->{b} in the graph")
        out.append(edge)
    return out


def follow_route(
    d: Drive,
    islands: dict[int, Island],
    edges: Sequence[Edge],
    source: int,
    observer: RouteObserver,
) -> Generator[Command, None, RouteOutcome]:
    """Follow `edges` (consecutive, starting at island `source`) by island localization.

    Each leg (the source's arrival, then every edge with its arrival) has
    `cfg.max_edge_time_s` of time; a leg that runs out ends the route (timed_out)."""
    c = d.cfg
    followed = 0
    last: Fix | None = None
    try:
        d.deadline_s = d.sense.t_s + c.max_edge_time_s
        last = yield from localize_and_dock(d, islands[source], Pose2D(0.0, 0.0, 0.0),
                                            observer.fixed)
        if not observer.arrived(None, last):
            return RouteOutcome(False, 0, False, last, RouteEnd.ARRIVAL_REFUSED)
        for e in edges:
            d.deadline_s = d.sense.t_s + c.max_edge_time_s
            yield from execute_strategy(d, e.strategy)
            last = yield from localize_and_dock(d, islands[e.target], Pose2D(0.0, 0.0, 0.0),
                                                observer.fixed)
            followed += 1
            if not observer.arrived(e, last):
                return RouteOutcome(False, followed, False, last, RouteEnd.ARRIVAL_REFUSED)
    except RouteDeviationError:
        return RouteOutcome(False, followed, True, last, RouteEnd.DEVIATED)
    except RouteTimeoutError:
        return RouteOutcome(False, followed, True, last, RouteEnd.TIMED_OUT)
    return RouteOutcome(True, followed, False, last)
