"""Exploration by the map (issue 16): exits, the choice of the next exit, bad input.

Public APIs only: `island_mapping.core.explore`, the builder's managed-mode inputs.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from island_mapping.core.builder import BuilderConfig, BuilderError, IslandBuilder
from island_mapping.core.builder.diagnostics import Refusal
from island_mapping.core.builder.hooks import BuilderHooks
from island_mapping.core.builder.recognition import PoseSnapshot, Recognition, Recognizer
from island_mapping.core.explore import (
    Abort,
    Docked,
    ExitConfig,
    ExitEvidence,
    ExploreError,
    ExplorerConfig,
    NoveltyConfig,
    Reject,
    apply_to_builder,
    arrival_exit,
    explorer_hooks,
    find_exits,
    known_space_costs,
    nearest_unexplored,
    route_edges,
    unexplored_count,
)
from island_mapping.core.graph import TopoGraph
from island_mapping.evaluation.explore_exits import explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitSide,
    ExitState,
    ExitUpdate,
    Island,
    LineModel,
    ModelType,
    Pose2D,
)
from island_sim.core.world_loader import load_world

# Walls in an island's frame (theta 0 along the hallway the robot arrived on, from -x) [m].
T_WALLS = np.array([[-6, -1, 6, -1], [-6, 1, -1, 1], [1, 1, 6, 1], [-1, 1, -1, 6],
                    [1, 1, 1, 6]], dtype=float)
END_WALLS = np.array([[-6, -1, 1, -1], [-6, 1, 1, 1], [1, -1, 1, 1]], dtype=float)
PLUS_WALLS = np.array([[-6, -1, -1, -1], [1, -1, 6, -1], [-6, 1, -1, 1], [1, 1, 6, 1],
                       [-1, 1, -1, 6], [1, 1, 1, 6], [-1, -1, -1, -6], [1, -1, 1, -6]],
                      dtype=float)
APPROACH = np.array([[-5.0, 0.0, 0.0, 0.0]])  # the robot drove in from the west


def echoes(walls: np.ndarray, rng: np.random.Generator, step_m: float = 0.3,
           noise_m: float = 0.03) -> np.ndarray:
    """Echo points along the walls, with range noise."""
    pts = []
    for x0, y0, x1, y1 in walls:
        n = max(2, int(math.hypot(x1 - x0, y1 - y0) / step_m))
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts.append(np.hstack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)]))
    p = np.concatenate(pts)
    return p + rng.normal(0.0, noise_m, p.shape)


def headings_deg(exits: tuple[Exit, ...], snap_deg: float = 10.0) -> list[int]:
    """Exit headings [deg, 0..359] rounded to the nearest axis when within snap_deg (an
    exit's heading points into the opening's entry, a few degrees off the corridor's axis)."""
    out = []
    for e in exits:
        d = math.degrees(e.heading_rad) % 360.0
        axis = 90.0 * round(d / 90.0)
        out.append(round(axis if abs(d - axis) <= snap_deg else d) % 360)
    return sorted(out)


@pytest.mark.parametrize(("walls", "expected"), [
    (T_WALLS, [0, 90, 180]), (END_WALLS, [180]), (PLUS_WALLS, [0, 90, 180, 270]),
])
def test_exits_of_a_star_in_a_t_a_corridor_end_and_a_crossing(walls: np.ndarray,
                                                               expected: list[int]) -> None:
    rng = np.random.default_rng(3)
    ev = ExitEvidence(walls, echoes(walls, rng), APPROACH, math.pi)
    exits = find_exits(ev)
    assert headings_deg(exits) == expected
    assert all(e.state is ExitState.UNEXPLORED for e in exits)
    assert [e.index for e in exits] == list(range(len(exits)))
    came = arrival_exit(exits, math.pi)
    assert came is not None and round(math.degrees(came.heading_rad)) % 360 == 180


def test_a_sparse_model_with_echoes_still_finds_the_side_corridor() -> None:
    """Two wall lines only (a sonar model is sparse): the echoes close the false gaps."""
    rng = np.random.default_rng(4)
    ev = ExitEvidence(T_WALLS[:2], echoes(T_WALLS, rng), APPROACH, math.pi)
    assert headings_deg(find_exits(ev)) == [0, 90, 180]


def test_a_closed_corridor_end_without_echoes_is_not_closed() -> None:
    """Without echoes the model alone decides: a missing end wall is an opening (liberal: a
    false exit costs a short drive, a missed one costs coverage)."""
    ev = ExitEvidence(END_WALLS[:2], np.zeros((0, 2)), APPROACH, math.pi)
    assert {0, 180} <= set(headings_deg(find_exits(ev)))


def _island(iid: int, exits: tuple[Exit, ...]) -> Island:
    return Island(iid, LineModel(np.zeros((0, 4))), ModelType.LINE, 1.0, 0.0, exits=exits)


def _edge(a: int, b: int, w: float) -> Edge:
    return Edge(a, b, ControlStrategy(()), w, w)


def _explored(k: int, edge: tuple[int, int]) -> Exit:
    return Exit(k, 0.0, 1.0, ExitState.EXPLORED, edge)


def test_the_explorer_picks_the_nearest_unexplored_exit_by_the_graph() -> None:
    """0 -5- 1 -5- 2 and 0 -20- 3: the unexplored exits are at 2 (10 m by the graph) and 3
    (20 m). From 0, island 2; from 3 itself, island 3; edges count backwards too."""
    g = TopoGraph.from_parts(
        [_island(0, (_explored(0, (0, 1)),)),
         _island(1, (_explored(0, (0, 1)), _explored(1, (1, 2)))),
         _island(2, (_explored(0, (1, 2)), Exit(1, 0.0, 1.0), Exit(2, 1.0, 1.0))),
         _island(3, (_explored(0, (0, 3)), Exit(1, 0.0, 1.0)))],
        [_edge(0, 1, 5.0), _edge(1, 2, 5.0), _edge(0, 3, 20.0)])
    t = nearest_unexplored(g, 0)
    assert t is not None and (t.island_id, t.exit_index) == (2, 1)
    assert t.route == (0, 1, 2) and t.distance_m == pytest.approx(10.0)
    t3 = nearest_unexplored(g, 3)
    assert t3 is not None and (t3.island_id, t3.route) == (3, (3,))
    back = nearest_unexplored(g, 2, skip={(2, 1), (2, 2)})
    assert back is not None and back.route == (2, 1, 0, 3)
    assert [e.source for e in route_edges(g, back.route)] == [2, 1, 0]
    assert unexplored_count(g) == 3
    assert nearest_unexplored(g, 0, skip={(2, 1), (2, 2), (3, 1)}) is None


def test_ties_go_to_the_lower_island_id() -> None:
    g = TopoGraph.from_parts([_island(0, ()), _island(1, (Exit(0, 0.0, 1.0),)),
                              _island(2, (Exit(0, 0.0, 1.0),))],
                             [_edge(0, 2, 4.0), _edge(0, 1, 4.0)])
    t = nearest_unexplored(g, 0)
    assert t is not None and t.island_id == 1


def _corridor_map() -> TopoGraph:
    """Island 1 lies 10 m ahead of island 0 (edge 'Go 1000'). Island 0's exit 1 looks down
    that corridor (known space); its side exit 2 opens to the left 5 m along it and island 1's
    exit 1 to the left of island 1 (both into space the map does not know)."""
    s = ControlStrategy.parse
    return TopoGraph.from_parts(
        [_island(0, (_explored(0, (0, 1)), Exit(1, 0.0, 1.0),
                     Exit(2, math.pi / 2, 1.0, prefix=s("Go 500"), side=ExitSide.LEFT))),
         _island(1, (Exit(0, math.pi, 1.0, ExitState.EXPLORED, (0, 1)),
                     Exit(1, math.pi / 2, 1.0)))],
        [Edge(0, 1, s("Go 1000"), 10.0, 10.0)])


def test_exits_into_known_space_go_last() -> None:
    """Nearest first takes island 0's exit 1, which looks down the corridor the edge drove;
    with its known-space cost the side exit 5 m away goes first, then island 1's exit, and
    the known one still goes before exploration ends."""
    g = _corridor_map()
    cfg = NoveltyConfig()
    costs = known_space_costs(g, 0, cfg)
    assert costs == {(0, 1): cfg.penalty_m}
    assert known_space_costs(g, 1, cfg) == costs  # the same space from the other island
    plain = nearest_unexplored(g, 0)
    assert plain is not None and (plain.island_id, plain.exit_index) == (0, 1)
    order = []
    skip: set[tuple[int, int]] = set()
    while (t := nearest_unexplored(g, 0, skip, costs)) is not None:
        order.append((t.island_id, t.exit_index, t.distance_m))
        skip.add((t.island_id, t.exit_index))
    assert order == [(0, 2, pytest.approx(5.0)), (1, 1, pytest.approx(10.0)),
                     (0, 1, pytest.approx(0.0))]


def test_a_look_point_beyond_the_radius_is_new_space() -> None:
    g = _corridor_map()
    assert known_space_costs(g, 0, NoveltyConfig(lookahead_m=4.0, radius_m=1.0)) == {
        (0, 1): NoveltyConfig().penalty_m}
    # island 1's exit looks 4 m to the left of it: 4 m from the edge's path at island 1
    assert (1, 1) in known_space_costs(g, 0, NoveltyConfig(radius_m=4.5))
    with pytest.raises(ExploreError, match=r"NoveltyConfig\.radius_m"):
        NoveltyConfig(radius_m=float("nan"))


def test_bad_input_names_what_is_wrong() -> None:
    with pytest.raises(ExploreError, match="segments"):
        ExitEvidence(np.zeros((3, 3)), np.zeros((0, 2)), np.zeros((0, 4)))
    with pytest.raises(ExploreError, match="points"):
        ExitEvidence(np.zeros((0, 4)), np.array([[np.nan, 0.0]]), np.zeros((0, 4)))
    with pytest.raises(ExploreError, match="clearance_m"):
        ExitConfig(clearance_m=-1.0)
    with pytest.raises(ExploreError, match="exit_cap_s"):
        ExplorerConfig(exit_cap_s=float("nan"))
    g = TopoGraph.from_parts([_island(0, ()), _island(1, ())], [])
    with pytest.raises(ExploreError, match="unknown island 7"):
        nearest_unexplored(g, 7)
    with pytest.raises(ExploreError, match="no edge between islands 0 and 1"):
        route_edges(g, (0, 1))


def test_the_builder_refuses_a_handover_it_cannot_take() -> None:
    """Handover and docking are the explorer's (managed mode), and only at an island."""
    plain = IslandBuilder(BuilderConfig())
    with pytest.raises(BuilderError, match="not in managed mode"):
        plain.handover(0, 0, ControlStrategy(()))
    managed = IslandBuilder(BuilderConfig(), hooks=BuilderHooks(managed=True))
    managed.on_odometry(0.0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
    with pytest.raises(BuilderError, match=r"unknown island 0 \(the builder has 0: \[\]\)"):
        managed.on_docked(0, Pose2D(0.0, 0.0, 0.0))  # no island yet: said before the state
    assert managed.islands == [] or len(managed.islands) == 0


def test_the_builders_requests_take_effect_or_are_refused_by_name() -> None:
    """One dispatch (the builder node's and the offline harness's): a request the builder
    cannot take, or one for the map, is refused with a reason and changes nothing (the
    requests it takes are driven by the exploration tests)."""
    managed = IslandBuilder(BuilderConfig(), hooks=BuilderHooks(managed=True))
    managed.on_odometry(0.0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
    state = managed.state
    with pytest.raises(BuilderError, match=rf"cannot give the robot back: it is busy \({state}\)"):
        apply_to_builder(managed, Abort())  # no island yet: the builder drives to make one
    with pytest.raises(BuilderError, match="unknown island 3"):
        apply_to_builder(managed, Docked(3, Pose2D(0.0, 0.0, 0.0)))
    with pytest.raises(BuilderError, match="no decision is held"):
        apply_to_builder(managed, Reject())
    with pytest.raises(BuilderError, match="ExitUpdate is a request for the map"):
        apply_to_builder(managed, ExitUpdate(0, 0, ExitState.BLOCKED))
    assert managed.state == state and len(managed.islands) == 0
    plain = IslandBuilder(BuilderConfig())
    with pytest.raises(BuilderError, match="not in managed mode"):
        apply_to_builder(plain, Abort())


def test_exploration_ends_by_itself_in_a_small_world_with_every_exit_explored() -> None:
    """The T world offline (simulator, builder in managed mode, explorer, hall follower): the
    explorer says it is done, no exit is left unexplored, the map has an edge per explored
    exit, and no arrival was reported localized while wrong, no wall touched."""
    run = explore_by_exits(SimSetup(world=load_world("t_junction")), 600.0,
                           rng=np.random.default_rng(1))
    assert run.done and run.sim_seconds < 600.0
    exits = [e for i in run.graph.islands() for e in i.exits]
    assert len(run.graph) >= 2 and exits
    assert all(e.state is not ExitState.UNEXPLORED for e in exits)
    for e in exits:
        if e.state is ExitState.EXPLORED:
            assert e.edge is not None and run.graph.has_edge(*e.edge)
    assert run.false_arrivals == 0 and run.collisions == 0


def _robot_points(walls: np.ndarray, robot: Pose2D, rng: np.random.Generator,
                  range_m: float = 5.0) -> np.ndarray:
    """Echoes of `walls` within range_m of `robot`, in the robot's frame [m]."""
    p = echoes(walls, rng, step_m=0.2, noise_m=0.02)
    p = p[np.hypot(p[:, 0] - robot.x, p[:, 1] - robot.y) <= range_m]
    c, s = math.cos(robot.theta), math.sin(robot.theta)
    d = p - np.array([robot.x, robot.y])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


T_EXITS = (Exit(0, math.pi, 2.0), Exit(1, 0.0, 2.0), Exit(2, math.pi / 2, 2.0))
"""The T's openings, in its frame: west (where the robot came from), east, north."""


def _t_island(iid: int, exits: tuple[Exit, ...] = ()) -> Island:
    return Island(iid, LineModel(T_WALLS), ModelType.LINE, 1.0, 0.0, exits=exits)


@pytest.mark.parametrize("right", [0, 1])
def test_a_revisit_docks_onto_the_right_island(right: int) -> None:
    """Two T junctions 30 m apart by odometry; the robot is back 0.45 m from one of them:
    that one is recognised, at the robot's true pose in its frame."""
    robot_in_island = Pose2D(0.4, 0.2, 0.05)
    origins = {0: Pose2D(0.0, 0.0, 0.0), 1: Pose2D(30.0, 0.0, 0.0)}
    at = origins[right].compose(robot_in_island)
    rec = Recognizer(BuilderConfig())
    for iid, o in origins.items():
        rec.remember(iid, o, np.zeros((3, 3)))
    snap = PoseSnapshot(at, np.diag([0.01, 0.01, 0.001]), 0.3, 0.02, 1 - right, 50.0)
    pts = _robot_points(T_WALLS, robot_in_island, np.random.default_rng(5))
    found = rec.recognize(pts, at, snap, [_t_island(0), _t_island(1)])
    assert found is not None and found.island_id == right
    assert math.hypot(found.pose.x - 0.4, found.pose.y - 0.2) < 0.1
    gate = explorer_hooks(ExplorerConfig(), TopoGraph).accept_revisit
    assert gate is not None and gate(found, snap, _t_island(right), False) is None
    far = Recognition(right, Pose2D(4.0, 0.0, 0.0), found.residual_m, found.inlier_fraction)
    # seen from the next place: no dock
    assert gate(far, snap, _t_island(right), False) is Refusal.NOT_AT_PLACE


@pytest.mark.parametrize("came_deg", [180.0, 95.0, -90.0])
def test_a_revisit_docks_only_through_an_exit_facing_the_arrival(came_deg: float) -> None:
    """The topological evidence: the robot may have come to a T from its west, east or north
    opening, never through its south wall; and the recognised pose must lie within the
    uncertainty of where odometry put the island."""
    gate = explorer_hooks(ExplorerConfig(), TopoGraph).accept_revisit
    assert gate is not None
    snap = PoseSnapshot(Pose2D(0.0, 0.0, 0.0), np.eye(3), 0.3, 0.02, 0, 50.0)
    rec = Recognition(1, Pose2D(0.4, 0.2, 0.05), 0.05, 0.9, mahalanobis2=2.0,
                      arrival_rad=math.radians(came_deg))
    facing = came_deg != -90.0
    assert (gate(rec, snap, _t_island(1, T_EXITS), True) is None) is facing
    assert gate(rec, snap, _t_island(1), True) is None  # no exits known: no evidence against
    unknown = Recognition(1, rec.pose, 0.05, 0.9, mahalanobis2=2.0)
    # no arrival: no evidence for
    assert gate(unknown, snap, _t_island(1, T_EXITS), True) is Refusal.TOPOLOGY
    unlikely = Recognition(1, rec.pose, 0.05, 0.9, mahalanobis2=30.0, arrival_rad=math.pi)
    # outside the uncertainty
    assert gate(unlikely, snap, _t_island(1, T_EXITS), True) is Refusal.OUTSIDE_UNCERTAINTY


def test_the_explorers_search_reaches_a_drifted_island_and_docks_onto_it() -> None:
    """Odometry drifted by 3 m and 8 deg around a 60 m loop: the plain search refuses the
    window as too large, the explorer's (within its caps, one island fitting) finds the
    island at the robot's true pose in its frame."""
    robot_in_island = Pose2D(0.4, 0.2, 0.05)
    believed = Pose2D(3.0, -2.0, math.radians(8.0))  # the island's origin by odometry
    at = believed.compose(robot_in_island)
    pts = _robot_points(T_WALLS, robot_in_island, np.random.default_rng(7))
    snap = PoseSnapshot(at, np.diag([9.0, 9.0, 0.02]), 3.0, 0.14, 1, 60.0)
    islands = [_t_island(0), Island(1, LineModel(END_WALLS), ModelType.LINE, 1.0, 0.0)]
    far_end = Pose2D(40.0, 0.0, 0.0)
    for cfg in (BuilderConfig(), BuilderConfig(revisit=ExplorerConfig().revisit)):
        rec = Recognizer(cfg)
        rec.remember(0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
        rec.remember(1, far_end, np.zeros((3, 3)))
        found = rec.recognize(pts, at, snap, islands, star=True)
        if not cfg.revisit.clip_search:
            assert found is None and rec.diagnostics.revisit_refusals["drift_too_large"] >= 1
            continue
        assert found is not None and found.island_id == 0
        assert math.hypot(found.pose.x - 0.4, found.pose.y - 0.2) < 0.15
        assert found.mahalanobis2 is not None and found.mahalanobis2 < 11.34


def test_an_ambiguous_revisit_does_not_dock_without_more_evidence() -> None:
    """Two identical T junctions 4 m apart, both within the search window of a drifted
    odometry: the points fit both, so neither is recognised (a look-alike refusal)."""
    robot_in_island = Pose2D(0.4, 0.2, 0.05)
    rec = Recognizer(BuilderConfig())
    rec.remember(0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
    rec.remember(1, Pose2D(4.0, 0.0, 0.0), np.zeros((3, 3)))
    snap = PoseSnapshot(robot_in_island, np.diag([1.0, 1.0, 0.001]), 0.3, 0.02, None, 50.0)
    pts = _robot_points(T_WALLS, robot_in_island, np.random.default_rng(6))
    assert rec.recognize(pts, robot_in_island, snap, [_t_island(0), _t_island(1)]) is None
    assert rec.diagnostics.revisit_refusals.get("look_alike", 0) >= 1


def test_the_explorers_search_refuses_two_identical_junctions_within_the_window() -> None:
    """The explorer's search (clipped windows) with two identical T junctions 8 m apart, both
    within the drifted odometry's window: the star's points fit both, so the robot does not
    dock (a missed closure, never a false one); with one of them it docks."""
    robot_in_island = Pose2D(0.4, 0.2, 0.05)
    snap = PoseSnapshot(robot_in_island, np.diag([16.0, 16.0, 0.01]), 0.3, 0.1, None, 50.0)
    pts = _robot_points(T_WALLS, robot_in_island, np.random.default_rng(8))
    for twins in (True, False):
        rec = Recognizer(BuilderConfig(revisit=ExplorerConfig().revisit))
        rec.remember(0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
        islands = [_t_island(0)]
        if twins:
            rec.remember(1, Pose2D(8.0, 0.0, 0.0), np.zeros((3, 3)))
            islands.append(_t_island(1))
        found = rec.recognize(pts, robot_in_island, snap, islands, star=True)
        if twins:
            assert found is None and rec.diagnostics.revisit_refusals["look_alike"] >= 1
        else:
            assert found is not None and found.island_id == 0


def test_a_look_alike_refusal_keeps_both_fits_as_hypotheses() -> None:
    """The twins above: the star's points fit both, the recognition is refused (no dock on
    the spot), and both islands are kept as hypotheses for more evidence (the explorer's
    rehearsal, `core.explore.rehearse`), each with the robot's pose in its frame and its
    distance from its estimate; with a recognition that needs more inliers than the fits
    have, none is kept."""
    robot_in_island = Pose2D(0.4, 0.2, 0.05)
    snap = PoseSnapshot(robot_in_island, np.diag([16.0, 16.0, 0.01]), 0.3, 0.1, None, 50.0)
    pts = _robot_points(T_WALLS, robot_in_island, np.random.default_rng(8))
    for floor, kept in ((0.85, True), (1.01, False)):
        revisit = dataclasses.replace(ExplorerConfig().revisit, accept_inlier_fraction=floor)
        rec = Recognizer(BuilderConfig(revisit=revisit))
        rec.remember(0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
        rec.remember(1, Pose2D(8.0, 0.0, 0.0), np.zeros((3, 3)))
        found = rec.recognize(pts, robot_in_island, snap, [_t_island(0), _t_island(1)],
                              star=True)
        assert found is None
        if not kept:
            assert rec.hypotheses == []
            continue
        assert sorted(h.island_id for h in rec.hypotheses) == [0, 1]
        for h in rec.hypotheses:
            assert math.hypot(h.pose.x - 0.4, h.pose.y - 0.2) < 0.15
            assert h.mahalanobis2 is not None
