"""What an explorer adds to the builder (issue 16): a managed mode, the handover, exits.

- **Managed mode** (`BuilderHooks.managed`): handing back at an island (built or recognised)
  ends in IDLE, waiting for the explorer, instead of resuming the hall follower. While IDLE
  the builder neither drives nor lets the follower drive; it still tracks odometry.
- **Docked** (`IslandBuilder.on_docked`): the explorer reports the robot docked at an island's
  origin (odometry pose): that island is the last one, epsilon restarts there, and the
  recognizer knows where its origin is now.
- **Handover** (`IslandBuilder.handover`): the explorer leaves the last docked island by one of
  its exits, having driven `prefix` (e.g. `Rot 90, Go 150`) since docking; the builder
  resumes FOLLOWING and the next edge's strategy starts at that island's origin with the
  prefix. The edge records the exit it left by (`source_exit`) and the exit of its target it
  arrived by (`target_exit`); both exits become explored by it (`exit_updates` of the event).
- **Exits** (`BuilderHooks.find_exits`): called at acceptance with what the star saw, in the
  island frame; the exit facing where the robot came from is the arrival.
- **Held decisions** (`BuilderHooks.hold_hypotheses`, `IslandBuilder.confirm` / `reject`): a
  star that fits look-alike islands waits for the explorer's evidence (`core.builder.held`).
- **Revisit gate** (`BuilderHooks.accept_revisit`): a recognition the Recognizer proposed is
  kept only if the gate agrees (loop closure with topological evidence): it answers why it
  refuses (a `Refusal`, counted) or None; the recognition it sees carries the direction the
  robot came from in the island frame (`arrival_rad`). The live builder and the passive mode
  (`core.builder.passive`) both ask it.
  `BuilderHooks.revisit` replaces the builder's revisit search settings, `opening` and
  `accept_on_legs` its side openings and eq. 3 over the star's region (`hooked_config`):
  exploration by the map attempts islands at side openings.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitState,
    ExitUpdate,
    FloatArray,
    Island,
    LineModel,
    Pose2D,
    PrimitiveKind,
    wrap_angle,
)

from island_mapping.core.builder.config import BuilderConfig, RevisitConfig
from island_mapping.core.builder.diagnostics import Refusal
from island_mapping.core.builder.events import BuilderEvent, EventKind
from island_mapping.core.builder.geometry import concat
from island_mapping.core.builder.opening import OpeningExit
from island_mapping.core.builder.opening_config import OpeningConfig
from island_mapping.core.builder.recognition import PoseSnapshot, Recognition
from island_mapping.core.builder.star import Attempt

ExitFinder = Callable[[FloatArray, FloatArray, FloatArray, float | None, FloatArray,
                       OpeningExit | None], tuple[Exit, ...]]
"""(segments (N, 4), echo points (M, 2), driven paths (K, 4), arrival heading [rad] or None,
the star's readings (R, 4: where from [m], bearing [rad], range [m], inf for no echo), the
opening the island stands in or None), all in the island frame [m] -> the island's exits
(all unexplored)."""

RevisitGate = Callable[[Recognition, PoseSnapshot, Island, bool], Refusal | None]
"""(the proposed recognition, the robot's snapshot, the recognised island, from a star?) ->
why it is refused, or None: keep it."""

APPROACH_M = 5.0
"""The path the robot came along is taken back this far (free: it drove there) [m]."""
ARRIVAL_BACK_M = 3.0
"""The direction the robot came from points to where it was this far back along its path [m]."""


@dataclass(frozen=True)
class BuilderHooks:
    """The explorer's hooks (module docstring); the defaults are the paper's plain builder."""

    managed: bool = False
    find_exits: ExitFinder | None = None
    accept_revisit: RevisitGate | None = None
    arrival_match_deg: float = 45.0
    revisit: RevisitConfig | None = None  # the recognition the explorer wants (None: the builder's)
    opening: OpeningConfig | None = None  # side openings as places (None: the builder's)
    accept_on_legs: bool | None = None  # eq. 3 over the star's region (None: the builder's)
    # An edge's way without its loops: (edge_shortcut_m, edge_loop_m) [m] (None: the builder's).
    edge_loops: tuple[float, float] | None = None
    # A star fitting this many look-alike islands at most holds its decision for the
    # explorer's evidence (`core.builder.held`; 0: decide on the spot), for at most hold_s [s].
    hold_hypotheses: int = 0
    hold_s: float = 3600.0


def hooked_config(config: BuilderConfig | None, hooks: BuilderHooks) -> BuilderConfig:
    """The builder's configuration under `hooks`: its revisit settings, its side openings,
    accept_on_legs and the edges' loop cutting replaced by the hooks' when they bring their
    own."""
    cfg = config if config is not None else BuilderConfig()
    if hooks.revisit is not None:
        cfg = dataclasses.replace(cfg, revisit=hooks.revisit)
    if hooks.opening is not None:
        cfg = dataclasses.replace(cfg, opening=hooks.opening)
    if hooks.accept_on_legs is not None:
        cfg = dataclasses.replace(cfg, accept_on_legs=hooks.accept_on_legs)
    if hooks.edge_loops is not None:
        cfg = dataclasses.replace(cfg, edge_shortcut_m=hooks.edge_loops[0],
                                  edge_loop_m=hooks.edge_loops[1])
    return cfg


@dataclass(frozen=True)
class Departure:
    """The explorer's handover: leaving island `island_id` by exit `exit_index` (None: not
    by a known exit) after driving `prefix` from its origin."""

    island_id: int
    exit_index: int | None
    prefix: ControlStrategy


def approach_path(strategy: ControlStrategy, back_m: float) -> FloatArray:
    """The last back_m [m] of the path `strategy` drove, walked back from where it ended, as a
    polyline (K, 2) in the frame of its end pose (the end first) [m]. Turns turn the walk."""
    pts = [np.zeros(2)]
    x = y = th = 0.0
    left = back_m
    for s in reversed(strategy.steps):
        if left <= 0.0:
            break
        if s.kind is PrimitiveKind.ROT:
            th -= s.radians
            continue
        d = min(s.metres, left)
        x, y = x - d * math.cos(th), y - d * math.sin(th)
        left -= d
        pts.append(np.array([x, y]))
    return np.array(pts)


def arrival_heading(path: FloatArray, at: Pose2D | None = None,
                    back_m: float = ARRIVAL_BACK_M) -> float | None:
    """The direction from an island's origin toward where a robot came from: back_m [m] back
    along its approach `path` (from `approach_path`, in the robot's frame at pose `at` in the
    island frame; None: the island frame itself) [rad]; None when the path has no length."""
    if path.shape[0] < 2:
        return None
    far = _along(path, back_m)
    if at is not None:
        c, s = math.cos(at.theta), math.sin(at.theta)
        far = np.array([at.x + c * far[0] - s * far[1], at.y + s * far[0] + c * far[1]])
    if math.hypot(float(far[0]), float(far[1])) < 1e-6:
        return None
    return math.atan2(float(far[1]), float(far[0]))


def gate_refusal(hooks: BuilderHooks, rec: Recognition, snap: PoseSnapshot, island: Island,
                 star: bool, approach: FloatArray, at: Pose2D) -> Refusal | None:
    """The hooks' revisit gate on a proposed recognition `rec` of `island`, shown where the
    robot came from (`arrival_heading` of its `approach` polyline, from `approach_path`, seen
    from pose `at` in the island frame): why it is refused, or None (also without a gate)."""
    gate = hooks.accept_revisit
    if gate is None:
        return None
    came = arrival_heading(approach, at)
    return gate(dataclasses.replace(rec, arrival_rad=came), snap, island, star)


def _along(path: FloatArray, dist_m: float) -> FloatArray:
    """The point dist_m [m] along a polyline (its end when shorter)."""
    for a, b in itertools.pairwise(path):
        seg = float(np.hypot(*(b - a)))
        if seg >= dist_m and seg > 0.0:
            return np.asarray(a + (b - a) * (dist_m / seg), dtype=np.float64)
        dist_m -= seg
    return np.asarray(path[-1], dtype=np.float64)


def exit_evidence(att: Attempt, model: LineModel, shift: Pose2D, approach: FloatArray
                  ) -> tuple[FloatArray, FloatArray, FloatArray, float | None, FloatArray]:
    """The star's evidence for `ExitFinder` in the island frame (the origin at `shift` in
    the anchor frame, same heading): the model, the star's echoes, the legs driven and the
    approach polyline (anchor frame, from `approach_path`), the direction the robot came
    from (None for island 0), and the star's readings (`Attempt.looks`)."""
    off = np.array([shift.x, shift.y])
    pts = concat(att.points) - off if att.points else np.zeros((0, 2))
    driven = [[-off[0], -off[1], length * math.cos(b) - off[0], length * math.sin(b) - off[1]]
              for b, length in att.legs_done]
    way = approach - off
    if not att.first:
        driven.extend([*a, *b] for a, b in itertools.pairwise(way))
    arrival = None if att.first else arrival_heading(way)
    segs = np.asarray(driven, dtype=np.float64).reshape(-1, 4)
    looks = att.looks() - np.array([off[0], off[1], 0.0, 0.0])
    return model.segments, pts, segs, arrival, looks


def facing_exit(island: Island, heading_rad: float, within_deg: float) -> Exit | None:
    """The island's exit at its origin nearest `heading_rad`, if within `within_deg` [deg]
    (a side exit lies elsewhere, along an edge: it says nothing of arrivals at the origin)."""
    best = min((e for e in island.exits if not e.is_side),
               key=lambda e: abs(wrap_angle(e.heading_rad - heading_rad)), default=None)
    if best is None or abs(wrap_angle(best.heading_rad - heading_rad)) > math.radians(within_deg):
        return None
    return best


def with_exits(edge: Edge | None, departure: Departure | None, target_exit: int | None
               ) -> Edge | None:
    """`edge` naming the exit it leaves by (when it leaves the departure's island) and the
    exit of its target it arrives by."""
    if edge is None:
        return None
    src = departure.exit_index if departure is not None and (
        departure.island_id == edge.source) else None
    return Edge(edge.source, edge.target, edge.strategy, edge.weight, edge.length_m,
                edge.expected_error_m, src, target_exit)


def exit_updates(edge: Edge | None, explored_by: tuple[int, int] | None,
                 departure: Departure | None, target_exit: int | None) -> tuple[ExitUpdate, ...]:
    """The exits `explored_by` (the edge that now joins the two islands, (source, target))
    explored: the departure's exit on its island and the target's arrival exit."""
    if explored_by is None or edge is None:
        return ()
    out = []
    if departure is not None and departure.exit_index is not None and (
        departure.island_id == edge.source
    ):
        out.append(ExitUpdate(edge.source, departure.exit_index, ExitState.EXPLORED, explored_by))
    if target_exit is not None:
        out.append(ExitUpdate(edge.target, target_exit, ExitState.EXPLORED, explored_by))
    return tuple(out)


GraphItem = Island | Edge | ExitUpdate
"""What a builder event adds to the map (`/topo_graph/add` items, in order)."""


def graph_items(event: BuilderEvent) -> list[GraphItem]:
    """The items a builder event adds to the map, in the order they must be applied: the new
    island (its exits unexplored), then the edge, then the exits that edge explored."""
    items: list[GraphItem] = []
    if event.kind is EventKind.ISLAND_ACCEPTED and event.island is not None:
        items.append(event.island)
    if event.kind in (EventKind.ISLAND_ACCEPTED, EventKind.ISLAND_REVISITED) and (
        event.edge is not None
    ):
        items.append(event.edge)
    items.extend(event.exit_updates)
    return items
