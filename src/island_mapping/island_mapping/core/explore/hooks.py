"""The builder hooks an explorer installs (`core.builder.hooks.BuilderHooks`): managed mode,
exits found from the star's evidence, the revisit search it wants, and the loop-closure gate
on recognitions.

Loop closure with topological evidence: the Recognizer proposes an island whose origin,
propagated from the last island along odometry (and the links measured on edges) with its
uncertainty, could be here, and whose model fits the points at one island only. The gate keeps
it when (1) the robot is at its place (within revisit_near_m of its origin), (2) the
recognised pose is within the uncertainty of the propagated estimate (squared Mahalanobis
distance), and (3) the island has an exit facing the direction the robot came from, whatever
its state (explored by an edge from elsewhere too: a closure missed earlier leaves two islands
at one place, and the robot may come from the other). An arrival of unknown direction at an
island with exits is refused (no evidence for it: a star's corridor points fitted a junction's
model 6 m along its corridor once); an island without exits gives no evidence either way.
`loop_closure_gate` is the gate, `loop_closure_hooks` the loop closure alone (a recording's
passive mode installs it: the same search and gate as live exploration).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from island_msgs_py.types import Exit, FloatArray, Island, Pose2D, wrap_angle

from island_mapping.core.builder.diagnostics import Refusal
from island_mapping.core.builder.hooks import BuilderHooks, RevisitGate, facing_exit
from island_mapping.core.builder.opening import OpeningExit
from island_mapping.core.builder.recognition import PoseSnapshot, Recognition
from island_mapping.core.explore.config import ExplorerConfig
from island_mapping.core.explore.exits import (
    ExitEvidence,
    island_exits,
    opening_exits,
)
from island_mapping.core.explore.openings import exit_pose
from island_mapping.core.graph import TopoGraph

SIDE_EXIT_LOOK_M = 2.0
"""A side exit faces an arrival by the direction to this far along it from its opening [m]."""


def arrival_agrees(island: Island, arrival_rad: float | None, within_deg: float) -> bool:
    """Topological evidence (module docstring, (3)): may a robot that came from `arrival_rad`
    (island frame [rad]) arrive at `island`? An exit must face it within `within_deg` [deg]:
    one at the origin, or a side exit, by the direction from the origin to a point
    SIDE_EXIT_LOOK_M along it (an island in a doorway is reached along the hallway its
    continuation leads down)."""
    if not island.exits:
        return True
    if arrival_rad is None:
        return False  # nothing to check it by: a missed closure is cheaper than a false one
    if facing_exit(island, arrival_rad, within_deg) is not None:
        return True
    for e in island.exits:
        if e.prefix is None or e.side is None:
            continue
        p = exit_pose(e.prefix, e.side).compose(Pose2D(SIDE_EXIT_LOOK_M, 0.0, 0.0))
        if abs(wrap_angle(math.atan2(p.y, p.x) - arrival_rad)) <= math.radians(within_deg):
            return True
    return False


def loop_closure_gate(cfg: ExplorerConfig, graph: Callable[[], TopoGraph] | None = None
                      ) -> RevisitGate:
    """The loop-closure gate (module docstring): why a proposed recognition is refused
    (`Refusal.NOT_AT_PLACE`, `OUTSIDE_UNCERTAINTY`, `TOPOLOGY`), or None to keep it. `graph`
    returns the latest map (the exits' states); None: the island as the builder has it."""

    def gate(rec: Recognition, snap: PoseSnapshot, island: Island, star: bool
             ) -> Refusal | None:
        del star, snap
        if math.hypot(rec.pose.x, rec.pose.y) > cfg.revisit_near_m:
            return Refusal.NOT_AT_PLACE  # seen from the next place, not at its own
        if rec.mahalanobis2 is not None and rec.mahalanobis2 > cfg.revisit_max_mahalanobis2:
            return Refusal.OUTSIDE_UNCERTAINTY
        g = None if graph is None else graph()
        known = g.get_island(island.id) if g is not None and island.id in g else island
        if not arrival_agrees(known, rec.arrival_rad, cfg.exit.arrival_match_deg):
            return Refusal.TOPOLOGY
        return None

    return gate


def explorer_hooks(cfg: ExplorerConfig, graph: Callable[[], TopoGraph]) -> BuilderHooks:
    """Managed mode with `find_exits` (cfg.exit), cfg.revisit's search and the loop-closure
    gate (module docstring), edges without their loops as the way back is
    (return_shortcut_m, return_loop_m); `graph` returns the latest map (the exits' states)."""

    def exits(segments: FloatArray, points: FloatArray, driven: FloatArray,
              arrival_rad: float | None, looks: FloatArray, opening: OpeningExit | None
              ) -> tuple[Exit, ...]:
        ev = ExitEvidence(segments, points, driven, arrival_rad, looks)
        found = island_exits(ev, cfg.exit)
        return found if opening is None else opening_exits(found, ev, opening, cfg.exit)

    return BuilderHooks(managed=True, find_exits=exits,
                        accept_revisit=loop_closure_gate(cfg, graph),
                        arrival_match_deg=cfg.exit.arrival_match_deg, revisit=cfg.revisit,
                        opening=cfg.opening, accept_on_legs=cfg.accept_on_legs,
                        edge_loops=(cfg.return_shortcut_m, cfg.return_loop_m),
                        hold_hypotheses=cfg.rehearse_hypotheses)


def loop_closure_hooks(cfg: ExplorerConfig) -> BuilderHooks:
    """Exploration's loop closure alone (its revisit search and `loop_closure_gate`), without
    the managed mode and exits: what the passive mode of a recording installs to close loops
    as live exploration does (`core.builder.passive.PassiveBuilder`). A recording's windows of
    scans are not the live robot's: accept_inlier_fraction (measured live) stays off."""
    revisit = dataclasses.replace(cfg.revisit, accept_inlier_fraction=0.0)
    return BuilderHooks(accept_revisit=loop_closure_gate(cfg),
                        arrival_match_deg=cfg.exit.arrival_match_deg, revisit=revisit)
