"""Side exits: openings the robot passes while the hall follower drives an edge.

The paper places islands only where eq. 3 and the measure R say so, and the hall follower
drives straight through junctions without one; exploring by the islands' exits alone then
never learns of them (docs/exploration.md, Known limits). While the builder side drives, the
explorer watches the follower's hall perception (`left_open`/`right_open`, the same test the
follower decides by): a side that stays open over `side_min_width_m` of straight driving is an
opening. Its way from the island the edge left is the edge's strategy up to the opening's
middle (the handover's prefix, then the follower's record): a *side exit* of that island
(`Exit.prefix`, `Exit.side`), reached later by the map: to the island, the prefix, a turn.

Duplicates are not added: an opening near a known island's origin (that island's own exits
cover it; the edge's end is one) or near a known side exit leading the same way, both
dead-reckoned into the island's frame along the edges' strategies up to `side_chain_m` of
route (`chained_frames`).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Generator
from dataclasses import dataclass

from island_msgs_py.hall_perception import Perception, perceive
from island_msgs_py.limits import MAX_EXITS_PER_ISLAND
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitSide,
    ExitState,
    ExitUpdate,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
    wrap_angle,
)

from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.explore.planner import distances_from, route_to
from island_mapping.core.graph import TopoGraph, normalize_strategy, strategy_displacement
from island_mapping.core.route import (
    Command,
    Drive,
    RouteTimeoutError,
    execute_strategy,
    go_along_hall,
    go_to,
    rotate_by,
    rotate_to,
)


@dataclass(frozen=True)
class Opening:
    """A side opening seen from an edge: reached from the island's origin by `prefix`, entered
    by a quarter turn to `side`; `width_m` of driving it stayed open [m]."""

    prefix: ControlStrategy
    side: ExitSide
    width_m: float


def exit_pose(prefix: ControlStrategy, side: ExitSide) -> Pose2D:
    """Where a side exit is in its island's frame (the prefix's end) and the heading into it
    (after the turn) [m, rad]: the prefix executed ideally from the origin facing theta 0."""
    end = strategy_displacement(prefix)
    turn = math.pi / 2 if side is ExitSide.LEFT else -math.pi / 2
    return Pose2D(end.x, end.y, wrap_angle(end.theta + turn))


@dataclass
class _Run:
    """A side open since the record was `samples[0][0]` long [m]; max heading change [rad]."""

    theta0: float
    samples: list[tuple[float, ControlStrategy]]
    turn_rad: float = 0.0


class OpeningWatch:
    """Feed `update` once per scan while the builder side drives an edge that left an island
    after `head` (the handover's prefix); `finish` gives the openings seen."""

    def __init__(self, cfg: ExplorerConfig, head: ControlStrategy) -> None:
        self.cfg = cfg
        self.head = head
        self._runs: dict[ExitSide, _Run | None] = {ExitSide.LEFT: None, ExitSide.RIGHT: None}
        self._last_m: float | None = None
        self.last = ControlStrategy(())  # the longest record seen (the edge so far)
        self.openings: list[Opening] = []

    def update(self, p: Perception, record: ControlStrategy, heading_rad: float) -> None:
        """One scan's perception, the follower's record since the handover and the odometric
        heading [rad]. Scans without forward driving (the builder's star, a turn in place,
        a pause) neither open nor close an opening."""
        length = record.length_m
        if self._last_m is not None and length <= self._last_m + 1e-9:
            return
        self._last_m = length
        self.last = record
        for side, is_open in ((ExitSide.LEFT, p.left_open), (ExitSide.RIGHT, p.right_open)):
            run = self._runs[side]
            if is_open and run is None:
                self._runs[side] = _Run(heading_rad, [(length, record)])
            elif is_open and run is not None:
                run.samples.append((length, record))
                run.turn_rad = max(run.turn_rad, abs(wrap_angle(heading_rad - run.theta0)))
            elif run is not None:
                self._close(side, run)
                self._runs[side] = None

    def finish(self) -> list[Opening]:
        """The openings seen (a side still open at the end is not one: the edge ended there)."""
        return list(self.openings)

    def _close(self, side: ExitSide, run: _Run) -> None:
        first, last = run.samples[0][0], run.samples[-1][0]
        width = last - first
        if width < self.cfg.side_min_width_m:
            return
        if run.turn_rad > math.radians(self.cfg.side_max_turn_deg):
            return
        mid = 0.5 * (first + last)
        rec = min(run.samples, key=lambda s: abs(s[0] - mid))[1]
        prefix = normalize_strategy(ControlStrategy(self.head.steps + rec.steps))
        if prefix.length_m > 0.0:
            self.openings.append(Opening(prefix, side, width))


def chained_frames(graph: TopoGraph, start: int, max_m: float) -> dict[int, Pose2D]:
    """Each island's frame in `start`'s frame, dead-reckoned along the edges' strategies (an
    edge ends at its target's origin facing its theta 0), for islands up to `max_m` of route
    (edge weights) away; the nearest route wins (`planner.distances_from`), and between two
    islands the lightest edge."""
    if start not in graph:
        return {}
    dist, prev = distances_from(graph, start)
    steps: dict[tuple[int, int], tuple[float, Pose2D]] = {}
    for e in graph.iter_edges():
        t = strategy_displacement(e.strategy)
        for key, move in (((e.source, e.target), t), ((e.target, e.source), t.inverse())):
            if key not in steps or e.weight < steps[key][0]:
                steps[key] = (e.weight, move)
    frames = {start: Pose2D(0.0, 0.0, 0.0)}
    for goal in (i for i, d in dist.items() if d <= max_m):
        route = route_to(prev, start, goal)
        for a, b in itertools.pairwise(route):
            if b not in frames:
                frames[b] = frames[a].compose(steps[(a, b)][1])
    return frames


def new_side_exits(graph: TopoGraph, island_id: int, openings: list[Opening],
                   cfg: ExplorerConfig, also_near: tuple[Pose2D, ...] = (),
                   pending: tuple[Exit, ...] = ()) -> list[Exit]:
    """The side exits to add to island `island_id` for `openings` (module docstring), indexed
    after its exits and `pending` (exits sent, maybe not yet in the map). `also_near`: places
    (its frame) where an island is, or is about to be (the end of the edge driven)."""
    if island_id not in graph:
        return []
    frames = chained_frames(graph, island_id, cfg.side_chain_m)
    places = [Pose2D(f.x, f.y, 0.0) for f in frames.values()] + list(also_near)
    known = [frames[j].compose(exit_pose(e.prefix, e.side)) for j in frames
             for e in graph.get_island(j).exits if e.prefix is not None and e.side is not None]
    known += [exit_pose(e.prefix, e.side) for e in pending
              if e.prefix is not None and e.side is not None]
    own = graph.get_island(island_id).exits + pending
    index = max((e.index for e in own), default=-1) + 1
    room = MAX_EXITS_PER_ISLAND - len(own)
    out: list[Exit] = []
    for o in openings:
        pose = exit_pose(o.prefix, o.side)
        if len(out) >= room or _near(pose, places, cfg.side_near_island_m):
            continue
        if any(_near(pose, [k], cfg.side_merge_m) and abs(wrap_angle(k.theta - pose.theta))
               < math.radians(cfg.side_merge_deg) for k in known):
            continue
        out.append(Exit(index, pose.theta, o.width_m, prefix=o.prefix, side=o.side))
        known.append(pose)
        index += 1
    return out


def noted_side_exits(graph: TopoGraph, island_id: int, watch: OpeningWatch,
                     cfg: ExplorerConfig, sent: dict[int, list[Exit]]) -> list[Exit]:
    """The openings `watch` saw on the way from island_id as its new side exits (none that
    the map or the exits already `sent` per island, not yet in the map, cover); they are
    added to `sent`."""
    openings = watch.finish()
    if not openings or island_id not in graph:
        return []
    end = strategy_displacement(ControlStrategy(watch.head.steps + watch.last.steps))
    known = {e.index for e in graph.get_island(island_id).exits}
    pending = tuple(e for e in sent.get(island_id, []) if e.index not in known)
    new = new_side_exits(graph, island_id, openings, cfg, (end,), pending)
    sent.setdefault(island_id, []).extend(new)
    return new


def side_trip_end(graph: TopoGraph, sent: dict[int, list[Exit]], exit_key: tuple[int, int],
                  reached: int, edges: list[Edge]) -> ExitUpdate | None:
    """A trip by exit exit_key = (island, index) ended at island `reached`: when it is a side
    exit (one in `sent`, or marked side in the map), its update: explored by the edge the
    builder made from the island (one of `edges`, or in the map), else blocked. None: not a
    side exit."""
    island_id, index = exit_key
    side = index in {e.index for e in sent.get(island_id, [])} or (
        island_id in graph and any(e.index == index and e.is_side
                                   for e in graph.get_island(island_id).exits))
    if not side:
        return None
    if any((e.source, e.target) == (island_id, reached) for e in edges) or graph.has_edge(
            island_id, reached):
        return ExitUpdate(island_id, index, ExitState.EXPLORED, (island_id, reached))
    return ExitUpdate(island_id, index, ExitState.BLOCKED)


def _near(pose: Pose2D, places: list[Pose2D], within_m: float) -> bool:
    return any(math.hypot(pose.x - q.x, pose.y - q.y) < within_m for q in places)


def approach(prefix: ControlStrategy, short_m: float) -> tuple[ControlStrategy, float]:
    """The prefix with its last Go shortened by up to `short_m` [m] (the robot looks for the
    opening from there), and how much was cut [m]."""
    steps = list(prefix.steps)
    if not steps or steps[-1].kind is not PrimitiveKind.GO:
        return prefix, 0.0
    cut = min(steps[-1].value, round(100.0 * short_m))
    steps[-1] = StrategyPrimitive(PrimitiveKind.GO, steps[-1].value - cut)
    return normalize_strategy(ControlStrategy(tuple(steps))), cut / 100.0


def side_departure(d: Drive, ex: Exit, origin_theta: float, cfg: ExplorerConfig
                   ) -> Generator[Command, None, bool]:
    """From its island's origin (facing odometric heading origin_theta [rad]: the island's
    theta 0): the side exit's prefix, the opening sought by perception over the last
    side_search_m of it and as far past (not when the prefix drives no more than
    side_direct_m: odometry is good enough there, and it ends where the opening is), a
    quarter turn into it (through it, door_through_m,
    when it is a doorway: narrower than door_max_width_m); False when it is not found open or
    the time (d.deadline_s) ran out."""
    assert ex.prefix is not None and ex.side is not None
    near = sum(s.metres for s in ex.prefix.steps if s.kind is PrimitiveKind.GO) <= (
        cfg.side_direct_m)
    way, cut = (ex.prefix, 0.0) if near else approach(ex.prefix, cfg.side_search_m)
    try:
        yield from rotate_to(d, origin_theta)
        yield from (drive_straight(d, way) if near else execute_strategy(d, way))
        if not near and not (yield from seek_side(d, ex.side, cut + cfg.side_search_m,
                                                  0.5 * min(ex.width_m, 2.0))):
            return False
        turn = math.pi / 2 if ex.side is ExitSide.LEFT else -math.pi / 2
        yield from rotate_to(d, wrap_angle(d.sense.odom.theta + turn))
        # the robot's whole path must be free: turned short of a doorway's middle, a jamb in
        # the way holds the follower against the wall for the whole exit cap
        ahead = perceive(d.sense.ranges_m, d.sense.angles_rad, d.perception).front_cone_m
        if ahead < cfg.depart_min_free_m:
            return False
        if ex.width_m <= cfg.door_max_width_m:  # through the doorway before the follower
            yield from go_along_hall(d, cfg.door_through_m)
    except RouteTimeoutError:
        return False
    return True


def drive_straight(d: Drive, strategy: ControlStrategy) -> Generator[Command, None, None]:
    """A short strategy by odometry alone: each Go a straight drive to where odometry says it
    ends (`go_to`), each Rot a turn in place. From a localized origin over a few metres that is
    exact enough to pass a doorway, where the hallway centring of `Go` steers at the walls
    beside it."""
    for s in strategy.steps:
        if s.kind is PrimitiveKind.GO:
            yield from go_to(d, d.sense.odom.compose(Pose2D(s.metres, 0.0, 0.0)))
        else:
            yield from rotate_by(d, s.radians)


def seek_side(d: Drive, side: ExitSide, max_m: float, into_m: float
              ) -> Generator[Command, None, bool]:
    """Drive on along the hallway up to max_m [m] until `side` has been open for into_m [m]
    (about the opening's middle), then stop; True when found."""
    start, opened = d.sense.odom, None
    motion = go_along_hall(d, max_m)
    for cmd in motion:
        p = perceive(d.sense.ranges_m, d.sense.angles_rad, d.perception)
        o = d.sense.odom
        s = math.hypot(o.x - start.x, o.y - start.y)
        is_open = p.left_open if side is ExitSide.LEFT else p.right_open
        opened = (s if opened is None else opened) if is_open else None
        if opened is not None and s - opened >= into_m:
            motion.close()
            yield (0.0, 0.0)
            return True
        yield cmd
    return False
