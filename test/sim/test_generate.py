"""Generated offices: deterministic per (seed, scale), connected, with the loops they claim."""

from __future__ import annotations

import numpy as np
import pytest
from island_sim.core.freespace import free_space, largest_enclosed_region
from island_sim.core.generate import REFERENCE_AREA_M2, generate_office, parse_spec
from island_sim.core.places import WorldPlaceKind, world_places
from island_sim.core.world import WorldError
from island_sim.core.world_loader import load_world


def _area_m2(world: object) -> float:
    x0, y0, x1, y1 = world.bounds  # type: ignore[attr-defined]
    return (x1 - x0) * (y1 - y0)


def test_same_seed_and_scale_give_the_same_world_and_other_seeds_differ() -> None:
    a = generate_office(7, 2.0)
    b = generate_office(7, 2.0)
    assert np.array_equal(a.world.segments, b.world.segments)
    assert a.world.start_pose == b.world.start_pose and a.cycle_rank == b.cycle_rank
    assert not np.array_equal(a.world.segments, generate_office(8, 2.0).world.segments)
    assert not np.array_equal(a.world.segments, generate_office(7, 1.0).world.segments)


@pytest.mark.parametrize(("seed", "scale"), [(1, 1.0), (2, 1.0), (3, 2.0), (4, 4.0)])
def test_a_generated_office_is_connected_and_has_the_cycle_rank_it_claims(
        seed: int, scale: float) -> None:
    office = generate_office(seed, scale)
    space = free_space(office.world)
    # connected: the free space reachable from the start is the largest enclosed region, and
    # it holds (nearly) all the free rectangles' area (minus the robot's clearance)
    assert space.area_m2 == pytest.approx(largest_enclosed_region(office.world).area_m2)
    drawn = sum((x1 - x0) * (y1 - y0) for x0, y0, x1, y1 in office.free_rects)
    assert 0.5 * drawn < space.area_m2 < drawn
    assert office.cycle_rank == space.cycle_rank
    assert office.corridor_loops >= 1
    assert office.rooms >= 10
    # the start lies in a corridor (2 m wide: clearance about 1 m)
    start = office.world.start_pose
    ranges = office.world.raycast([start.x, start.y], [start.theta + np.pi / 2,
                                                       start.theta - np.pi / 2]).distance_m
    assert ranges.sum() == pytest.approx(2.0, abs=0.01)


def test_offices_have_junctions_dead_ends_and_rooms_and_grow_with_the_scale() -> None:
    small, large = generate_office(5, 1.0), generate_office(5, 4.0)
    wp = world_places(small.world)
    kinds = [p.kind for p in wp.places]
    assert kinds.count(WorldPlaceKind.JUNCTION) >= 10
    assert kinds.count(WorldPlaceKind.END) >= small.rooms  # every room, and the dead ends
    assert 0.7 * REFERENCE_AREA_M2 < _area_m2(small.world) < 1.3 * REFERENCE_AREA_M2
    assert 3.0 < _area_m2(large.world) / _area_m2(small.world) < 5.0


def test_a_generated_world_loads_from_its_spec() -> None:
    world = load_world("gen:office:seed=3,scale=2")
    assert np.array_equal(world.segments, generate_office(3, 2.0).world.segments)
    assert world.name == "gen_office_seed3_scale2"
    assert parse_spec("gen:office") == ("office", 1, 1.0)


@pytest.mark.parametrize(("spec", "match"), [
    ("gen:castle:seed=1", "unknown generated world kind"),
    ("gen:office:seed=x", "seed must be a number"),
    ("gen:office:size=2", "unknown parameter"),
    ("gen:office:scale=0", "scale must be in"),
    ("gen:office:scale=nan", "scale must be in"),
])
def test_bad_generated_specs_are_clear_errors(spec: str, match: str) -> None:
    with pytest.raises(WorldError, match=match):
        load_world(spec)
