"""The explorer: exploration by the map (issue 16), a mission fed once per scan.

At an island the explorer picks the nearest island with an unexplored exit (`planner`), drives
there by the map (`core.route`: each edge's strategy, then localize and dock), turns to the exit
(through its gate when the island's model shows one: a doorway, a side corridor's mouth) and
hands the robot over to the builder (`core.builder.hooks`): the hall follower drives, the builder
decides, until it builds a new island or docks onto a known one and hands back. An exit whose
way is closed, or whose exploration runs past `exit_cap_s`, is marked blocked (after the robot
has been driven back to the island it left; a way back that does not localize looks again,
`relocalize`, before the robot counts as lost). DONE when no unexplored exit is left.

One `step(sense)` per scan returns who answers that scan (the explorer with (v, w), or the
builder side: the builder's star or the hall follower) and the requests for the builder and
the map (`Docked`, `Handover`, `Abort`, blocked exits as `ExitUpdate`, side exits as `NewExit`).

Held decisions (`trips`, `rehearse`): a star that fits a known island and a look-alike is held
by the builder; the explorer rehearses each hypothesis (drives the island's shortest edge from
its origin and looks for the neighbour) and confirms the first it finds (a loop closed) or
rejects them all (the builder builds its island, and a look there docks the robot).

Side exits (`openings`): while the builder side drives, openings beside the way become exits
of the island left, with the way there as a prefix; such an exit is reached by the map, then
its prefix (the opening sought by perception near its end), a quarter turn into it and a
handover by no exit the builder knows, with everything driven from the island as the prefix.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Generator, Iterable

import numpy as np
from island_msgs_py.geometry import to_frame
from island_msgs_py.hall_perception import HallPerceptionConfig, perceive
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitState,
    ExitUpdate,
    FloatArray,
    Island,
    Pose2D,
)

from island_mapping.core.builder import BuilderEvent, EventKind
from island_mapping.core.builder.path_record import PathRecord
from island_mapping.core.explore.config import ExploreError, ExplorerConfig
from island_mapping.core.explore.departure import STOP, drive_departure, go_clear, plan_departure
from island_mapping.core.explore.novelty import known_space_costs
from island_mapping.core.explore.openings import (
    OpeningWatch,
    side_departure,
)
from island_mapping.core.explore.planner import (
    Target,
    nearest_unexplored,
    route_edges,
    unexplored_count,
)
from island_mapping.core.explore.record import MotionRecord
from island_mapping.core.explore.relocalize import relocalize
from island_mapping.core.explore.requests import (
    Abort,
    Docked,
    ExplorerCommand,
    ExplorerState,
    ExplorerStatus,
    Handover,
    Request,
)
from island_mapping.core.explore.trips import Here, Step, TripEnds
from island_mapping.core.explore.watch import Deferred, StuckWatch
from island_mapping.core.graph import (
    TopoGraph,
    reverse_strategy,
    without_loops,
)
from island_mapping.core.route import (
    Drive,
    Fix,
    NavigateConfig,
    RouteTimeoutError,
    Sense,
    execute_strategy,
    localize_and_dock,
    rotate_to,
)


class Explorer(TripEnds):
    """The mission (module docstring). Feed `on_graph` (the latest map), `on_events` (the
    builder's events), `on_strategy` (the hall follower's record), then `step(sense)` once per
    scan. `on_fix` sees every arrival's localization (evaluation compares it with the truth)."""

    def __init__(self, cfg: ExplorerConfig | None = None, nav: NavigateConfig | None = None,
                 perception: HallPerceptionConfig | None = None, hall_width_m: float = 2.0,
                 on_fix: Callable[[Fix], None] | None = None) -> None:
        self.cfg = cfg if cfg is not None else ExplorerConfig()
        self.nav = nav if nav is not None else NavigateConfig()
        self.perception = perception if perception is not None else HallPerceptionConfig()
        self.hall_width_m = hall_width_m
        self._on_fix = on_fix
        self.graph = TopoGraph()
        self._events: list[BuilderEvent] = []
        self._awaited: list[ExitUpdate] = []
        self._follower = ControlStrategy(())
        self._requests: list[Request] = []
        self._drive: Drive | None = None
        self._gen: Generator[Step, None, None] | None = None
        self._since_dock = MotionRecord(Pose2D(0.0, 0.0, 0.0))
        self._way = PathRecord(self.cfg.way_tolerance_m)  # everything since the dock
        self._seen: deque[tuple[float, FloatArray]] = deque()  # (t [s], echoes, odometry frame)
        self._drove = False  # the explorer answered the last scan
        self._blocked: set[tuple[int, int]] = set()  # marked by us, maybe not yet in the map
        self._deferred = Deferred(self.cfg.retries_per_exit)
        self._side_sent: dict[int, list[Exit]] = {}  # side exits added by us, per island
        self.state = ExplorerState.WAITING
        self._here: int | None = None
        self._target: tuple[int, int] | None = None
        self.reason = ""
        self._penalty: dict[frozenset[int], float] = {}  # edges whose arrival failed
        self.counts = {"exits_explored": 0, "exits_blocked": 0, "lost": 0, "returns": 0,
                       "retreats": 0, "arrivals": 0, "untrusted_arrivals": 0,
                       "side_exits_added": 0, "side_exits_explored": 0, "exits_deferred": 0,
                       "relocalized": 0, "rehearsals": 0, "closures_rehearsed": 0}

    # ----- inputs -----

    def on_graph(self, graph: TopoGraph) -> None:
        """The latest map (read only)."""
        self.graph = graph

    def on_events(self, events: Iterable[BuilderEvent]) -> None:
        """The builder's events since the last step."""
        self._events.extend(events)

    def on_strategy(self, strategy: ControlStrategy) -> None:
        """The hall follower's record since its last reset (at the handover)."""
        self._follower = strategy

    @property
    def done(self) -> bool:
        return self.state is ExplorerState.DONE

    @property
    def status(self) -> ExplorerStatus:
        return ExplorerStatus(self.state, self._here, self._target,
                              unexplored_count(self.graph), self.done, self.reason)

    def step(self, sense: Sense) -> ExplorerCommand:
        """One scan: who answers it, and the requests made."""
        if self._drive is None:
            self._drive = Drive(sense, self.nav, self.perception, self.hall_width_m)
            self._gen = self._mission()
        self._drive.spin(sense)
        if any(e.kind is EventKind.HANDED_BACK and e.accepted_island_id is not None
               for e in self._events):  # at an island's origin: the pose is known again
            self._drive.spun_rad = 0.0
        self._since_dock.update(sense.odom, counted=self._drove)
        self._way.add(sense.odom)
        self._seen.append((sense.t_s, sense.points_odom()))
        while self._seen and self._seen[0][0] < sense.t_s - self.cfg.look_buffer_s:
            self._seen.popleft()
        assert self._gen is not None
        out = next(self._gen)
        self._events.clear()
        requests, self._requests = tuple(self._requests), []
        self._drove = out is not None
        if out is None:
            return ExplorerCommand(False, requests=requests)
        return ExplorerCommand(True, out[0], out[1], requests)

    # ----- the mission -----

    def _mission(self) -> Generator[Step, None, None]:
        here = yield from self._await_hand_back()
        while True:
            self.state = ExplorerState.CHOOSING
            self._here = here.island_id
            yield from self._await_map(here.island_id)
            extra = (known_space_costs(self.graph, here.island_id, self.cfg.novelty)
                     if self.cfg.novelty.enabled else None)
            for skip in self._deferred.skips(self._blocked):  # given-up exits last
                target = nearest_unexplored(self.graph, here.island_id, skip, extra,
                                            self._penalty)
                if target is not None:
                    break
            if target is None:
                self.state, self.reason = ExplorerState.DONE, "no unexplored exit left"
                self._target = None
                while True:
                    yield STOP
            self._target = (target.island_id, target.exit_index)
            here = yield from self._go_and_explore(here, target)

    def _go_and_explore(self, here: Here, target: Target) -> Generator[Step, None, Here]:
        """Drive to the target's island, depart by its exit, let the builder explore; where
        the robot is docked afterwards."""
        if target.island_id != here.island_id:
            self.state = ExplorerState.NAVIGATING
            arrived, last = yield from self._navigate(here, target)
            if arrived is None:
                return (yield from self._lost(last))
            if arrived.island_id != target.island_id:  # turned back: choose again
                return arrived
            here = arrived
        self.state = ExplorerState.DEPARTING
        ex = _exit(self.graph.get_island(here.island_id), target.exit_index)
        handed: int | None = target.exit_index
        if ex.is_side:  # the builder does not know it: a handover by no known exit
            handed = None
            assert self._drive is not None
            if not (yield from side_departure(self._drive, ex, here.origin_odom.theta,
                                              self.cfg)):
                self._follower = ControlStrategy(())
                return (yield from self._return(here, target.exit_index))
        elif not (yield from self._depart(here, target.exit_index)):
            self._mark_blocked(here.island_id, target.exit_index)
            return here
        self._requests.append(Handover(here.island_id, handed, self._since_dock.strategy()))
        self.state = ExplorerState.HANDED_OVER
        return (yield from self._handed_over(here, target.exit_index))

    def _await_hand_back(self) -> Generator[Step, None, Here]:
        """Let the builder side drive until it hands back at an island (island 0)."""
        while True:
            for e in self._events:
                if e.kind is EventKind.HANDED_BACK and e.accepted_island_id is not None:
                    self._awaited.extend(_updates_of(self._events))
                    return self._docked_by_builder(e)
            yield None

    def _await_map(self, island_id: int) -> Generator[Step, None, None]:
        """Hold still until the map holds the island and the exits the builder's last edge
        explored (the map may lag the builder's events), at most map_wait_s."""
        t0 = self._sense.t_s
        while self._sense.t_s - t0 <= self.cfg.map_wait_s and not self._map_has(island_id):
            yield STOP
        self._awaited.clear()

    def _map_has(self, island_id: int) -> bool:
        if island_id not in self.graph:
            return False
        for i, sent in self._side_sent.items():  # the side exits we added
            have = {e.index for e in self.graph.get_island(i).exits} if i in self.graph else set()
            if any(e.index not in have for e in sent):
                return False
        for u in self._awaited:
            if u.island not in self.graph:
                return False
            if all(e.index != u.index or e.state is not u.state
                   for e in self.graph.get_island(u.island).exits):
                return False
        return True

    def _navigate(self, here: Here, target: Target
                  ) -> Generator[Step, None, tuple[Here | None, Here]]:
        """Follow the route by the map; (where docked at the target or None, the last island
        docked at)."""
        d = self._drive
        assert d is not None
        edges = route_edges(self.graph, target.route)
        islands = {i.id: i for i in self.graph.islands()}
        d.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
        try:
            yield from rotate_to(d, here.origin_odom.theta)  # strategies start facing theta 0
        except RouteTimeoutError:
            return None, here
        last = here
        for e in edges:
            d.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
            try:
                yield from execute_strategy(d, e.strategy)
                fix = yield from localize_and_dock(d, islands[e.target], Pose2D(0.0, 0.0, 0.0),
                                                   self._fixed)
            except RouteTimeoutError:  # an edge that cannot be driven: avoid it next time
                _penalize(self._penalty, e, self.cfg.failed_edge_penalty_m)
                return None, last
            if not fix.trusted:  # back the way it came, to the island it left
                _penalize(self._penalty, e, self.cfg.failed_edge_penalty_m)
                back = yield from self._retreat(e, last)
                return (back, last) if back is not None else (None, last)
            last = self._dock(e.target, fix)
        return last, last

    def _retreat(self, e: Edge, last: Here) -> Generator[Step, None, Here | None]:
        """After an arrival that did not localize: drive the edge's strategy reversed back to
        the island it left and localize there from where odometry says the robot is (no
        search along a hallway); docked there, or None (lost)."""
        d = self._drive
        assert d is not None
        self.counts["retreats"] += 1
        d.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
        island = self.graph.get_island(last.island_id)
        try:
            yield from execute_strategy(d, reverse_strategy(e.strategy))
            near = self._sense.odom.relative_to(last.origin_odom)
            fix = yield from localize_and_dock(d, island, near, self._fixed,
                                               self.cfg.return_max_shift_m)
        except RouteTimeoutError:
            fix = None
        fix = yield from self._again(island, last.origin_odom, fix)
        return self._dock(last.island_id, fix) if fix is not None and fix.trusted else None

    def _again(self, island: Island, origin_odom: Pose2D, fix: Fix | None
               ) -> Generator[Step, None, Fix | None]:
        """`fix` when trusted, else `relocalize` at the island (origin last at origin_odom);
        None past the deadline."""
        if (fix is not None and fix.trusted) or self._drive is None:
            return fix
        self._drive.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
        try:
            fix = yield from relocalize(self._drive, island, origin_odom, self.cfg,
                                        self._fixed)
        except RouteTimeoutError:
            return None
        self.counts["relocalized"] += int(fix is not None and fix.trusted)
        return fix

    def _fixed(self, fix: Fix) -> None:
        self.counts["arrivals"] += 1
        if not fix.trusted:
            self.counts["untrusted_arrivals"] += 1
        if self._on_fix is not None:
            self._on_fix(fix)

    def _depart(self, here: Here, exit_index: int) -> Generator[Step, None, bool]:
        """Turn to the exit (through its gate) within max_edge_time_s; False when the way is
        closed or the time ran out (the robot back at the origin, as far as it can)."""
        d = self._drive
        assert d is not None
        d.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
        try:
            return (yield from self._depart_moves(here, exit_index))
        except RouteTimeoutError:
            d.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
            try:
                yield from go_clear(d, here.origin_odom)
            except RouteTimeoutError:
                pass
            self._since_dock = MotionRecord(self._sense.odom)
            return False

    def _depart_moves(self, here: Here, exit_index: int) -> Generator[Step, None, bool]:
        d = self._drive
        assert d is not None
        island = self.graph.get_island(here.island_id)
        seen = np.concatenate([p for _, p in self._seen]) if self._seen else np.zeros((0, 2))
        plan = plan_departure(island.model, _exit(island, exit_index),
                              to_frame(seen, here.origin_odom), self.cfg)
        left = yield from drive_departure(d, plan, here.origin_odom, self.cfg, self.perception)
        if not left:
            self._since_dock = MotionRecord(self._sense.odom)
        return left

    def _handed_over(self, here: Here, exit_index: int | None
                     ) -> Generator[Step, None, Here]:
        """The builder side drives until it hands back at an island; past exit_cap_s (or after
        open_space_cap_s without both sides walls: the follower circles a room) the
        explorer asks it to stop and drives the robot back to `here`, and the exit is blocked.
        exit_index None: leaving after getting lost (nothing to block)."""
        self._follower = ControlStrategy(())
        # The events of this step came before the handover (the builder takes it after the
        # step): the hand-back that ended the last trip must not end this one too.
        self._events.clear()
        watch = OpeningWatch(self.cfg, self._since_dock.strategy())
        t0 = walled_t = self._sense.t_s  # walled_t: when both sides were last walls
        stuck = StuckWatch(self.cfg.stuck_s, self.cfg.stuck_m, self._sense)
        edges: list[Edge] = []
        built: Island | None = None  # the island the builder built on this trip
        rehearsed = False
        while True:
            for e in list(self._events):
                edges.extend([e.edge] if e.edge is not None else [])
                built = e.island if e.kind is EventKind.ISLAND_ACCEPTED else built
                if e.kind is EventKind.REVISIT_HYPOTHESIS:
                    closed = yield from self._held_decision(here, exit_index, e, watch, edges)
                    if closed is not None:
                        return closed
                    rehearsed = True  # the builder builds its island: the timers start again
                    t0 = walled_t = self._sense.t_s
                    stuck = StuckWatch(self.cfg.stuck_s, self.cfg.stuck_m, self._sense)
                    break
                if e.kind is EventKind.HANDED_BACK and e.accepted_island_id is not None:
                    self._end_trip(here, exit_index, e.accepted_island_id, watch, edges)
                    self._awaited.extend(_updates_of(self._events))
                    back = self._docked_by_builder(e)
                    if rehearsed and built is not None and built.id == back.island_id:
                        return (yield from self._settle(back, built))
                    return back
                if e.kind is EventKind.STOPPED:
                    if exit_index is not None:
                        self._note_openings(here.island_id, watch)
                    return (yield from self._return(here, exit_index))
            seen = perceive(self._sense.ranges_m, self._sense.angles_rad, self.perception)
            if self.cfg.side_exits:
                watch.update(seen, self._follower, self._sense.odom.theta)
            if not (seen.left_open or seen.right_open):
                walled_t = self._sense.t_s  # a hallway (or a doorway): not circling a room
            if self._sense.t_s - t0 > self.cfg.exit_cap_s or stuck.update(self._sense) or (
                    self._sense.t_s - walled_t > self.cfg.open_space_cap_s):
                self._requests.append(Abort())
            yield None

    def _docked_by_builder(self, e: BuilderEvent) -> Here:
        assert e.accepted_island_id is not None
        origin = e.anchor_odom if e.anchor_odom is not None else e.odom_pose
        self._since_dock = MotionRecord(self._sense.odom)
        self._way.restart(origin)
        return Here(e.accepted_island_id, origin)

    def _return(self, here: Here, exit_index: int | None) -> Generator[Step, None, Here]:
        """Back to the island left, by the reversed record of the way out."""
        self.state = ExplorerState.RETURNING
        self.counts["returns"] += 1
        d = self._drive
        assert d is not None
        driven = self._way_driven()
        out = driven if driven is not None else ControlStrategy(
            self._since_dock.strategy().steps + self._follower.steps)
        way = without_loops(out, self.cfg.return_shortcut_m, self.cfg.return_loop_m)
        d.deadline_s = self._sense.t_s + self.nav.max_edge_time_s
        island = self.graph.get_island(here.island_id)
        try:
            yield from execute_strategy(d, reverse_strategy(way))
            # Where odometry says the robot is in the island's frame: the reversed record
            # rarely ends on the origin, and a fit searched from the origin instead can land
            # in a wrong basin yet look trusted (a false arrival).
            near = self._sense.odom.relative_to(here.origin_odom)
            fix = yield from localize_and_dock(d, island, near, self._fixed,
                                               self.cfg.return_max_shift_m)
        except RouteTimeoutError:
            fix = None
        fix = yield from self._again(island, here.origin_odom, fix)
        if exit_index is not None and self._deferred.give_up((here.island_id, exit_index)):
            self._mark_blocked(here.island_id, exit_index)
        self.counts["exits_deferred"] = self._deferred.deferred
        if fix is None or not fix.trusted:
            return (yield from self._lost(here))
        return self._dock(here.island_id, fix)

    def _dock(self, island_id: int, fix: Fix) -> Here:
        """Docked at island_id's origin by the explorer's own localization (`fix`: where the
        last look put the origin in the odometry frame; the robot stands within the docking
        tolerance of it): tell the builder."""
        origin = fix.origin_odom if fix.origin_odom is not None else self._sense.odom
        here = Here(island_id, origin)
        self._requests.append(Docked(here.island_id, here.origin_odom))
        self._since_dock = MotionRecord(self._sense.odom)
        self._way.restart(origin)
        self._here = island_id
        return here

    def _lost(self, last: Here) -> Generator[Step, None, Here]:
        """An arrival did not localize: the builder takes over as if the robot had left the
        last island docked at by no known exit, with everything driven since as the prefix."""
        self.state = ExplorerState.LOST
        self.counts["lost"] += 1
        way = self._way_driven()
        prefix = self._since_dock.strategy() if way is None else without_loops(
            way, self.cfg.return_shortcut_m, self.cfg.return_loop_m)
        self._requests.append(Handover(last.island_id, None, prefix))
        self.state = ExplorerState.HANDED_OVER
        return (yield from self._handed_over(last, None))

    def _way_driven(self) -> ControlStrategy | None:
        """Everything driven since the last dock, by whoever drove (odometry's polyline from
        that island's origin), or None with way_tolerance_m 0. The records it replaces (the
        explorer's own moves, the follower's primitives) miss the follower's turns while
        driving, and a lost robot's own record leaves out every stretch the follower drove."""
        return self._way.strategy() if self._way.on else None

    def _mark_blocked(self, island_id: int, exit_index: int) -> None:
        self._blocked.add((island_id, exit_index))
        self.counts["exits_blocked"] += 1
        self._requests.append(ExitUpdate(island_id, exit_index, ExitState.BLOCKED))


def _penalize(penalty: dict[frozenset[int], float], e: Edge, metres: float) -> None:
    """Edge e counts `metres` longer in the planner from now on."""
    key = frozenset((e.source, e.target))
    penalty[key] = penalty.get(key, 0.0) + metres


def _exit(island: Island, index: int) -> Exit:
    for e in island.exits:
        if e.index == index:
            return e
    raise ExploreError(f"island {island.id} has no exit {index}")


def _updates_of(events: Iterable[BuilderEvent]) -> list[ExitUpdate]:
    """The exit updates the builder's events carry (the map must show them before a choice)."""
    return [u for e in events for u in e.exit_updates]
