"""Ground-truth places of a world, from its geometry alone (numpy/scipy only).

The rule (what a person marks on a floor plan as "a place the robot must know"):

1. the free space reachable from the start, for a robot of radius 0.25 m, on a 0.1 m raster
   (`freespace.free_space`);
2. its skeleton, by Zhang-Suen thinning (vectorized; topology-preserving, so the skeleton has
   the free space's loops), read as a graph: skeleton pixels with one neighbour are ends, with
   three or more are branch pixels (touching branch pixels form one node), chains of pixels
   with two neighbours are edges with a length;
3. spurs pruned: an edge from an end to a branch node is an artifact of a corner of the free
   space (a corridor's end splits into two diagonals to its corners, a room's skeleton fans out
   to its four) when it is no longer than `spur_factor` (1.5) times the wall clearance at its
   branch node; all such spurs go at once, nodes left with two edges dissolve, and this repeats
   until nothing changes. So a corridor's dead end keeps one end place at its far end, a room
   with one door shrinks to one end place in its middle, and a real side corridor (longer than
   1.5 clearances) stays;
4. places: the branch nodes (kind JUNCTION: crossings, T junctions, doorways off a corridor)
   and the end nodes (kind END: dead ends, rooms), merged greedily within 2 m of each other
   where one sees the other (junctions first, then by clearance: the leader keeps its
   position and a merged place is a junction if any member is one).

A bend without a side branch (an L corner) is not a place under this rule.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import numpy.typing as npt
from island_msgs_py.types import FloatArray, Pose2D
from scipy import ndimage

from island_sim.core.freespace import (
    EIGHT,
    AllowedFn,
    FreeSpace,
    FreeSpaceConfig,
    FreeSpaceError,
    free_space,
)
from island_sim.core.world import World

BoolArray = npt.NDArray[np.bool_]
_BUMP_PX = 4
"""A chain leaving a branch cluster and returning to it within this many pixels is a bulge of
the cluster, not a loop of the free space [px]."""


class WorldPlaceKind(StrEnum):
    JUNCTION = "junction"
    END = "end"


@dataclass(frozen=True)
class WorldPlace:
    """A ground-truth place: its kind, position [m] and clearance from the walls [m]."""

    kind: WorldPlaceKind
    x_m: float
    y_m: float
    clearance_m: float


@dataclass(frozen=True)
class PlacesConfig:
    """The ground-truth place rule (module docstring)."""

    free: FreeSpaceConfig = field(
        default_factory=FreeSpaceConfig, metadata={"help": "raster and robot radius"}
    )
    spur_factor: float = field(
        default=1.5,
        metadata={"help": "an end-to-branch skeleton edge no longer than this times the wall "
                          "clearance at its branch is a corner artifact and is pruned [-]"},
    )
    merge_radius_m: float = field(
        default=2.0, metadata={"help": "places within this distance in sight are one [m]"}
    )

    def __post_init__(self) -> None:
        for name in ("spur_factor", "merge_radius_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise FreeSpaceError(f"PlacesConfig.{name}: expected a finite number >= 0, "
                                     f"got {v!r}")


@dataclass(frozen=True, eq=False)
class WorldPlaces:
    """The places of a world, its reachable free space and its pruned skeleton (H, W)."""

    world_name: str
    places: tuple[WorldPlace, ...]
    space: FreeSpace
    skeleton: BoolArray

    @property
    def cycle_rank(self) -> int:
        """Holes in the reachable free space (independent loops the robot can drive)."""
        return self.space.cycle_rank

    @property
    def junctions(self) -> tuple[WorldPlace, ...]:
        return tuple(p for p in self.places if p.kind is WorldPlaceKind.JUNCTION)

    def positions_m(self) -> FloatArray:
        """(P, 2) place positions [m]."""
        return np.array([[p.x_m, p.y_m] for p in self.places]).reshape(-1, 2)


# ----------------------------------------------------------------------------- thinning


def zhang_suen(mask: npt.ArrayLike) -> BoolArray:
    """The Zhang-Suen (1984) skeleton of a binary image (8-connected foreground), vectorized.

    Each iteration has two sub-steps that delete, all at once, the border pixels with 2-6
    neighbours and exactly one 0->1 transition around them, south-east then north-west."""
    img = np.pad(np.asarray(mask, dtype=bool), 1).astype(np.uint8)
    if not img.any():
        return np.zeros(np.asarray(mask).shape, dtype=bool)
    rows, cols = np.nonzero(img)
    r0, r1 = max(rows.min() - 1, 0), min(rows.max() + 2, img.shape[0])
    c0, c1 = max(cols.min() - 1, 0), min(cols.max() + 2, img.shape[1])
    sub = img[r0:r1, c0:c1].copy()
    while True:
        changed = False
        for step in (0, 1):
            centre = sub[1:-1, 1:-1]
            # Neighbours P2..P9 clockwise from north (row index grows downwards here).
            p = [sub[:-2, 1:-1], sub[:-2, 2:], sub[1:-1, 2:], sub[2:, 2:],
                 sub[2:, 1:-1], sub[2:, :-2], sub[1:-1, :-2], sub[:-2, :-2]]
            b = sum(q.astype(np.int16) for q in p)
            a = sum(((p[k] == 0) & (p[(k + 1) % 8] == 1)).astype(np.int16) for k in range(8))
            p2, p4, p6, p8 = p[0], p[2], p[4], p[6]
            if step == 0:
                cond = (p2 * p4 * p6 == 0) & (p4 * p6 * p8 == 0)
            else:
                cond = (p2 * p4 * p8 == 0) & (p2 * p6 * p8 == 0)
            delete = (centre == 1) & (b >= 2) & (b <= 6) & (a == 1) & cond
            if delete.any():
                centre[delete] = 0
                changed = True
        if not changed:
            break
    out = np.zeros_like(img)
    out[r0:r1, c0:c1] = sub
    return out[1:-1, 1:-1].astype(bool)


# ----------------------------------------------------------------------------- skeleton graph


def _neighbours(skel: BoolArray) -> dict[int, list[int]]:
    """Adjacency of skeleton pixels (flat indices): 4-neighbours always, a diagonal neighbour
    only when no skeleton pixel is a 4-neighbour of both (so staircases are chains)."""
    w = skel.shape[1]
    pad = np.pad(skel, 1)
    pw = w + 2
    flat = np.flatnonzero(pad)
    on = pad.reshape(-1)
    adj: dict[int, list[int]] = {int(f): [] for f in flat}
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        b = flat + di * pw + dj
        keep = on[b]
        if di and dj:
            keep &= ~(on[flat + dj] | on[flat + di * pw])
        for u, v in zip(flat[keep].tolist(), b[keep].tolist(), strict=True):
            adj[u].append(v)
            adj[v].append(u)
    # back to unpadded flat indices
    def unpad(f: int) -> int:
        return (f // pw - 1) * w + (f % pw - 1)

    return {unpad(u): [unpad(v) for v in vs] for u, vs in adj.items()}


@dataclass
class SkeletonGraph:
    """Skeleton graph: node -> its pixels (flat indices); edge id -> (u, v, length [m], the
    pixels between); node -> ids of its edges (a self-loop listed twice)."""

    node_pixels: dict[int, list[int]]
    edges: dict[int, tuple[int, int, float, list[int]]]
    incident: dict[int, list[int]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.incident = {n: [] for n in self.node_pixels}
        for k, (u, v, _l, _p) in self.edges.items():
            self.incident[u].append(k)
            self.incident[v].append(k)

    def degree(self, node: int) -> int:
        return len(self.incident[node])

    def remove_edge(self, k: int) -> tuple[int, int, float, list[int]]:
        e = self.edges.pop(k)
        self.incident[e[0]].remove(k)
        self.incident[e[1]].remove(k)
        return e

    def add_edge(self, u: int, v: int, length_m: float, pixels: list[int]) -> None:
        k = max(self.edges, default=-1) + 1
        self.edges[k] = (u, v, length_m, pixels)
        self.incident[u].append(k)
        self.incident[v].append(k)

    def remove_node(self, n: int) -> None:
        for k in list(self.incident[n]):
            if k in self.edges:
                self.remove_edge(k)
        del self.incident[n]
        del self.node_pixels[n]


def _step_m(a: int, b: int, w: int, res: float) -> float:
    return res * (math.sqrt(2.0) if (a // w != b // w and a % w != b % w) else 1.0)


def skeleton_graph(skel: BoolArray, resolution_m: float) -> SkeletonGraph:
    """Nodes (ends, clusters of touching branch pixels) and the pixel chains between them.

    A closed loop of skeleton pixels with no node on it (a ring corridor's skeleton) has no
    node and no edge: it holds no place."""
    h, w = skel.shape
    adj = _neighbours(skel)
    deg = {u: len(vs) for u, vs in adj.items()}
    branch = np.zeros(h * w, dtype=bool)
    branch[[u for u, d in deg.items() if d >= 3]] = True
    labels, count = ndimage.label(branch.reshape(h, w), structure=EIGHT)
    lab = labels.reshape(-1)
    node_of: dict[int, int] = {int(u): int(lab[u]) for u in np.flatnonzero(branch)}
    nid = count + 1
    for u, d in deg.items():
        if d <= 1:  # an end, or a lone pixel
            node_of[u] = nid
            nid += 1
    node_pixels: dict[int, list[int]] = defaultdict(list)
    for u, n in node_of.items():
        node_pixels[n].append(u)
    edges: dict[int, tuple[int, int, float, list[int]]] = {}
    seen: set[int] = set()
    pairs: set[tuple[int, int]] = set()
    for u, n in node_of.items():
        for v in adj[u]:
            if node_of.get(v) == n:
                continue
            if v in node_of:  # two nodes side by side: a one-step edge, once per pixel pair
                key = (min(u, v), max(u, v))
                if key not in pairs:
                    pairs.add(key)
                    edges[len(edges)] = (n, node_of[v], _step_m(u, v, w, resolution_m), [])
                continue
            if v in seen:
                continue
            chain, length, prev, cur = [v], _step_m(u, v, w, resolution_m), u, v
            seen.add(v)
            while cur not in node_of:  # pixels off nodes have exactly two neighbours
                nxt = next(x for x in adj[cur] if x != prev)
                length += _step_m(cur, nxt, w, resolution_m)
                prev, cur = cur, nxt
                if cur not in node_of:
                    seen.add(cur)
                    chain.append(cur)
            if node_of[cur] == n and length <= _BUMP_PX * resolution_m:
                continue  # a pixel or two bulging off a branch cluster, not a loop
            edges[len(edges)] = (n, node_of[cur], length, chain)
    return SkeletonGraph(dict(node_pixels), edges)


def prune_spurs(g: SkeletonGraph, clearance_m: FloatArray, spur_factor: float) -> SkeletonGraph:
    """Remove end-to-branch edges no longer than spur_factor x the branch's clearance [m]
    (clearance_m: per flat pixel), all at once per round, dissolving nodes left with two edges,
    until nothing changes. Modifies and returns `g`."""
    clear = {n: float(clearance_m[px].max()) for n, px in g.node_pixels.items()}
    while True:
        spur_ends = []
        for u, v, length, _px in g.edges.values():
            for end, root in ((u, v), (v, u)):
                if g.degree(end) == 1 and g.degree(root) >= 3 and \
                        length <= spur_factor * clear[root]:
                    spur_ends.append(end)
                    break
        if not spur_ends:
            return g
        for end in spur_ends:
            g.remove_node(end)
        _dissolve_two_edge_nodes(g)


def _dissolve_two_edge_nodes(g: SkeletonGraph) -> None:
    """Join the two edges of every node with exactly two edges (a self-loop's node stays)."""
    for n in list(g.node_pixels):
        ks = g.incident[n]
        if len(ks) != 2 or ks[0] == ks[1]:
            continue
        (u1, v1, l1, p1), (u2, v2, l2, p2) = g.remove_edge(ks[0]), g.remove_edge(ks[0])
        a = v1 if u1 == n else u1
        b = v2 if u2 == n else u2
        g.add_edge(a, b, l1 + l2, p1 + g.node_pixels[n] + p2)
        del g.incident[n]
        del g.node_pixels[n]


# ----------------------------------------------------------------------------- places


def _merge(places: list[WorldPlace], world: World, radius_m: float) -> list[WorldPlace]:
    """Greedy merge within radius_m where in sight: junctions first, then by clearance."""
    order = sorted(places, key=lambda p: (p.kind is not WorldPlaceKind.JUNCTION, -p.clearance_m,
                                          p.x_m, p.y_m))
    taken = [False] * len(order)
    out: list[WorldPlace] = []
    for i, lead in enumerate(order):
        if taken[i]:
            continue
        taken[i] = True
        kind = lead.kind
        for j in range(i + 1, len(order)):
            o = order[j]
            d = math.hypot(o.x_m - lead.x_m, o.y_m - lead.y_m)
            if taken[j] or d > radius_m:
                continue
            if d > 0:
                hit = world.raycast(np.array([[lead.x_m, lead.y_m]]),
                                    np.array([math.atan2(o.y_m - lead.y_m, o.x_m - lead.x_m)]),
                                    d).distance_m[0]
                if np.isfinite(hit):
                    continue  # a wall between them
            taken[j] = True
            if o.kind is WorldPlaceKind.JUNCTION:
                kind = WorldPlaceKind.JUNCTION
        out.append(WorldPlace(kind, lead.x_m, lead.y_m, lead.clearance_m))
    return out


def world_places(world: World, start: Pose2D | None = None,
                 cfg: PlacesConfig | None = None, allowed: AllowedFn | None = None) -> WorldPlaces:
    """The ground-truth places of `world` reachable from `start` (default: its start pose),
    within `allowed` if given (e.g. an occupancy image's known-free pixels).

    FreeSpaceError when the start has no free space around it or nothing reachable yields a
    place."""
    c = cfg if cfg is not None else PlacesConfig()
    space = free_space(world, start, c.free, allowed)
    r = space.raster
    skel = zhang_suen(space.filled)
    g = prune_spurs(skeleton_graph(skel, r.resolution_m), r.clearance_m.reshape(-1),
                    c.spur_factor)
    w = r.shape[1]
    clear = r.clearance_m.reshape(-1)
    raw = []
    for n, px in g.node_pixels.items():
        best = px[int(np.argmax(clear[px]))]
        x, y = r.centres_m(best // w, best % w)[0]
        kind = WorldPlaceKind.JUNCTION if g.degree(n) >= 3 else WorldPlaceKind.END
        raw.append(WorldPlace(kind, float(x), float(y), float(clear[best])))
    places = _merge(raw, world, c.merge_radius_m)
    if not places:
        raise FreeSpaceError(
            f"world {world.name!r}: the free space reachable from the start has no place "
            "(no junction and no end on its skeleton)")
    pruned = np.zeros(r.clearance_m.size, dtype=bool)
    for _u, _v, _l, px in g.edges.values():
        pruned[px] = True
    for px in g.node_pixels.values():
        pruned[px] = True
    return WorldPlaces(world.name, tuple(places), space, pruned.reshape(r.shape))

