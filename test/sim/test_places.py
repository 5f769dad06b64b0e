"""Ground-truth places and the cycle rank of worlds, from their geometry alone."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_msgs_py.types import Pose2D
from island_sim.core.freespace import (
    FreeSpaceConfig,
    FreeSpaceError,
    default_start_pose,
    free_space,
    known_free_allowed,
)
from island_sim.core.importers import rectangles_to_segments
from island_sim.core.places import (
    PlacesConfig,
    WorldPlaceKind,
    WorldPlaces,
    world_places,
    zhang_suen,
)
from island_sim.core.world import World
from island_sim.core.world_loader import load_world

JUNCTION, END = WorldPlaceKind.JUNCTION, WorldPlaceKind.END
TOL_M = 0.3
"""Where a person would put a place vs the rule's place [m] (raster cell 0.1 m + skeleton)."""


def _world(rects: list[tuple[float, float, float, float]], start: tuple[float, float]) -> World:
    return World(rectangles_to_segments(rects, 0.25), name="test",
                 start_pose=Pose2D(start[0], start[1], 0.0))


def _assert_places(found: WorldPlaces, expected: list[tuple[WorldPlaceKind, float, float]]) -> None:
    """Every expected place has one found place of its kind within TOL_M, and nothing else."""
    got = [(p.kind, p.x_m, p.y_m) for p in found.places]
    assert len(got) == len(expected), got
    for kind, x, y in expected:
        near = [g for g in got if g[0] is kind and math.hypot(g[1] - x, g[2] - y) <= TOL_M]
        assert len(near) == 1, (kind, x, y, got)


def test_t_junction_has_the_junction_and_three_dead_ends() -> None:
    # east-west 0..20 x 0..2, branch north 9..11 x 2..12: dead ends 1 m (the clearance) inside
    _assert_places(world_places(load_world("t_junction")),
                   [(JUNCTION, 10.0, 1.0), (END, 1.0, 1.0), (END, 19.0, 1.0), (END, 10.0, 11.0)])


def test_corridor_has_two_dead_ends_and_no_loop() -> None:
    wp = world_places(load_world("corridor"))
    _assert_places(wp, [(END, 1.0, 1.0), (END, 19.0, 1.0)])
    assert wp.cycle_rank == 0


def test_a_crossing_is_one_junction_with_four_ends() -> None:
    world = _world([(0, 9, 20, 11), (9, 0, 11, 20)], (3, 10))
    _assert_places(world_places(world), [(JUNCTION, 10, 10), (END, 1, 10), (END, 19, 10),
                                         (END, 10, 1), (END, 10, 19)])


def test_an_l_bend_is_no_place_only_its_two_ends_are() -> None:
    world = _world([(0, 0, 12, 2), (10, 2, 12, 14)], (3, 1))
    _assert_places(world_places(world), [(END, 1, 1), (END, 11, 13)])


def test_a_room_off_a_corridor_is_one_end_and_its_door_a_junction() -> None:
    # corridor 0..20 x 0..2; room 6..14 x 2.5..8.5 with a 1 m door at x 9.5..10.5
    world = _world([(0, 0, 20, 2), (6, 2.5, 14, 8.5), (9.5, 2, 10.5, 2.5)], (2, 1))
    _assert_places(world_places(world), [(JUNCTION, 10, 1), (END, 1, 1), (END, 19, 1),
                                         (END, 10, 5.5)])


def test_places_within_two_metres_in_sight_merge_into_one() -> None:
    # two 1 m side branches 1.5 m apart along a corridor: one junction, not two
    world = _world([(0, 0, 20, 2), (8, 2, 9, 8), (9.5, 2, 10.5, 8)], (2, 1))
    wp = world_places(world)
    near = [p for p in wp.places if p.kind is JUNCTION and 7 < p.x_m < 13]
    assert len(near) == 1
    wide = world_places(world, cfg=PlacesConfig(merge_radius_m=1.0))
    assert len([p for p in wide.places if p.kind is JUNCTION and 7 < p.x_m < 13]) == 2


def test_ring_corridor_has_cycle_rank_one() -> None:
    ring = _world([(0, 0, 20, 2), (0, 10, 20, 12), (0, 0, 2, 12), (18, 0, 20, 12)], (5, 1))
    assert free_space(ring).cycle_rank == 1


def test_paper_fig4_corridors_form_three_loops_and_its_places() -> None:
    wp = world_places(load_world("paper_fig4"))
    assert wp.cycle_rank == 3
    # 7 corridor junctions (the north-west corner is a plain bend) + 12 doorways; 13 rooms and
    # 4 dead ends
    assert len(wp.junctions) == 19
    assert len(wp.places) - len(wp.junctions) == 13 + 4
    kinds = {(round(p.x_m), round(p.y_m)): p.kind for p in wp.places}
    for xy in [(9, 9), (9, 22), (35, 22), (35, 9), (35, 35), (61, 9), (61, 35)]:
        assert kinds.get(xy) is JUNCTION, xy
    assert (9, 35) not in kinds


def test_a_room_with_two_doors_is_a_loop_and_one_with_doors_close_together_is_not() -> None:
    base = [(0, 0, 30, 2), (5, 2.5, 25, 8.5)]
    far = _world([*base, (7, 2, 8, 2.5), (20, 2, 21, 2.5)], (2, 1))
    assert free_space(far).cycle_rank == 1
    # 0.5 m of wall between the doors: a post the robot cannot even pass around
    near = _world([*base, (7, 2, 8, 2.5), (8.5, 2, 9.5, 2.5)], (2, 1))
    assert free_space(near).cycle_rank == 0


def test_cycle_rank_counts_only_holes_the_robot_drives_around() -> None:
    hall = _world([(0, 0, 30, 12)], (2, 2))
    pillar = World(np.vstack([hall.segments, [[14, 5, 15, 5], [15, 5, 15, 6], [15, 6, 14, 6],
                                              [14, 6, 14, 5]]]), start_pose=hall.start_pose)
    block = World(np.vstack([hall.segments, [[10, 4, 20, 4], [20, 4, 20, 8], [20, 8, 10, 8],
                                             [10, 8, 10, 4]]]), start_pose=hall.start_pose)
    assert free_space(pillar).cycle_rank == 0  # a 1 m pillar: furniture
    assert free_space(pillar, cfg=FreeSpaceConfig(min_hole_extent_m=0.0)).cycle_rank == 1
    assert free_space(block).cycle_rank == 1


def test_zhang_suen_thins_a_bar_to_its_centre_line() -> None:
    bar = np.zeros((12, 40), dtype=bool)
    bar[3:9, 2:38] = True
    skel = zhang_suen(bar)
    rows = np.nonzero(skel[:, 10:30])[0]
    assert skel.sum() < bar.sum() / 4
    assert set(rows.tolist()) <= {5, 6}  # one line along the middle
    assert np.all(skel[:, 10:30].sum(axis=0) == 1)


def test_a_start_inside_a_wall_or_a_placeless_ring_is_a_clear_error() -> None:
    world = load_world("t_junction")
    with pytest.raises(FreeSpaceError, match="no free space within"):
        world_places(world, Pose2D(5.0, -3.0, 0.0))
    ring = _world([(0, 0, 20, 2), (0, 10, 20, 12), (0, 0, 2, 12), (18, 0, 20, 12)], (5, 1))
    ring = World(ring.segments, start_pose=Pose2D(5, 1, 0))
    with pytest.raises(FreeSpaceError, match="no place"):
        world_places(ring)


def test_default_start_is_in_the_largest_region_not_a_closed_room() -> None:
    # a closed 9 x 9 m room (the widest open space) beside a longer corridor system
    world = _world([(0, 0, 40, 2), (19, 2, 21, 20), (45, 0, 54, 9)], (1, 1))
    sp = default_start_pose(world)
    assert not (45 <= sp.x <= 54), sp
    space = free_space(world, sp)
    assert space.area_m2 > 60.0  # the corridors, not the room
    assert np.isfinite(world.raycast([sp.x, sp.y], [sp.theta]).distance_m[0])


def test_known_free_pixels_bound_the_free_space() -> None:
    world = _world([(0, 0, 20, 10)], (2, 2))
    known = np.zeros((100, 200), dtype=bool)  # 0.1 m pixels: only x < 10 m is known free
    known[:, :100] = True
    all_free = free_space(world).area_m2
    half = free_space(world, allowed=known_free_allowed(known, 0.1)).area_m2
    assert half == pytest.approx(all_free / 2, rel=0.1)


def test_geodesic_path_goes_around_walls() -> None:
    world = load_world("t_junction")
    space = free_space(world)
    straight, _ = space.shortest_path_m((2.0, 1.0), (18.0, 1.0))
    assert straight == pytest.approx(16.0, abs=0.2)
    around, path = space.shortest_path_m((2.0, 1.0), (10.0, 11.0))
    by_corner = math.hypot(9.0 - 2.0, 2.0 - 1.0) + math.hypot(10.0 - 9.0, 11.0 - 2.0)
    assert by_corner <= around <= 1.05 * by_corner  # round the corner (9, 2), not through it
    assert path.shape[1] == 2 and len(path) >= 3
