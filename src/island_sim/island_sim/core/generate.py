"""Generated office worlds, deterministic from (seed, scale) (numpy only).

An office is a lattice of 2 m corridors: corridor lines cross at lattice nodes 13-19 m apart;
a random spanning tree of the lattice's edges keeps every node connected, and about half of
the remaining edges are added back as loops (+ and T junctions where three or four meet).
Half of the edges left out become dead-end stubs from one of their nodes, and a few boundary
nodes get a stub pointing out of the lattice. Rooms (3.5-6 m deep, 4-8 m wide, 0.5 m walls)
line the corridors: each lattice cell takes rooms along one pair of its opposite corridors,
and the corridors on the lattice's boundary get rooms outside; every room has a 1 m door onto
its corridor, and about a third of the rooms wide enough get a second door (a loop through
the room). Everything is drawn as free rectangles on a 0.25 m grid and traced into walls
(`importers.rectangles_to_segments`), like the built-in worlds.

The world's cycle rank is known by construction: the corridor lattice's independent cycles
(edges - nodes + 1) plus one per two-door room. The scale multiplies the area: scale 1 is
about the area of `paper_fig4` (62 x 41 m).

Spec strings (accepted wherever a world is, see `world_loader.load_world`):
`gen:office:seed=3,scale=2` (defaults: seed 1, scale 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from island_msgs_py.json_checks import describe
from island_msgs_py.limits import MAX_INT_DIGITS
from island_msgs_py.types import Pose2D

from island_msgs_py import inputs
from island_sim.core.importers import rectangles_to_segments
from island_sim.core.world import World, WorldError

Rect = tuple[float, float, float, float]  # (x0, y0, x1, y1) [m]

SPEC_PREFIX = "gen:"
GRID_M = 0.25
"""Every corner lies on this grid [m] (the rasterization of the free rectangles)."""
CORRIDOR_M = 2.0
DOOR_M = 1.0
WALL_M = 0.5
REFERENCE_AREA_M2 = 62.0 * 41.0
"""Area of paper_fig4's bounding box: scale 1 [m^2]."""
SPACING_M = (13, 19)
"""Distance between neighbouring corridor lines, in whole metres within these bounds [m]."""
ROOM_DEPTH_M = (3.5, 6.0)
ROOM_WIDTH_M = (4.0, 8.0)
MIN_ROOM_WIDTH_M = 3.0
"""A leftover stretch narrower than this joins the previous room [m]."""
TWO_DOOR_MIN_WIDTH_M = 6.5
TWO_DOOR_GAP_M = 3.5
"""Door centres of a two-door room are at least this far apart, so the wall between them is a
loop of the building, not a pillar (2.5 m of wall) [m]."""
TWO_DOOR_PROB = 0.35
NO_ROOM_PROB = 0.15
LOOP_FRACTION = (0.35, 0.65)
"""Fraction of the non-tree lattice edges added back as corridor loops [-]."""
STUB_PROB = 0.5
STUB_FRACTION = (0.3, 0.45)
OUTWARD_STUB_LENGTH_M = (4.0, 7.0)
OUTWARD_STUBS = (1, 3)
START_OFFSET_M = 1.5
"""The start pose lies this far along a corridor from its first lattice node [m]."""
MAX_SCALE = 16.0


@dataclass(frozen=True)
class GeneratedOffice:
    """A generated world and what its construction says about it."""

    world: World
    seed: int
    scale: float
    cycle_rank: int
    corridor_loops: int
    rooms: int
    two_door_rooms: int
    dead_ends: int
    free_rects: tuple[Rect, ...]


def _snap(v: float) -> float:
    return round(v / GRID_M) * GRID_M


class _Builder:
    """The drawing state of one office (lattice lines, free rectangles, counts)."""

    def __init__(self, rng: np.random.Generator, xs: list[float], ys: list[float]) -> None:
        self.rng = rng
        self.xs, self.ys = xs, ys
        self.rects: list[Rect] = []
        self.rooms = 0
        self.two_door = 0

    def corridor(self, a: tuple[float, float], b: tuple[float, float]) -> None:
        h = CORRIDOR_M / 2
        self.rects.append((min(a[0], b[0]) - h, min(a[1], b[1]) - h,
                           max(a[0], b[0]) + h, max(a[1], b[1]) + h))

    def rooms_along(self, lo: float, hi: float, line: float, horizontal: bool, side: int,
                    max_depth: float) -> None:
        """Rooms along a corridor on `line` (y for a horizontal corridor) from lo to hi (the
        corridor's extent between its nodes), on `side` (+1: above/right, -1: below/left)."""
        if max_depth < ROOM_DEPTH_M[0]:
            return
        start = lo + CORRIDOR_M / 2 + WALL_M
        end = hi - CORRIDOR_M / 2 - WALL_M
        widths: list[float] = []
        pos = start
        while end - pos >= MIN_ROOM_WIDTH_M:
            w = _snap(float(self.rng.uniform(*ROOM_WIDTH_M)))
            if end - (pos + w) < MIN_ROOM_WIDTH_M + WALL_M:
                w = end - pos
            widths.append(w)
            pos += w + WALL_M
        pos = start
        face = line + side * (CORRIDOR_M / 2)
        for w in widths:
            depth = _snap(float(self.rng.uniform(ROOM_DEPTH_M[0], max_depth)))
            if self.rng.random() >= NO_ROOM_PROB:
                self._room(pos, pos + w, face, side, depth, horizontal)
            pos += w + WALL_M

    def _room(self, a: float, b: float, face: float, side: int, depth: float,
              horizontal: bool) -> None:
        near = face + side * WALL_M
        far = near + side * depth
        rects = [(a, min(near, far), b, max(near, far))]
        doors = [_snap(float(self.rng.uniform(a + DOOR_M, b - DOOR_M)))]
        if b - a >= TWO_DOOR_MIN_WIDTH_M and self.rng.random() < TWO_DOOR_PROB:
            first = _snap(float(self.rng.uniform(a + DOOR_M, b - DOOR_M - TWO_DOOR_GAP_M)))
            doors = [first, _snap(float(self.rng.uniform(first + TWO_DOOR_GAP_M,
                                                          b - DOOR_M)))]
            self.two_door += 1
        for c in doors:
            rects.append((c - DOOR_M / 2, min(face, near), c + DOOR_M / 2, max(face, near)))
        if not horizontal:  # drawn as if horizontal: swap x and y
            rects = [(y0, x0, y1, x1) for x0, y0, x1, y1 in rects]
        self.rects.extend(rects)
        self.rooms += 1


def _spanning_tree(rng: np.random.Generator, n_nodes: int,
                   edges: list[tuple[int, int]]) -> tuple[list[int], list[int]]:
    """Indices of a random spanning tree's edges (randomized Kruskal) and of the others."""
    parent = list(range(n_nodes))

    def find(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    tree, rest = [], []
    for k in rng.permutation(len(edges)).tolist():
        a, b = (find(v) for v in edges[k])
        if a != b:
            parent[a] = b
            tree.append(k)
        else:
            rest.append(k)
    return tree, rest


def _lattice_lines(rng: np.random.Generator, scale: float) -> tuple[list[float], list[float]]:
    """Corridor line coordinates [m]: as many gaps as fill the scaled area."""
    aspect = float(rng.uniform(1.2, 1.6))
    outer = 2 * (CORRIDOR_M / 2 + WALL_M + ROOM_DEPTH_M[1] + WALL_M)
    width = math.sqrt(scale * REFERENCE_AREA_M2 * aspect)
    height = scale * REFERENCE_AREA_M2 / width
    mean = sum(SPACING_M) / 2
    lines = []
    for extent in (width, height):
        gaps = max(1, round((extent - outer) / mean))
        base = (extent - outer) / gaps  # fill the extent, each gap varied by up to 2 m
        steps = np.clip(np.round(base + rng.uniform(-2.0, 2.0, size=gaps)), *SPACING_M)
        lines.append([float(v) for v in np.concatenate([[0], np.cumsum(steps)])])
    return lines[0], lines[1]


def generate_office(seed: int, scale: float = 1.0) -> GeneratedOffice:
    """The office world of (seed, scale); WorldError for a scale outside (0, 16]."""
    if not (isinstance(scale, int | float) and math.isfinite(scale) and 0 < scale <= MAX_SCALE):
        raise WorldError(f"generated office: scale must be in (0, {MAX_SCALE:g}], got {scale!r}")
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, round(scale * 1000)])
    xs, ys = _lattice_lines(rng, scale)
    nx, ny = len(xs), len(ys)

    def node(i: int, j: int) -> int:
        return j * nx + i

    edges = [(node(i, j), node(i + 1, j)) for j in range(ny) for i in range(nx - 1)]
    edges += [(node(i, j), node(i, j + 1)) for j in range(ny - 1) for i in range(nx)]
    tree, rest = _spanning_tree(rng, nx * ny, edges)
    n_loops = round(len(rest) * float(rng.uniform(*LOOP_FRACTION)))
    if rest:
        n_loops = max(1, n_loops)
    order = rng.permutation(len(rest)).tolist()
    loops = [rest[k] for k in order[:n_loops]]
    dropped = [rest[k] for k in order[n_loops:]]
    present = set(tree) | set(loops)
    b = _Builder(rng, xs, ys)

    def xy(n: int) -> tuple[float, float]:
        return xs[n % nx], ys[n // nx]

    for k in sorted(present):
        b.corridor(xy(edges[k][0]), xy(edges[k][1]))
    degree = np.zeros(nx * ny, dtype=np.int64)
    for k in present:
        degree[list(edges[k])] += 1
    dead_ends = int(np.sum(degree == 1))
    for k in sorted(dropped):
        if rng.random() < STUB_PROB:
            a, c = edges[k] if rng.random() < 0.5 else edges[k][::-1]
            pa, pc = xy(a), xy(c)
            f = float(rng.uniform(*STUB_FRACTION))
            b.corridor(pa, (_snap(pa[0] + f * (pc[0] - pa[0])), _snap(pa[1] + f * (pc[1] - pa[1]))))
            dead_ends += 1 - int(degree[a] == 1)  # a stub off a dead end just lengthens it
            degree[a] += 1
    dead_ends += _outward_stubs(b, rng, nx, ny, degree)
    _add_rooms(b, rng, edges, present, nx, ny)
    corridor_loops = len(present) - nx * ny + 1
    start = _start_pose(xs, ys, edges, present, nx)
    name = f"gen_office_seed{seed}_scale{scale:g}"

    world = World(rectangles_to_segments(b.rects, GRID_M), name=name, start_pose=start)
    return GeneratedOffice(world, int(seed), float(scale), corridor_loops + b.two_door,
                           corridor_loops, b.rooms, b.two_door, dead_ends, tuple(b.rects))


def _outward_stubs(b: _Builder, rng: np.random.Generator, nx: int, ny: int,
                   degree: np.ndarray) -> int:
    """Dead-end stubs pointing out of the lattice from a few boundary nodes; the number of
    dead ends they add (one off a dead-end node only moves that dead end)."""
    sides = []
    for i in range(nx):
        sides += [(i, 0, 0.0, -1.0), (i, ny - 1, 0.0, 1.0)]
    for j in range(ny):
        sides += [(0, j, -1.0, 0.0), (nx - 1, j, 1.0, 0.0)]
    n = int(rng.integers(OUTWARD_STUBS[0], OUTWARD_STUBS[1] + 1))
    picks = rng.choice(len(sides), size=min(n, len(sides)), replace=False)
    added = 0
    for k in sorted(picks.tolist()):
        i, j, dx, dy = sides[k]
        length = _snap(float(rng.uniform(*OUTWARD_STUB_LENGTH_M)))
        x, y = b.xs[i], b.ys[j]
        b.corridor((x, y), (x + dx * length, y + dy * length))
        added += 1 - int(degree[j * nx + i] == 1)
        degree[j * nx + i] += 1
    return added


def _add_rooms(b: _Builder, rng: np.random.Generator, edges: list[tuple[int, int]],
               present: set[int], nx: int, ny: int) -> None:
    """Rooms in every lattice cell along one pair of opposite corridors, and outside the
    boundary corridors."""
    have = {edges[k] for k in present}
    for j in range(ny - 1):
        for i in range(nx - 1):
            _cell_rooms(b, rng, have, i, j, nx)
    _outer_rooms(b, have, nx, ny)


def _cell_rooms(b: _Builder, rng: np.random.Generator, have: set[tuple[int, int]], i: int,
                j: int, nx: int) -> None:
    """Rooms of lattice cell (i, j): along its south and north corridors or (even odds) its
    west and east ones, as deep as leaves a wall between facing rooms."""
    xs, ys = b.xs, b.ys
    n00, n10, n01 = j * nx + i, j * nx + i + 1, (j + 1) * nx + i
    n11 = n01 + 1
    if rng.random() < 0.5:
        d = (ys[j + 1] - ys[j] - CORRIDOR_M - 3 * WALL_M) / 2
        if (n00, n10) in have:
            b.rooms_along(xs[i], xs[i + 1], ys[j], True, +1, d)
        if (n01, n11) in have:
            b.rooms_along(xs[i], xs[i + 1], ys[j + 1], True, -1, d)
    else:
        d = (xs[i + 1] - xs[i] - CORRIDOR_M - 3 * WALL_M) / 2
        if (n00, n01) in have:
            b.rooms_along(ys[j], ys[j + 1], xs[i], False, +1, d)
        if (n10, n11) in have:
            b.rooms_along(ys[j], ys[j + 1], xs[i + 1], False, -1, d)


def _outer_rooms(b: _Builder, have: set[tuple[int, int]], nx: int, ny: int) -> None:
    """Rooms outside the lattice along its boundary corridors."""
    xs, ys = b.xs, b.ys
    top = ROOM_DEPTH_M[1]
    for i in range(nx - 1):
        if (i, i + 1) in have:
            b.rooms_along(xs[i], xs[i + 1], ys[0], True, -1, top)
        k = (ny - 1) * nx + i
        if (k, k + 1) in have:
            b.rooms_along(xs[i], xs[i + 1], ys[-1], True, +1, top)
    for j in range(ny - 1):
        if (j * nx, (j + 1) * nx) in have:
            b.rooms_along(ys[j], ys[j + 1], xs[0], False, -1, top)
        k = j * nx + nx - 1
        if (k, k + nx) in have:
            b.rooms_along(ys[j], ys[j + 1], xs[-1], False, +1, top)


def _start_pose(xs: list[float], ys: list[float], edges: list[tuple[int, int]],
                present: set[int], nx: int) -> Pose2D:
    """1.5 m along the first corridor from the south-west-most node that has one, facing
    along it."""
    for k in sorted(present, key=lambda k: (edges[k][0] // nx + edges[k][0] % nx, k)):
        a, c = edges[k]
        (x0, y0), (x1, y1) = (xs[a % nx], ys[a // nx]), (xs[c % nx], ys[c // nx])
        theta = math.atan2(y1 - y0, x1 - x0)
        return Pose2D(x0 + START_OFFSET_M * math.cos(theta),
                      y0 + START_OFFSET_M * math.sin(theta), theta)
    raise WorldError("generated office: no corridor")  # unreachable: a lattice has an edge


def parse_spec(spec: str) -> tuple[str, int, float]:
    """(kind, seed, scale) of `gen:office:seed=3,scale=2`; WorldError naming what is wrong."""
    if not spec.startswith(SPEC_PREFIX):
        raise WorldError(f"{describe(spec)}: a generated world spec starts with {SPEC_PREFIX!r}")
    kind, _, params = spec[len(SPEC_PREFIX):].partition(":")
    if kind != "office":
        raise WorldError(f"{describe(spec)}: unknown generated world kind {describe(kind)} "
                         "(known: office)")
    seed, scale = 1, 1.0
    for item in filter(None, (p.strip() for p in params.split(","))):
        key, eq, value = item.partition("=")
        if key not in ("seed", "scale") or not eq:
            raise WorldError(f"{describe(spec)}: unknown parameter {describe(item)} (use seed=N, "
                             "scale=S)")
        try:
            if key == "seed":
                seed = inputs.parse_int(value, f"{describe(spec)}: seed", WorldError)
            else:
                scale = float(value)  # its range: generate_office
        except ValueError:  # WorldError is one
            raise WorldError(f"{describe(spec)}: {key} must be a number of at most "
                             f"{MAX_INT_DIGITS} digits, got {describe(value)}") from None
    return kind, seed, scale


def generated_world(spec: str) -> World:
    """The world of a `gen:...` spec string."""
    _kind, seed, scale = parse_spec(spec)
    return generate_office(seed, scale).world
