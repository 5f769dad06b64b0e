"""More evidence for a held star (`core.builder.held`): a rehearsal of a known island's edge.

The builder's star fitted a known island C, but also another place (a look-alike): deciding
on the spot either builds a duplicate of C or merges two places. Kuipers' rehearsal procedure
(the paper's reference [1]) tells them apart by what lies beyond: if the robot stands at C, C's
edge to a neighbour D, driven from C's origin, ends at D, where the robot localizes in D's
model. A look-alike of C rarely has a look-alike of D at the end of the same strategy.

`rehearse` drives it: onto C's origin as the star's fit puts it, where the robot must be
found at C (`_found`: a trusted look within `return_max_shift_m`, a dock that ends on the
origin, `docked`, and the walls C's model shows heard, `heard_through`), else the hypothesis
fails at once; then C's shortest edge to a neighbour D (its strategy, or the reverse of an
edge into C), and a look at D within `rehearse_max_shift_m` of its origin (no search along a
hallway: a far basin would confirm a look-alike) where the robot must be found at D in the
same way. Confirmed once `rehearse_neighbours` neighbours were found (each time the edge is
driven back and the robot docks at C again before the next; where C has fewer edges, all of
them): the robot is docked at the last. Only the first look at C can refute the hypothesis:
once C and a neighbour were found, a look at C on the way back that does not localize says
little (paper_fig4 seed 3: a hypothesis 0.02 m off the truth, its neighbour found 0.04 m from
its origin, was rejected by it), and the next edge starts from C's origin as last docked.
Not found: the edge is driven back, the robot docks at C again and tries C's next edge
(`rehearse_edges`); after the last the robot stands near C's supposed origin, the star's
place. In a lattice of corridors a look-alike of C often has
a look-alike of one neighbour (office 11: two false merges in three runs with one), rarely of
two.

Onward (`rehearse_onward`, off by default until whole runs say more than two seeds did, see
docs/exploration.md, session 32): when one more island would confirm and D has an edge to an
island E other than C, the robot drives it from D (docked there) and looks for E, instead of
driving back to C, docking there and driving C's next edge: one edge and one dock fewer (a
confirmed rehearsal took three edge drives of 75-77 s each on paper_fig4, and 390-490 s in
all). A look-alike of C with a look-alike of D must then have one of E beyond it, as rare as
one of C's second neighbour. E not found counts as one of the `rehearse_edges` trials: the
robot drives back to D, then to C, and goes on with C's next edge.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from dataclasses import dataclass, replace

import numpy as np
from island_msgs_py.raycast import raycast
from island_msgs_py.types import (
    ControlStrategy,
    Island,
    LineModel,
    Pose2D,
)

from island_mapping.core.builder import Hypothesis
from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.graph import TopoGraph, reverse_strategy
from island_mapping.core.route import (
    Command,
    Drive,
    Fix,
    RouteTimeoutError,
    execute_strategy,
    go_to,
    localize_and_dock,
)
from island_mapping.core.route.arrival import FixHook
from island_mapping.core.route.motion import Scan, look_scans

# A wall the model puts within this range of the robot [m], met by a beam's axis within this of
# head-on [deg], echoes (the ring's cones return an echo up to 30 deg off the normal); an echo
# farther than it by more than the margin [m] heard through it. Model walls nearer than
# MUST_ECHO_MIN_M are not asked: a star's sonar model draws phantom segments around its origin
# (paper_fig4 seed 2, island 4: a 3.3 m segment 0.7 m from the origin, where the ring hears
# 3.2 m of free space; 80 % of its beams "heard through" at the right place).
MUST_ECHO_MIN_M = 1.0
MUST_ECHO_M = 3.0
MUST_ECHO_DEG = 20.0
THROUGH_MARGIN_M = 0.3

# After docking at the neighbour, the robot stands within this of its origin by the last look
# [m]. A look-alike along a hallway slides with the robot: each drive onto the origin its fit
# shows is followed by a fit that shows it as far ahead again, and the dock gives up there
# (the twin-T test: 0.75 m after three rounds).
DOCKED_M = 0.3



@dataclass(frozen=True)
class Trial:
    """The edge a rehearsal drives: from the hypothesis' island to `neighbour` by `strategy`."""

    neighbour: int
    strategy: ControlStrategy


@dataclass(frozen=True)
class Rehearsal:
    """How a rehearsal ended: `fix` at the neighbour when confirmed, else None."""

    island_id: int
    trial: Trial | None
    fix: Fix | None

    @property
    def confirmed(self) -> bool:
        return self.fix is not None and self.fix.trusted


def trial_edges(graph: TopoGraph, island_id: int, avoid: int | None = None, k: int = 1
                ) -> list[Trial]:
    """The edges a rehearsal at island island_id drives, at most k, shortest first (an edge
    into it driven backwards, as routes do; ties to the lower neighbour id); those to `avoid`
    (the island the robot came from: odometry already relates the two) after all others."""
    found: list[tuple[bool, float, int, Trial]] = []
    for e in graph.iter_edges():
        if island_id not in (e.source, e.target) or e.source == e.target:
            continue
        other = e.target if e.source == island_id else e.source
        if other not in graph or any(f[2] == other for f in found):
            continue
        way = e.strategy if e.source == island_id else reverse_strategy(e.strategy)
        found.append((other == avoid, e.length_m, other, Trial(other, way)))
    found.sort(key=lambda f: f[:3])
    return [f[3] for f in found[:k]]


def rehearse(d: Drive, graph: TopoGraph, hyp: Hypothesis, odom_then: Pose2D,
             cfg: ExplorerConfig, came_from: int | None = None,
             on_fix: FixHook | None = None) -> Generator[Command, None, Rehearsal]:
    """Test `hyp` (the robot's pose in its island's frame when the robot stood at odometric
    pose odom_then) by its island's shortest edges (rehearse_edges of them, not to island
    came_from where others exist; module docstring). on_fix sees the neighbour's
    localization once it confirms, the one the robot reports; the looks at the hypothesis'
    own island are only a test and are not reported."""
    if hyp.island_id not in graph:
        return Rehearsal(hyp.island_id, None, None)
    island = graph.get_island(hyp.island_id)
    origin_odom = odom_then.compose(hyp.pose.inverse())  # where the hypothesis puts the origin
    trial: Trial | None = None
    trials = trial_edges(graph, hyp.island_id, came_from, cfg.rehearse_edges)
    need, found, tried = min(cfg.rehearse_neighbours, len(trials)), 0, 0
    for trial in trials:
        if tried >= cfg.rehearse_edges:
            break
        d.deadline_s = d.sense.t_s + d.cfg.max_edge_time_s
        try:
            yield from go_to(d, origin_odom)
            here = yield from localize_and_dock(
                d, island, d.sense.odom.relative_to(origin_odom), None, cfg.return_max_shift_m)
        except RouteTimeoutError:
            break
        if (yield from _found(d, island, here, cfg)):
            assert here.origin_odom is not None
            origin_odom = here.origin_odom
        elif not found:
            break
        fix = yield from _trial(d, graph, trial, cfg)
        tried += 1
        if fix is None:
            continue
        found += 1
        onward = _onward(graph, hyp.island_id, trial) if (
            cfg.rehearse_onward and found + 1 == need and tried < cfg.rehearse_edges) else None
        if onward is not None:
            tried += 1
            got = yield from _trial(d, graph, onward, cfg)  # not found: driven back to D
            if got is not None:
                trial, fix, found = onward, got, need
        if found >= need:
            if on_fix is not None:
                on_fix(fix)
            return Rehearsal(hyp.island_id, trial, fix)
        d.deadline_s = d.sense.t_s + d.cfg.max_edge_time_s  # back for the next neighbour
        try:
            yield from execute_strategy(d, reverse_strategy(trial.strategy))
        except RouteTimeoutError:
            break
    return Rehearsal(hyp.island_id, trial, None)


def _onward(graph: TopoGraph, island_id: int, trial: Trial) -> Trial | None:
    """The shortest edge from trial's neighbour D to an island other than island_id (the
    hypothesis' island), or None (module docstring, "Onward")."""
    ways = trial_edges(graph, trial.neighbour, island_id, k=len(graph))
    return next((t for t in ways if t.neighbour != island_id), None)


def _trial(d: Drive, graph: TopoGraph, trial: Trial, cfg: ExplorerConfig
           ) -> Generator[Command, None, Fix | None]:
    """From the hypothesis' origin (docked there) drive `trial` and look for the neighbour:
    its fix, the robot's pose in its frame after docking there, when the dock ended on its
    origin and its walls were heard; else None, the edge driven back."""
    d.deadline_s = d.sense.t_s + d.cfg.max_edge_time_s
    try:
        yield from execute_strategy(d, trial.strategy)
        neighbour = graph.get_island(trial.neighbour)
        fix = yield from localize_and_dock(d, neighbour, Pose2D(0.0, 0.0, 0.0), None,
                                           cfg.rehearse_max_shift_m)
        if (yield from _found(d, neighbour, fix, cfg)):
            assert fix.origin_odom is not None
            return replace(fix, pose=d.sense.odom.relative_to(fix.origin_odom))
        d.deadline_s = d.sense.t_s + d.cfg.max_edge_time_s
        yield from execute_strategy(d, reverse_strategy(trial.strategy))
    except RouteTimeoutError:
        pass
    return None


def _found(d: Drive, island: Island, fix: Fix, cfg: ExplorerConfig
           ) -> Generator[Command, None, bool]:
    """Is the robot at `island` by `fix`: trusted, the dock ended on its origin (`docked`),
    and a look there heard the walls its model shows (`heard_through`)?"""
    if not fix.trusted or fix.origin_odom is None or not docked(d.sense.odom, fix.origin_odom):
        return False
    scans = yield from look_scans(d)
    return heard_through(island.model, fix.origin_odom, scans) <= cfg.rehearse_through


def heard_through(model: LineModel, origin_odom: Pose2D, scans: list[Scan]) -> float:
    """Of the beams `model` (its origin at origin_odom) says must echo (a wall between
    MUST_ECHO_MIN_M and MUST_ECHO_M met within MUST_ECHO_DEG of head-on), the fraction that
    heard nothing there (no echo, or one beyond the wall by THROUGH_MARGIN_M) [-]; 0 when none
    must. A fit
    explains the echoes it has; this asks whether the walls it shows were heard: a look-alike
    place fits the island's model as well, but the ring hears through walls it lacks."""
    must = through = 0
    cos_min = math.cos(math.radians(MUST_ECHO_DEG))
    for odom, ranges, angles in scans:
        p = odom.relative_to(origin_odom)
        hits = raycast(model.segments, np.tile([p.x, p.y], (angles.size, 1)),
                       p.theta + angles, MUST_ECHO_M)
        want = (hits.distance_m >= MUST_ECHO_MIN_M) & np.isfinite(hits.distance_m) & (
            hits.cos_incidence >= cos_min)
        heard = np.isfinite(ranges) & (ranges <= hits.distance_m + THROUGH_MARGIN_M)
        must += int(np.count_nonzero(want))
        through += int(np.count_nonzero(want & ~heard))
    return through / must if must else 0.0


def docked(odom: Pose2D, origin_odom: Pose2D) -> bool:
    """Does the robot at odometric pose `odom` stand within DOCKED_M of the origin?"""
    here = odom.relative_to(origin_odom)
    return math.hypot(here.x, here.y) <= DOCKED_M
