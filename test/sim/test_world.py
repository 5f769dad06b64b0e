"""Worlds: exact spatial index, built-in worlds' geometry, world files and their errors."""

from __future__ import annotations

import copy
import itertools
import json
import math
from pathlib import Path

import numpy as np
import pytest
from island_msgs_py.raycast import raycast
from island_sim.core.world import World, WorldError, save_world
from island_sim.core.world_loader import load_world
from island_sim.core.worlds_builtin import BUILTIN_WORLDS, in_free_space


def _random_world(n: int, seed: int) -> World:
    rng = np.random.default_rng(seed)
    c = rng.uniform(0, 40, (n, 2))
    ang = rng.uniform(0, math.pi, n)
    length = rng.uniform(0.2, 4.0, n)
    segs = np.hstack([c, c + length[:, None] * np.stack([np.cos(ang), np.sin(ang)], axis=1)])
    segs[10] = segs[20]  # an exact duplicate: ties must go to the lowest index, as brute force
    segs[30] = segs[40, [2, 3, 0, 1]]  # a reversed duplicate
    segs[50] = [5.0, 5.0, 15.0, 5.0]  # axis-aligned, collinear pair
    segs[51] = [15.0, 5.0, 25.0, 5.0]
    return World(segs)


@pytest.mark.parametrize("max_range", [math.inf, 6.5, 0.4])
def test_index_agrees_exactly_with_brute_force(max_range: float) -> None:
    world = _random_world(600, 1)
    rng = np.random.default_rng(2)
    o = rng.uniform(-5, 45, (3000, 2))
    a = rng.uniform(-math.pi, math.pi, 3000)
    o[:50] = [10.0, 5.0]  # rays starting on a wall and along it
    a[:25] = 0.0
    # Directions on the index's 45 deg sector borders, negative and beyond 2 pi.
    a[50:250] = np.tile(np.arange(-8, 17) * (math.pi / 4), 8)[:200]
    o[250:300] = o[250:300].round()  # origins on cell corners
    fast = world.raycast(o, a, max_range)
    slow = raycast(world.segments, o, a, max_range)
    assert np.array_equal(fast.distance_m, slow.distance_m)
    assert np.array_equal(fast.segment, slow.segment)
    assert np.array_equal(fast.cos_incidence, slow.cos_incidence)
    assert np.array_equal(fast.normal_angle, slow.normal_angle)
    assert np.isfinite(fast.distance_m).any()
    # Second call uses the cached candidate lists: still identical.
    again = world.raycast(o, a, max_range)
    assert np.array_equal(again.distance_m, slow.distance_m)


def test_index_single_origin_broadcast_and_shape_errors() -> None:
    world = _random_world(200, 3)
    a = np.linspace(-math.pi, math.pi, 500)
    fast = world.raycast([20.0, 20.0], a)
    slow = raycast(world.segments, np.tile([20.0, 20.0], (500, 1)), a)
    assert np.array_equal(fast.distance_m, slow.distance_m)
    with pytest.raises(WorldError, match="origins"):
        world.raycast(np.zeros((3, 2)), np.zeros(5))


def test_world_is_immutable_and_validated() -> None:
    segs = np.array([[0.0, 0.0, 1.0, 0.0]])
    world = World(segs)
    segs[0, 0] = 5.0
    assert world.segments[0, 0] == 0.0  # copied
    with pytest.raises(ValueError):
        world.segments[0, 0] = 1.0
    with pytest.raises(WorldError, match="shape"):
        World(np.zeros((3, 3)))
    with pytest.raises(WorldError, match="segment 1 has a NaN"):
        World(np.array([[0.0, 0, 1, 0], [0, np.nan, 1, 1]]))
    assert World([]).segments.shape == (0, 4)
    assert World([]).bounds == (0.0, 0.0, 0.0, 0.0)
    big = load_world("paper_fig4")
    big.raycast([12.0, 9.0], [0.0])  # builds the index (which holds a lock)
    assert copy.deepcopy(big) is big and copy.copy(big) is big


def _clearance(world: World, x: float, y: float) -> float:
    a = np.linspace(0, 2 * math.pi, 72, endpoint=False)
    return float(world.raycast([x, y], a).distance_m.min())


@pytest.mark.parametrize("name", sorted(BUILTIN_WORLDS))
def test_builtin_start_pose_is_in_a_corridor_or_room(name: str) -> None:
    world = load_world(name)
    sp = world.start_pose
    assert in_free_space(name, sp.x, sp.y, margin_m=0.5)
    assert _clearance(world, sp.x, sp.y) >= 0.9
    # Facing along the corridor: the way ahead is longer than the way sideways.
    ahead = world.raycast([sp.x, sp.y], [sp.theta]).distance_m[0]
    side = world.raycast([sp.x, sp.y], [sp.theta + math.pi / 2]).distance_m[0]
    assert ahead > side or name == "square_room"
    assert load_world(name) is world  # generated once


def test_builtins_are_deterministic_and_sized() -> None:
    fig3, fig4 = load_world("paper_fig3"), load_world("paper_fig4")
    x0, y0, x1, y1 = fig3.bounds
    assert 25 <= x1 - x0 <= 32 and 25 <= y1 - y0 <= 32
    x0, y0, x1, y1 = fig4.bounds
    assert x1 - x0 >= 60 and y1 - y0 >= 40
    seg_len = np.hypot(*(fig4.segments[:, 2:4] - fig4.segments[:, 0:2]).T)
    assert seg_len.min() > 0.2


def _side_openings(world: World, path: list[tuple[float, float]], step: float) -> list[float]:
    """Widths [m] of openings in the walls on both sides of a corridor centre line."""
    widths: list[float] = []
    for (xa, ya), (xb, yb) in itertools.pairwise(path):
        n = max(2, int(math.hypot(xb - xa, yb - ya) / step))
        t = np.linspace(0, 1, n)
        pts = np.stack([xa + t * (xb - xa), ya + t * (yb - ya)], axis=1)
        heading = math.atan2(yb - ya, xb - xa)
        for side in (math.pi / 2, -math.pi / 2):
            r = world.raycast(pts, np.full(n, heading + side)).distance_m
            opening = r > 1.6  # the far wall of a 2 m corridor is 1 m away
            run = 0
            for flag in [*opening.tolist(), False]:
                if flag:
                    run += 1
                elif run:
                    widths.append(run * step)
                    run = 0
    return widths


def test_paper_fig4_has_a_loop_intersections_doors_and_dead_ends() -> None:
    world = load_world("paper_fig4")
    loop = [(9.0, 9.0), (61.0, 9.0), (61.0, 35.0), (9.0, 35.0), (9.0, 9.0)]
    # The loop's centre line is clear of walls all the way round (a hall follower circulates).
    for (xa, ya), (xb, yb) in itertools.pairwise(loop):
        for t in np.linspace(0, 1, 80):
            assert _clearance(world, xa + t * (xb - xa), ya + t * (yb - ya)) >= 0.95
    widths = _side_openings(world, loop, 0.05)
    corridors = [w for w in widths if 1.8 <= w <= 2.4]  # side corridors branching off the loop
    doors = [w for w in widths if 0.8 <= w <= 1.3]
    assert len(corridors) >= 3, widths  # T junctions on the loop's sides
    assert len(doors) >= 6, widths
    # T junctions at three loop corners, where a dead-end stub continues straight on.
    for x, y, th in [(9.0, 9.0, -math.pi / 2), (61.0, 9.0, 0.0), (61.0, 35.0, math.pi / 2)]:
        assert world.raycast([x, y], [th]).distance_m[0] > 3.0
    # A + crossing in the middle: long views in all four directions.
    r = world.raycast([35.0, 22.0], [0, math.pi / 2, math.pi, -math.pi / 2]).distance_m
    assert np.all(r > 5.0)
    # Dead-end corridor ends: a wall right across the corridor a few metres ahead.
    for x, y, th, expect in [(9.0, 6.0, -math.pi / 2, 4.0), (66.0, 9.0, 0.0, 4.0),
                             (61.0, 40.0, math.pi / 2, 3.0)]:
        ahead = world.raycast([x, y], [th]).distance_m[0]
        assert ahead == pytest.approx(expect, abs=1e-9)


def test_paper_fig3_has_plus_and_t_intersections() -> None:
    world = load_world("paper_fig3")
    # + at the centre: long views in all four directions.
    r = world.raycast([15.0, 15.0], [0, math.pi / 2, math.pi, -math.pi / 2]).distance_m
    assert np.all(r > 8.0)
    # T where V3 leaves H1 southwards: open east, west and south, wall to the north.
    r = world.raycast([23.0, 15.0], [0, math.pi / 2, math.pi, -math.pi / 2]).distance_m
    assert r[0] > 4 and r[2] > 4 and r[3] > 8 and r[1] == pytest.approx(1.0)


def test_save_and_load_roundtrip(tmp_path: Path) -> None:
    world = load_world("paper_fig3")
    for suffix in (".yaml", ".json"):
        path = save_world(world, tmp_path / f"sub/fig3{suffix}")
        back = load_world(path)
        assert np.array_equal(back.segments, world.segments)
        assert back.name == "paper_fig3"
        assert back.start_pose == world.start_pose
    assert not list((tmp_path / "sub").glob(".*"))  # no temp files left behind


def test_world_file_without_start_pose_gets_an_enclosed_one(tmp_path: Path) -> None:
    # A 6 x 4 m room next to a stray wall outside it.
    segs = [[0, 0, 6, 0], [6, 0, 6, 4], [6, 4, 0, 4], [0, 4, 0, 0], [20, -5, 20, 30]]
    path = tmp_path / "room.yaml"
    path.write_text(json.dumps({"segments": segs}))  # JSON is valid YAML
    world = load_world(path)
    assert world.name == "room"
    assert 0.5 < world.start_pose.x < 5.5 and 0.5 < world.start_pose.y < 3.5


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    ("name", "text", "match"),
    [
        ("a.yaml", "name: x\n", "missing key 'segments'"),
        ("b.yaml", "segments: [[0, 0, .nan, 1]]\n", "segment 0 has a NaN"),
        ("c.json", '{"segments": [[0, 0, 1, 1], [0, 0, Infinity, 1]]}', "segment 1 has a NaN"),
        ("d.yaml", "segments: [[0, 0, 1, 1], [2, 2, 2, 2]]\n", "segment 1 has zero length"),
        ("e.yaml", "segments: [[0, 0, 1]]\n", r"segment 0 must be \[x1, y1, x2, y2\]"),
        ("f.yaml", "segments: [[0, 0, a, 1]]\n", "non-numeric"),
        ("g.yaml", "segments: []\n", "empty"),
        ("h.yaml", "segments: [[0, 0, 1, 1]]\nstart_pose: [1, 2]\n", "start_pose"),
        ("i.yaml", "segments: [[0, 0, 1, 1]]\nstart_pose: [1, 2, .inf]\n", "start_pose"),
        ("j.yaml", "- 1\n- 2\n", "mapping"),
        ("k.yaml", "segments: [[0, 0\n", "not valid YAML"),
        ("l.json", "{nope", "not valid JSON"),
        ("m.txt", "segments: []\n", "unknown world file extension '.txt'"),
        ("n.yaml", "segments: 3\n", "must be a list"),
    ],
)
def test_world_file_errors_name_the_file_and_problem(
    tmp_path: Path, name: str, text: str, match: str
) -> None:
    path = _write(tmp_path, name, text)
    with pytest.raises(WorldError, match=match) as info:
        load_world(path)
    assert name in str(info.value)


def test_missing_file_and_unknown_builtin(tmp_path: Path) -> None:
    with pytest.raises(WorldError, match="no such file"):
        load_world(tmp_path / "absent.yaml")
    with pytest.raises(WorldError, match="paper_fig4"):  # lists the built-ins
        load_world("paper_fig9")


def test_map_server_yaml(tmp_path: Path) -> None:
    img = np.full((20, 30), 255, dtype=np.uint8)
    img[0, :] = img[-1, :] = 0
    img[:, 0] = img[:, -1] = 0
    (tmp_path / "m.pgm").write_bytes(b"P5\n30 20\n255\n" + img.tobytes())
    path = _write(tmp_path, "m.yaml", "image: m.pgm\nresolution: 0.5\norigin: [-2.0, 1.0, 0.0]\n")
    world = load_world(path)
    x0, y0, x1, y1 = world.bounds
    assert (x0, y0, x1, y1) == pytest.approx((-2.0, 1.0, 13.0, 11.0))
    assert -1.5 < world.start_pose.x < 12.5
    sp = world.start_pose
    assert 0.0 < sp.y - 1.0 < 10.0
    assert np.isfinite(world.raycast([sp.x, sp.y], [sp.theta]).distance_m[0])


def test_index_far_origins_fall_back_to_brute_force() -> None:
    world = _random_world(300, 4)
    rng = np.random.default_rng(9)
    o = rng.uniform(0, 40, (300, 2))
    a = rng.uniform(-math.pi, math.pi, 300)
    o[:150:2] = [1e12, 20.0]  # far east, looking west: hits the world
    o[1:150:2] = [-1e12, 20.0]
    a[:150:2], a[1:150:2] = math.pi, 0.0
    fast = world.raycast(o, a)
    slow = raycast(world.segments, o, a)
    assert np.array_equal(fast.distance_m, slow.distance_m)
    assert np.isfinite(slow.distance_m[:150]).any()
    only_far = world.raycast(o[:150], a[:150])
    assert np.array_equal(only_far.segment, slow.segment[:150])
    assert world.raycast(np.zeros((0, 2)), np.zeros(0)).distance_m.shape == (0,)
