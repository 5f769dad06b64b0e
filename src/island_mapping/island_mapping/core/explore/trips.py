"""How a trip the explorer handed over ends (`core.explore.mission`): at an island the
builder built or recognised (the exit explored, openings passed become side exits), or at a
decision the builder holds because its star fits look-alike islands (`core.builder.held`):
the explorer rehearses each hypothesis (`rehearse`) and confirms the first whose neighbour is
found, or rejects them all, and then settles at the island the builder builds.

`TripEnds` is a base of `Explorer`; what it uses of the mission is declared here.
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass

from island_msgs_py.types import Edge, Exit, ExitUpdate, Island, NewExit, Pose2D

from island_mapping.core.builder import BuilderEvent, EventKind
from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.explore.departure import STOP
from island_mapping.core.explore.openings import OpeningWatch, noted_side_exits, side_trip_end
from island_mapping.core.explore.rehearse import rehearse
from island_mapping.core.explore.requests import Confirm, ExplorerState, Reject, Request
from island_mapping.core.graph import TopoGraph
from island_mapping.core.route import (
    Command,
    Drive,
    Fix,
    NavigateConfig,
    RouteTimeoutError,
    Sense,
    localize_and_dock,
)

Step = Command | None
"""What the mission yields per scan: a command the explorer answers with, or None: the
builder side (the builder's own driving or the hall follower) answers."""


@dataclass(frozen=True)
class Here:
    """Docked at island_id, whose origin is at origin_odom (odometry frame)."""

    island_id: int
    origin_odom: Pose2D


class TripEnds:
    """The ends of a trip (module docstring); the mission sets these attributes."""

    cfg: ExplorerConfig
    nav: NavigateConfig
    graph: TopoGraph
    state: ExplorerState
    counts: dict[str, int]
    _drive: Drive | None
    _events: list[BuilderEvent]
    _requests: list[Request]
    _awaited: list[ExitUpdate]
    _blocked: set[tuple[int, int]]
    _side_sent: dict[int, list[Exit]]

    @property
    def _sense(self) -> Sense:
        assert self._drive is not None
        return self._drive.sense

    def _fixed(self, fix: Fix) -> None:
        raise NotImplementedError  # the mission's

    def _dock(self, island_id: int, fix: Fix) -> Here:
        raise NotImplementedError  # the mission's

    def _mark_blocked(self, island_id: int, exit_index: int) -> None:
        raise NotImplementedError  # the mission's

    def _again(self, island: Island, origin_odom: Pose2D, fix: Fix | None
               ) -> Generator[Step, None, Fix | None]:
        raise NotImplementedError  # the mission's

    def _end_trip(self, here: Here, exit_index: int | None, reached: int,
                  watch: OpeningWatch, edges: list[Edge]) -> None:
        """A trip from `here` by exit exit_index (None: a lost robot's) ended at island
        `reached`: its openings become side exits, and the exit is explored (or blocked, when
        the trip came back to where it began)."""
        if exit_index is None:  # a lost robot's wander is no way to an opening
            return
        self._note_openings(here.island_id, watch)
        if reached == here.island_id:
            self._mark_blocked(here.island_id, exit_index)  # back: nothing new
            return
        self.counts["exits_explored"] += 1
        self._side_explored(here.island_id, exit_index, reached, edges)

    def _held_decision(self, here: Here, exit_index: int | None, e: BuilderEvent,
                       watch: OpeningWatch, edges: list[Edge]
                       ) -> Generator[Step, None, Here | None]:
        """The builder holds a star that fits look-alike islands: each hypothesis (best
        first, at most rehearse_hypotheses) is rehearsed (`rehearse`); the first confirmed is
        the trip's end (a loop closed: the robot docked at that island's neighbour), else the
        builder builds the star's island (None: the trip goes on)."""
        assert self._drive is not None
        self.state = ExplorerState.REHEARSING
        for hyp in e.hypotheses[:self.cfg.rehearse_hypotheses]:
            self.counts["rehearsals"] += 1
            got = yield from rehearse(self._drive, self.graph, hyp, e.odom_pose, self.cfg,
                                      here.island_id, self._fixed)
            if not got.confirmed:
                continue
            assert got.fix is not None and got.trial is not None
            self._requests.append(Confirm(hyp.island_id))
            revisit = yield from self._await_event(EventKind.ISLAND_REVISITED)
            if revisit is not None:
                edges.extend([revisit.edge] if revisit.edge is not None else [])
                self._awaited.extend(revisit.exit_updates)
            self.counts["closures_rehearsed"] += 1
            self._end_trip(here, exit_index, hyp.island_id, watch, edges)
            return self._dock(got.trial.neighbour, got.fix)
        self._requests.append(Reject())
        self.state = ExplorerState.HANDED_OVER
        return None

    def _await_event(self, kind: EventKind) -> Generator[Step, None, BuilderEvent | None]:
        """Hold still until the builder emits an event of `kind` (at most map_wait_s)."""
        t0 = self._sense.t_s
        while self._sense.t_s - t0 <= self.cfg.map_wait_s:
            yield STOP
            found = next((e for e in self._events if e.kind is kind), None)
            if found is not None:
                return found
        return None

    def _settle(self, here: Here, island: Island) -> Generator[Step, None, Here]:
        """Handed back at the island a rehearsal did not find elsewhere: odometry drifted on
        the rehearsal's way since the star, so a look docks the robot before the builder's
        origin is trusted (kept when the look does not localize)."""
        d = self._drive
        assert d is not None
        d.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
        try:
            first: Fix | None = yield from localize_and_dock(
                d, island, self._sense.odom.relative_to(here.origin_odom), self._fixed,
                self.cfg.return_max_shift_m)
        except RouteTimeoutError:
            first = None
        fix = yield from self._again(island, here.origin_odom, first)
        return self._dock(here.island_id, fix) if fix is not None and fix.trusted else here

    def _note_openings(self, island_id: int, watch: OpeningWatch) -> None:
        """The openings seen on the way from island_id become its side exits (new ones only)."""
        new = noted_side_exits(self.graph, island_id, watch, self.cfg, self._side_sent)
        self._requests.extend(NewExit(island_id, ex) for ex in new)
        self.counts["side_exits_added"] += len(new)

    def _side_explored(self, island_id: int, index: int, reached: int, edges: list[Edge]
                       ) -> None:
        """A side exit's trip ended at island `reached`: never chosen again (`side_trip_end`)."""
        update = side_trip_end(self.graph, self._side_sent, (island_id, index), reached, edges)
        if update is not None:
            self._blocked.add((island_id, index))
            self.counts["side_exits_explored"] += 1
            self._requests.append(update)
