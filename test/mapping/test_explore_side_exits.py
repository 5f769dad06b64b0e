"""Side exits while exploring by the map: openings seen beside an edge become exits of the island
the edge left (strategy prefix and side), duplicates are merged, and the explorer reaches one by
its prefix and a turn (the T world's branch, which has no island at its junction)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from island_mapping.core.builder.opening_config import OpeningConfig
from island_mapping.core.explore import ExplorerConfig
from island_mapping.core.explore.openings import (
    Opening,
    OpeningWatch,
    approach,
    chained_frames,
    exit_pose,
    new_side_exits,
)
from island_mapping.core.graph import TopoGraph
from island_mapping.evaluation.explore_exits import explore_by_exits
from island_mapping.evaluation.navigate import SimSetup
from island_msgs_py.hall_perception import Perception
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    Exit,
    ExitSide,
    ExitState,
    Island,
    LineModel,
    ModelType,
    NewExit,
    PrimitiveKind,
)
from island_sim.core.world_loader import load_world

CFG = ExplorerConfig()
S = ControlStrategy.parse


def seen(left: bool, right: bool = False) -> Perception:
    return Perception(front_m=5.0, front_free_m=5.0, left_open=left, right_open=right,
                      left_dist_m=1.0, right_dist_m=1.0, wall_angle_rad=0.0)


def drive(watch: OpeningWatch, left_open_m: tuple[float, float], total_m: float = 12.0,
          turn_at_m: float | None = None) -> None:
    """The follower drives straight `total_m` in 5 cm steps; the left side is open between
    the two distances [m]; optionally the heading swings 40 deg at turn_at_m."""
    for k in range(1, round(total_m / 0.05) + 1):
        s = 0.05 * k
        heading = math.radians(40.0) if turn_at_m is not None and s >= turn_at_m else 0.0
        watch.update(seen(left_open_m[0] <= s <= left_open_m[1]), S(f"Go {round(100 * s)}"),
                     heading)


def island(i: int, *exits: Exit) -> Island:
    rng = np.random.default_rng(i)
    return Island(i, LineModel(rng.uniform(-3, 3, (2, 4))), ModelType.LINE, 0.6, float(i),
                  exits=exits)


def test_an_opening_passed_becomes_a_prefix_and_a_side() -> None:
    watch = OpeningWatch(CFG, S("Rot 90, Go 150"))
    drive(watch, (5.0, 6.2))
    [o] = watch.finish()
    assert o.side is ExitSide.LEFT
    assert abs(o.width_m - 1.2) < 0.06
    # the handover's prefix, then the follower's record to the opening's middle
    assert o.prefix.steps[0].kind is PrimitiveKind.ROT and o.prefix.steps[0].value == 90
    assert abs(o.prefix.steps[1].value - (150 + 560)) <= 5
    pose = exit_pose(o.prefix, o.side)
    assert abs(pose.x) < 0.05 and abs(pose.y - 7.1) < 0.06  # north of the origin, facing west
    assert abs(abs(pose.theta) - math.pi) < 1e-6


def test_narrow_gaps_turns_and_an_open_end_are_not_openings() -> None:
    short = OpeningWatch(CFG, S(""))
    drive(short, (5.0, 5.3))  # 0.3 m < side_min_width_m
    turned = OpeningWatch(CFG, S(""))
    drive(turned, (5.0, 7.0), turn_at_m=6.0)  # the follower turned into it
    still = OpeningWatch(CFG, S(""))
    drive(still, (10.0, 13.0))  # open until the edge ended
    assert short.finish() == turned.finish() == still.finish() == []


def test_duplicates_are_merged_and_openings_at_islands_dropped() -> None:
    """Island 1 lies 20 m east of island 0 (edge 0 -> 1, Go 2000). An opening 5.6 m along
    (left) from 0 is new; the same one seen again from 0 (6 m), or from island 1 driving back
    west (right, 14.4 m), is not; one 19 m along is island 1's place."""
    g = TopoGraph.from_parts([island(0, Exit(0, 0.0, 1.2, ExitState.EXPLORED, (0, 1))),
                              island(1)], [Edge(0, 1, S("Go 2000"), 20.0, source_exit=0)])
    frames = chained_frames(g, 1, 100.0)
    assert abs(frames[0].x + 20.0) < 1e-9  # island 0 seen from 1: 20 m behind
    first = Opening(S("Go 560"), ExitSide.LEFT, 1.2)
    added = new_side_exits(g, 0, [first, Opening(S("Go 600"), ExitSide.LEFT, 1.0),
                                  Opening(S("Go 1900"), ExitSide.RIGHT, 1.0),
                                  Opening(S("Go 560"), ExitSide.RIGHT, 1.0)], CFG)
    assert [(e.index, str(e.prefix), e.side) for e in added] == [
        (1, "Go 560", ExitSide.LEFT), (2, "Go 560", ExitSide.RIGHT)]  # the other side: new
    for ex in added:
        g.add_exit(NewExit(0, ex))
    again = new_side_exits(g, 1, [Opening(S("Rot 180, Go 1440"), ExitSide.RIGHT, 1.1)], CFG)
    assert again == []
    assert new_side_exits(g, 0, [first], CFG) == []


def test_the_approach_leaves_the_last_metres_to_perception() -> None:
    assert approach(S("Rot 90, Go 800"), 1.5) == (S("Rot 90, Go 650"), 1.5)
    assert approach(S("Go 100"), 1.5) == (S(""), 1.0)


def test_the_explorer_reaches_a_branch_by_its_side_exit() -> None:
    """The T world: the follower drives the corridor through the junction without an island;
    the branch north becomes a side exit of island 0, and the explorer drives its prefix,
    turns north and hands over: the branch gets an island, by an edge from island 0."""
    setup = SimSetup(world=load_world("t_junction"))
    no_openings = ExplorerConfig(opening=OpeningConfig(enabled=False), accept_on_legs=False)
    run = explore_by_exits(setup, 600.0, explorer_cfg=no_openings, rng=np.random.default_rng(1))
    assert run.done
    side = [e for e in run.graph.get_island(0).exits if e.is_side]
    assert len(side) == 1 and side[0].side is ExitSide.LEFT
    assert side[0].prefix is not None and 7.0 < side[0].prefix.length_m < 9.0  # x = 9-11 m
    assert side[0].state is ExitState.EXPLORED and side[0].edge is not None
    branch = run.graph.get_island(side[0].edge[1])
    assert branch.origin_truth is not None and branch.origin_truth.y > 5.0
    steps = run.graph.get_edge(0, branch.id).strategy.steps
    go = next(s for s in steps if s.kind is PrimitiveKind.GO)
    turn = steps[steps.index(go) + 1]
    assert abs(go.metres - side[0].prefix.length_m) < 1.6  # the prefix, then the turn
    assert turn.kind is PrimitiveKind.ROT and 60 <= turn.value <= 120
    plain = explore_by_exits(setup, 600.0, explorer_cfg=dataclasses.replace(
        no_openings, side_exits=False), rng=np.random.default_rng(1))
    assert len(plain.graph) == 2 and len(run.graph) == 3
    # With side openings as places (the default) the follower stops at the branch and the
    # island stands in its mouth: no side exit is needed to learn of it.
    direct = explore_by_exits(setup, 600.0, rng=np.random.default_rng(1))
    mouths = [i for i in direct.graph.islands() if i.origin_truth is not None
              and i.origin_truth.y > 1.0]
    assert mouths and all(not e.is_side or e.prefix is not None for i in mouths for e in i.exits)
