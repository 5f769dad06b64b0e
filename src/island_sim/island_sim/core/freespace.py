"""The free space of a line-segment world on a raster (numpy/scipy only).

The world's walls are drawn into a square grid (every cell a wall crosses is a wall cell); a
cell is *free* when its centre lies more than the robot's radius from every wall cell (an
exact Euclidean distance transform), so the free cells are the robot's configuration space.
The *reachable* free space is the 8-connected component of the free cells holding the start
pose. Free regions that touch the raster's border are outside the building: they are never a
start region.

From the reachable free space come

- its cycle rank: the number of holes, i.e. components of everything else (walls, unreachable
  cells, the outside) that the reachable space encloses. The free space is 8-connected, so its
  complement is counted with 4-connectivity (the digital-topology duality: an 8-connected
  curve separates 4-connected regions), and the component touching the border is the outside;
- geodesic distances and shortest paths through it (Dijkstra on the 8-neighbour grid without
  corner cutting, then the path pulled straight where the straight line stays free);
- a default start pose for worlds without one (`default_start_pose`): the middle of the longest
  geodesic path of the largest enclosed free region, moved to the centre line of the corridor
  it crosses.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from island_msgs_py.types import FloatArray, Pose2D
from scipy import ndimage
from scipy.sparse import coo_array, csr_array
from scipy.sparse.csgraph import dijkstra

from island_sim.core.world import World, WorldError

BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]
AllowedFn = Callable[[FloatArray], BoolArray]
"""Where free space may be, as a predicate on (K, 2) points [m] (e.g. an image's known-free
pixels): cells whose centre it rejects are never free."""

ROBOT_RADIUS_M = 0.25
"""The simulated robot's radius (a Nomad 200) [m]."""
EIGHT = np.ones((3, 3), dtype=bool)
"""8-connectivity structure for ndimage.label."""
FOUR = ndimage.generate_binary_structure(2, 1)
"""4-connectivity structure for ndimage.label."""
_START_BEARINGS = 72
"""Headings tried for a default start pose (the longest free ray wins) [-]."""
START_MIN_CLEARANCE_M = 1.0
"""A default start wants this much room around it (a 2 m corridor's centre line): a robot
started in a 0.9 m hallway of a house plan touched its walls 250 times without leaving [m]."""


class FreeSpaceError(WorldError):
    """The world has no usable free space (none reachable, start in a wall, raster too big)."""


@dataclass(frozen=True)
class FreeSpaceConfig:
    """How a world's free space is rasterized."""

    resolution_m: float = field(default=0.1, metadata={"help": "raster cell size [m]"})
    robot_radius_m: float = field(
        default=ROBOT_RADIUS_M,
        metadata={"help": "a cell is free when its centre is farther than this from every wall "
                          "cell (the robot's radius) [m]"},
    )
    margin_m: float = field(
        default=1.0, metadata={"help": "raster border beyond the world's bounds [m]"}
    )
    max_cells: int = field(
        default=20_000_000, metadata={"help": "largest raster; bigger worlds are refused [cells]"}
    )
    min_hole_extent_m: float = field(
        default=2.0,
        metadata={"help": "an obstacle enclosed by the free space is a loop of the building "
                          "(counts in the cycle rank) when its configuration-space extent "
                          "(longer side of its bounding box, the robot's clearance included) "
                          "reaches this; smaller ones are furniture the robot drives around [m]"},
    )
    start_snap_m: float = field(
        default=0.5,
        metadata={"help": "a start closer to a wall than the robot's radius moves to the "
                          "nearest free cell within this distance [m]"},
    )

    def __post_init__(self) -> None:
        for name in ("resolution_m", "robot_radius_m", "margin_m", "start_snap_m",
                     "min_hole_extent_m"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise FreeSpaceError(f"FreeSpaceConfig.{name}: expected a finite number >= 0, "
                                     f"got {v!r}")
        if self.resolution_m <= 0:
            raise FreeSpaceError(f"FreeSpaceConfig.resolution_m: must be > 0, got "
                                 f"{self.resolution_m}")
        if self.max_cells < 1:
            raise FreeSpaceError(f"FreeSpaceConfig.max_cells: must be >= 1, got {self.max_cells}")


@dataclass(frozen=True, eq=False)
class Raster:
    """Walls of a world on a grid: cell (i, j) covers x in x0 + [j, j + 1] * res, y likewise
    with i (row 0 at the bottom). `clearance_m` (H, W): distance from each cell centre to the
    nearest wall cell's centre [m] (0 on wall cells)."""

    origin_m: tuple[float, float]
    resolution_m: float
    clearance_m: FloatArray

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.clearance_m.shape[0]), int(self.clearance_m.shape[1]))

    def cells_of(self, xy_m: npt.ArrayLike) -> IntArray:
        """(K, 2) (row, col) of the cells holding points (K, 2) [m] (may lie off the grid)."""
        p = np.atleast_2d(np.asarray(xy_m, dtype=np.float64))
        col = np.floor((p[:, 0] - self.origin_m[0]) / self.resolution_m)
        row = np.floor((p[:, 1] - self.origin_m[1]) / self.resolution_m)
        return np.stack([row, col], axis=1).astype(np.int64)

    def centres_m(self, rows: npt.ArrayLike, cols: npt.ArrayLike) -> FloatArray:
        """(K, 2) world xy [m] of the centres of cells (rows, cols)."""
        r = np.asarray(rows, dtype=np.float64).reshape(-1)
        c = np.asarray(cols, dtype=np.float64).reshape(-1)
        return np.stack([self.origin_m[0] + (c + 0.5) * self.resolution_m,
                         self.origin_m[1] + (r + 0.5) * self.resolution_m], axis=1)

    def on_grid(self, cells: IntArray) -> npt.NDArray[np.bool_]:
        h, w = self.shape
        return (cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)


def rasterize(world: World, cfg: FreeSpaceConfig | None = None) -> Raster:
    """The world's walls on a grid of `cfg.resolution_m` and each cell's clearance [m]."""
    c = cfg if cfg is not None else FreeSpaceConfig()
    if world.segments.shape[0] == 0:
        raise FreeSpaceError(f"world {world.name!r}: no walls, so no bounded free space")
    x0, y0, x1, y1 = world.bounds
    res = c.resolution_m
    ox, oy = x0 - c.margin_m, y0 - c.margin_m
    w = math.ceil((x1 + c.margin_m - ox) / res) + 1
    h = math.ceil((y1 + c.margin_m - oy) / res) + 1
    if w * h > c.max_cells:
        raise FreeSpaceError(
            f"world {world.name!r}: a {w} x {h} raster at {res} m exceeds {c.max_cells} cells "
            "(use a coarser resolution)")
    seg = world.segments
    length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    n = np.ceil(length / (0.25 * res)).astype(np.int64) + 1  # samples per segment, < res apart
    which = np.repeat(np.arange(seg.shape[0]), n)
    first = np.cumsum(n) - n
    t = (np.arange(which.size) - first[which]) / np.maximum(n[which] - 1, 1)
    pts = seg[which, 0:2] + t[:, None] * (seg[which, 2:4] - seg[which, 0:2])
    raster = Raster((ox, oy), res, np.zeros((h, w)))
    cells = raster.cells_of(pts)
    walls = np.zeros((h, w), dtype=bool)
    walls[cells[:, 0], cells[:, 1]] = True
    clearance = ndimage.distance_transform_edt(~walls) * res
    return Raster((ox, oy), res, clearance)


def _border_labels(labels: IntArray) -> IntArray:
    """Labels (> 0) of components that touch the grid's border."""
    edge = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    return np.unique(edge[edge > 0])


@dataclass(frozen=True, eq=False)
class FreeSpace:
    """The reachable free space of a world (see the module docstring).

    free: (H, W) cells whose clearance exceeds the robot's radius; reachable: the 8-connected
    component of `free` holding `start_cell` (row, col).
    """

    raster: Raster
    free: BoolArray
    reachable: BoolArray
    start_cell: tuple[int, int]
    robot_radius_m: float
    min_hole_extent_m: float = 0.0

    @functools.cached_property
    def _holes(self) -> tuple[IntArray, dict[int, float]]:
        """Labels (H, W) of everything that is not reachable (4-connected), and the extent [m]
        (longer side of the bounding box) of each hole: a label that does not touch the
        raster's border."""
        rest = np.pad(~self.reachable, 1, constant_values=True)
        labels, _count = ndimage.label(rest, structure=FOUR)
        outside = set(_border_labels(labels).tolist())
        res = self.raster.resolution_m
        extents = {k: max(sl[0].stop - sl[0].start, sl[1].stop - sl[1].start) * res
                   for k, sl in enumerate(ndimage.find_objects(labels), start=1)
                   if sl is not None and k not in outside}
        return labels[1:-1, 1:-1], extents

    @property
    def hole_extents_m(self) -> FloatArray:
        """Extent [m] of every hole of the reachable free space, small ones included."""
        return np.array(sorted(self._holes[1].values()), dtype=np.float64)

    @property
    def cycle_rank(self) -> int:
        """Loops of the building: holes whose extent reaches `min_hole_extent_m`."""
        return int(np.sum(self.hole_extents_m >= self.min_hole_extent_m))

    @functools.cached_property
    def filled(self) -> BoolArray:
        """The reachable cells with the holes smaller than `min_hole_extent_m` filled in (the
        free space as a building plan shows it, without furniture)."""
        labels, extents = self._holes
        small = [k for k, e in extents.items() if e < self.min_hole_extent_m]
        return self.reachable | np.isin(labels, small)

    @functools.cached_property
    def area_m2(self) -> float:
        """Area of the reachable cells [m^2]."""
        return float(self.reachable.sum()) * self.raster.resolution_m**2

    def snap(self, xy_m: npt.ArrayLike, max_m: float) -> IntArray:
        """(K,) flat index of the reachable cell nearest each point within `max_m` [m], -1 for
        none."""
        r = self.raster
        p = np.atleast_2d(np.asarray(xy_m, dtype=np.float64))
        out = np.full(p.shape[0], -1, dtype=np.int64)
        k = math.ceil(max_m / r.resolution_m)
        h, w = r.shape
        for n, cell in enumerate(r.cells_of(p)):
            i0, i1 = max(0, cell[0] - k), min(h, cell[0] + k + 1)
            j0, j1 = max(0, cell[1] - k), min(w, cell[1] + k + 1)
            if i0 >= i1 or j0 >= j1:
                continue
            ii, jj = np.nonzero(self.reachable[i0:i1, j0:j1])
            if ii.size == 0:
                continue
            d = np.hypot(*(r.centres_m(ii + i0, jj + j0) - p[n]).T)
            best = int(np.argmin(d))
            if d[best] <= max_m:
                out[n] = (ii[best] + i0) * w + jj[best] + j0
        return out

    @functools.cached_property
    def _graph(self) -> tuple[csr_array, IntArray, IntArray]:
        """Grid graph of the reachable cells: CSR [m], node -> flat cell, flat cell -> node."""
        h, w = self.raster.shape
        res = self.raster.resolution_m
        m = self.reachable.reshape(-1)
        flat = np.flatnonzero(m)
        node_of = np.full(h * w, -1, dtype=np.int64)
        node_of[flat] = np.arange(flat.size)
        i, j = flat // w, flat % w
        rows, cols, wts = [], [], []
        for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
            ok = (i + di < h) & (j + dj >= 0) & (j + dj < w)
            a = flat[ok]
            b = a + di * w + dj
            keep = m[b]
            if di and dj:  # no corner cutting: both orthogonal cells must be reachable too
                keep &= m[a + dj] & m[a + di * w]
            rows.append(node_of[a[keep]])
            cols.append(node_of[b[keep]])
            wts.append(np.full(int(keep.sum()), res * math.hypot(di, dj)))
        n = flat.size
        g = coo_array((np.concatenate(wts), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n, n)).tocsr()
        return g, flat, node_of

    def geodesic_from(self, flat_cells: Sequence[int], limit_m: float = math.inf) -> FloatArray:
        """(S, H*W) grid path length [m] from each source cell (flat index) to every cell, inf
        where not reachable or beyond `limit_m`; 8-neighbour moves without corner cutting."""
        g, flat, node_of = self._graph
        src = node_of[np.asarray(flat_cells, dtype=np.int64)]
        if np.any(src < 0):
            raise FreeSpaceError("geodesic: a source cell is not in the reachable free space")
        d = dijkstra(g, directed=False, indices=src, limit=limit_m)
        out = np.full((len(src), self.reachable.size), np.inf)
        out[:, flat] = np.atleast_2d(d)
        return out

    def shortest_path_m(self, a_xy: tuple[float, float], b_xy: tuple[float, float],
                        snap_m: float = 0.5) -> tuple[float, FloatArray]:
        """Length [m] and (K, 2) polyline [m] of the shortest path from a to b through the
        reachable free space: the grid path, pulled straight where a straight line stays
        reachable. (inf, empty) when there is none; FreeSpaceError when a or b is not within
        `snap_m` of the reachable space."""
        cells = self.snap(np.array([a_xy, b_xy], dtype=np.float64).reshape(2, 2), snap_m)
        if np.any(cells < 0):
            raise FreeSpaceError(f"shortest path: {a_xy!r} or {b_xy!r} is not within {snap_m} m of "
                                 "the reachable free space")
        g, flat, node_of = self._graph
        src, dst = (int(node_of[c]) for c in cells)
        d, pred = dijkstra(g, directed=False, indices=src, return_predecessors=True)
        if not np.isfinite(d[dst]):
            return math.inf, np.zeros((0, 2))
        nodes = [dst]
        while nodes[-1] != src:
            nodes.append(int(pred[nodes[-1]]))
        w = self.raster.shape[1]
        fc = flat[np.array(nodes[::-1])]
        pts = self.raster.centres_m(fc // w, fc % w)
        pulled = self._pull_straight(pts)
        return float(np.sum(np.hypot(*np.diff(pulled, axis=0).T))), pulled

    def line_is_free(self, a: FloatArray, b: FloatArray) -> bool:
        """True when every cell the segment a-b [m] crosses is reachable."""
        n = math.ceil(float(np.hypot(*(b - a))) / (0.25 * self.raster.resolution_m)) + 1
        t = np.linspace(0.0, 1.0, n)[:, None]
        cells = self.raster.cells_of(a + t * (b - a))
        ok = self.raster.on_grid(cells)
        return bool(np.all(ok) and np.all(self.reachable[cells[:, 0], cells[:, 1]]))

    def _pull_straight(self, pts: FloatArray) -> FloatArray:
        """Greedy string pulling of a grid path: skip vertices while the shortcut stays free."""
        out = [pts[0]]
        i = 0
        while i < pts.shape[0] - 1:
            j = i + 1
            while j + 1 < pts.shape[0] and self.line_is_free(pts[i], pts[j + 1]):
                j += 1
            out.append(pts[j])
            i = j
        return np.array(out)


def free_cells(raster: Raster, robot_radius_m: float,
               allowed: AllowedFn | None = None) -> BoolArray:
    """(H, W) cells farther than the robot's radius from every wall and, if `allowed` is
    given, from every cell it rejects (so thin allowed strands vanish as thin corridors do)."""
    free = raster.clearance_m > robot_radius_m
    if allowed is not None:
        h, w = raster.shape
        ii, jj = np.indices((h, w)).reshape(2, -1)
        ok = np.asarray(allowed(raster.centres_m(ii, jj)), dtype=bool).reshape(h, w)
        free &= ndimage.distance_transform_edt(ok) * raster.resolution_m > robot_radius_m
    return free


def free_space(world: World, start: Pose2D | None = None,
               cfg: FreeSpaceConfig | None = None, allowed: AllowedFn | None = None,
               raster: Raster | None = None) -> FreeSpace:
    """The free space reachable from `start` (default: the world's start pose), within
    `allowed` if given.

    FreeSpaceError when the start is outside the raster, or no free cell lies within
    `cfg.start_snap_m` of it (e.g. inside a wall)."""
    c = cfg if cfg is not None else FreeSpaceConfig()
    r = raster if raster is not None else rasterize(world, c)
    sp = start if start is not None else world.start_pose
    free = free_cells(r, c.robot_radius_m, allowed)
    labels, _count = ndimage.label(free, structure=EIGHT)
    probe = FreeSpace(r, free, free, (0, 0), c.robot_radius_m)
    cell = int(probe.snap([[sp.x, sp.y]], c.start_snap_m)[0])
    if cell < 0:
        raise FreeSpaceError(
            f"world {world.name!r}: no free space within {c.start_snap_m} m of the start "
            f"({sp.x:.2f}, {sp.y:.2f}) for a robot of radius {c.robot_radius_m} m")
    w = r.shape[1]
    reachable = labels == labels.reshape(-1)[cell]
    return FreeSpace(r, free, reachable, (cell // w, cell % w), c.robot_radius_m,
                     c.min_hole_extent_m)


def largest_enclosed_region(world: World, cfg: FreeSpaceConfig | None = None,
                            allowed: AllowedFn | None = None,
                            raster: Raster | None = None) -> FreeSpace:
    """The largest 8-connected free region (within `allowed`) that does not touch the raster's
    border (the outside); FreeSpaceError when there is none."""
    c = cfg if cfg is not None else FreeSpaceConfig()
    r = raster if raster is not None else rasterize(world, c)
    free = free_cells(r, c.robot_radius_m, allowed)
    labels, count = ndimage.label(free, structure=EIGHT)
    sizes = np.bincount(labels.reshape(-1), minlength=count + 1)
    sizes[0] = 0
    sizes[_border_labels(labels)] = 0
    if count == 0 or sizes.max() == 0:
        raise FreeSpaceError(f"world {world.name!r}: no enclosed free space for a robot of "
                             f"radius {c.robot_radius_m} m")
    best = int(np.argmax(sizes))
    region = labels == best
    flat = int(np.flatnonzero(region)[0])
    w = r.shape[1]
    return FreeSpace(r, free, region, (flat // w, flat % w), c.robot_radius_m,
                     c.min_hole_extent_m)


def _climb(clearance_m: FloatArray, region: BoolArray, flat: int) -> int:
    """Steepest ascent in clearance from cell `flat` within `region`, to a ridge (a centre
    line of the free space); returns the flat index where no neighbour is strictly clearer."""
    h, w = clearance_m.shape
    cur = flat
    while True:
        i, j = divmod(cur, w)
        best, best_c = cur, clearance_m[i, j]
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                a, b = i + di, j + dj
                if 0 <= a < h and 0 <= b < w and region[a, b] and clearance_m[a, b] > best_c:
                    best, best_c = a * w + b, clearance_m[a, b]
        if best == cur:
            return cur
        cur = best


def default_start_pose(world: World, cfg: FreeSpaceConfig | None = None,
                       allowed: AllowedFn | None = None) -> Pose2D:
    """A start pose for a world without one, in its largest enclosed free region.

    The region's longest geodesic path is found by a double sweep (the farthest cell from any
    cell, then the farthest from that one); the start is the cell nearest its middle (the
    larger of the distances to its two ends is least) among those with 1 m of clearance (if
    any), moved uphill in clearance to the centre line of the corridor or room it is in, facing
    the longest free ray. A closed room that is not the largest region is never chosen."""
    space = largest_enclosed_region(world, cfg, allowed)
    r = space.raster
    w = r.shape[1]

    def farthest(d: FloatArray) -> int:
        return int(np.argmax(np.where(np.isfinite(d), d, -1.0)))

    a = farthest(space.geodesic_from([space.start_cell[0] * w + space.start_cell[1]])[0])
    da = space.geodesic_from([a])[0]
    db = space.geodesic_from([farthest(da)])[0]
    reach = np.maximum(da, db)  # inf off the region
    roomy = r.clearance_m.reshape(-1) >= START_MIN_CLEARANCE_M
    if not np.any(roomy & np.isfinite(reach)):
        roomy[:] = True
    middle = int(np.argmin(np.where(roomy, reach, np.inf)))
    pick = _climb(r.clearance_m, space.reachable, middle)
    x, y = (float(v) for v in r.centres_m(pick // w, pick % w)[0])
    bearings = np.linspace(-math.pi, math.pi, _START_BEARINGS, endpoint=False)
    ranges = world.raycast(np.array([[x, y]]), bearings).distance_m
    ranges = np.where(np.isfinite(ranges), ranges, -1.0)
    return Pose2D(x, y, float(bearings[int(np.argmax(ranges))]))


def grid_lookup(mask: npt.ArrayLike, resolution_m: float,
                origin_m: tuple[float, float] = (0.0, 0.0)) -> AllowedFn:
    """An `AllowedFn` reading a boolean grid (row 0 at the bottom; cell (i, j) covers
    origin + [j, j + 1] x [i, i + 1] * resolution [m]); points off the grid are not allowed."""
    grid = np.asarray(mask, dtype=bool)
    h, w = grid.shape

    def allowed(xy_m: FloatArray) -> BoolArray:
        p = np.atleast_2d(np.asarray(xy_m, dtype=np.float64))
        j = np.floor((p[:, 0] - origin_m[0]) / resolution_m).astype(np.int64)
        i = np.floor((p[:, 1] - origin_m[1]) / resolution_m).astype(np.int64)
        ok = (i >= 0) & (i < h) & (j >= 0) & (j < w)
        out = np.zeros(p.shape[0], dtype=bool)
        out[ok] = grid[i[ok], j[ok]]
        return out

    return allowed


def known_free_allowed(known_free: npt.ArrayLike, resolution_m: float,
                       origin_m: tuple[float, float] = (0.0, 0.0),
                       close_m: float = 0.1) -> AllowedFn:
    """An `AllowedFn` for an occupancy image: its known-free pixels (row 0 at the bottom),
    with unknown specks narrower than 2 x `close_m` [m] closed (scan shadows inside rooms)."""
    grid = np.asarray(known_free, dtype=bool)
    k = round(close_m / resolution_m)
    if k > 0:
        yy, xx = np.mgrid[-k: k + 1, -k: k + 1]
        disk = xx**2 + yy**2 <= k * k
        grid = ndimage.binary_closing(np.pad(grid, k), structure=disk)[k:-k, k:-k]
    return grid_lookup(grid, resolution_m, origin_m)
