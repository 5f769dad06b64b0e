"""Turn floor plans into line-segment worlds (numpy/scipy and the standard library only).

- Occupancy images (binary/ASCII PGM, 8/16-bit PNG): dark pixels are walls. The boundary between
  occupied and free pixels is traced into closed contours (8-connected walls), which are then
  simplified with Douglas-Peucker, so a diagonal wall becomes one segment instead of a staircase
  and every wall stays a closed outline that no ray can slip through.
- HouseExpo JSON: `verts` is a closed wall polygon in metres.
- `grid_to_segments` is also used by the built-in worlds (free rectangles rasterized on a grid).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import clearance_m, douglas_peucker
from island_msgs_py.limits import (
    MAX_COORD_M,
    MAX_WORLD_SEGMENTS,
)
from island_msgs_py.types import FloatArray, Pose2D
from scipy import ndimage

from island_sim.core.freespace import (
    FreeSpaceConfig,
    FreeSpaceError,
    default_start_pose,
    known_free_allowed,
)
from island_sim.core.images import read_pgm, read_png
from island_sim.core.world import (
    MAX_NAME_CHARS,
    World,
    WorldError,
    enclosed_start_pose,
    read_structured,
    start_pose_from_clearance,
)

BoolArray = npt.NDArray[np.bool_]



@dataclass(frozen=True)
class ImageImportConfig:
    """How an occupancy image becomes a world (the ROS map_server conventions)."""

    resolution_m: float = field(default=0.1, metadata={"help": "pixel size [m/px]"})
    occupied_thresh: float = field(
        default=0.65,
        metadata={"help": "a pixel is a wall when (255 - value) / 255 exceeds this [-]"},
    )
    free_thresh: float = field(
        default=0.1,
        metadata={"help": "a pixel is known free when (255 - value) / 255 is below this [-]; "
                  "used only to choose the start pose"},
    )
    simplify_tol_px: float = field(
        default=1.0,
        metadata={"help": "Douglas-Peucker tolerance of traced wall outlines [px]"},
    )
    origin_x_m: float = field(
        default=0.0, metadata={"help": "world x of the image's lower-left corner [m]"}
    )
    origin_y_m: float = field(
        default=0.0, metadata={"help": "world y of the image's lower-left corner [m]"}
    )

    def __post_init__(self) -> None:
        for name in ("resolution_m", "simplify_tol_px", "origin_x_m", "origin_y_m"):
            v = getattr(self, name)
            if not math.isfinite(v):
                raise WorldError(f"ImageImportConfig.{name}: expected a finite number, got {v!r}")
        if self.resolution_m <= 0:
            raise WorldError(
                f"ImageImportConfig.resolution_m: must be > 0, got {self.resolution_m}"
            )
        if self.simplify_tol_px < 0:
            raise WorldError(
                f"ImageImportConfig.simplify_tol_px: must be >= 0, got {self.simplify_tol_px}"
            )
        for name in ("occupied_thresh", "free_thresh"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise WorldError(f"ImageImportConfig.{name}: must be in [0, 1], got {v!r}")


# ----------------------------------------------------------------------------- contour tracing


def grid_to_segments(
    occupied: npt.ArrayLike,
    resolution_m: float,
    origin_m: tuple[float, float] = (0.0, 0.0),
    simplify_tol_px: float = 1.0,
    outside_occupied: bool = False,
) -> FloatArray:
    """(N, 4) wall segments [m] along the boundary between occupied and free cells.

    occupied: (H, W) bool grid with row 0 at the BOTTOM (y up); cell (i, j) covers
    x in origin_x + [j, j + 1] * resolution, y in origin_y + [i, i + 1] * resolution.
    Outlines go counter-clockwise around occupied regions (8-connected: diagonal neighbours are
    one wall) and are simplified with Douglas-Peucker at `simplify_tol_px` [px] (0: only merge
    collinear runs). `outside_occupied` says what lies beyond the grid.
    """
    g = np.asarray(occupied, dtype=bool)
    if g.ndim != 2:
        raise WorldError(f"occupancy grid: expected a 2-D array, got shape {g.shape}")
    loops = _trace_loops(np.pad(g, 1, constant_values=outside_occupied))
    segs: list[FloatArray] = []
    for loop in loops:
        pts = _simplify_closed(_corners(loop), simplify_tol_px)
        if pts.shape[0] < 2:
            continue
        nxt = np.roll(pts, -1, axis=0)
        seg = np.hstack([pts, nxt])
        seg = seg[np.any(seg[:, 0:2] != seg[:, 2:4], axis=1)]
        segs.append(seg)
    if not segs:
        return np.zeros((0, 4))
    out = np.vstack(segs) - 1.0  # undo the padding
    out = out * resolution_m + np.array([origin_m[0], origin_m[1], origin_m[0], origin_m[1]])
    return _dedupe(out)


def _dedupe(segs: FloatArray) -> FloatArray:
    """Drop exact duplicates (including reversed copies) of segments."""
    if segs.shape[0] == 0:
        return segs
    a, b = segs[:, 0:2], segs[:, 2:4]
    swap = (a[:, 0] > b[:, 0]) | ((a[:, 0] == b[:, 0]) & (a[:, 1] > b[:, 1]))
    canon = np.where(swap[:, None], np.hstack([b, a]), segs)
    _, first = np.unique(canon, axis=0, return_index=True)
    return segs[np.sort(first)]


def _trace_loops(g: BoolArray) -> list[npt.NDArray[np.int64]]:
    """Closed boundary loops (lattice vertices (x, y), y up) around the True cells of `g`."""
    w = g.shape[1]
    span = w + 1
    starts: list[npt.NDArray[np.int64]] = []
    ends: list[npt.NDArray[np.int64]] = []
    # Horizontal lattice edges at y = k + 1 between cells (k, j) below and (k + 1, j) above.
    below, above = g[:-1, :], g[1:, :]
    k, j = np.nonzero(above & ~below)  # wall above: walk +x
    starts.append((k + 1) * span + j)
    ends.append((k + 1) * span + j + 1)
    k, j = np.nonzero(below & ~above)  # wall below: walk -x
    starts.append((k + 1) * span + j + 1)
    ends.append((k + 1) * span + j)
    # Vertical lattice edges at x = j + 1 between cells (i, j) left and (i, j + 1) right.
    left, right = g[:, :-1], g[:, 1:]
    i, j = np.nonzero(left & ~right)  # wall left: walk +y
    starts.append(i * span + j + 1)
    ends.append((i + 1) * span + j + 1)
    i, j = np.nonzero(right & ~left)  # wall right: walk -y
    starts.append((i + 1) * span + j + 1)
    ends.append(i * span + j + 1)
    s = np.concatenate(starts).astype(np.int64)
    e = np.concatenate(ends).astype(np.int64)
    if s.size == 0:
        return []
    # Out-edges per start vertex (at most two, at a saddle where walls touch diagonally).
    order = np.argsort(s, kind="stable")
    s_sorted = s[order]
    first = np.searchsorted(s_sorted, e, side="left")
    last = np.searchsorted(s_sorted, e, side="right")
    sx, sy = s % span, s // span
    ex, ey = e % span, e // span
    dx, dy = ex - sx, ey - sy
    nxt = np.empty(s.size, dtype=np.int64)
    single = last - first == 1
    nxt[single] = order[first[single]]
    for idx in np.flatnonzero(~single):
        cands = order[first[idx] : last[idx]].tolist()
        if not cands:
            raise WorldError("occupancy grid: broken wall outline (internal error)")
        # At a saddle take the right turn, which joins diagonal wall cells into one outline.
        right_turn = (dy[idx], -dx[idx])
        pick = cands[0]
        for c in cands:
            if (dx[c], dy[c]) == right_turn:
                pick = c
        nxt[idx] = pick
    seen = np.zeros(s.size, dtype=bool)
    nxt_list = nxt.tolist()
    loops: list[npt.NDArray[np.int64]] = []
    for e0 in range(s.size):
        if seen[e0]:
            continue
        chain = []
        cur = e0
        while not seen[cur]:
            seen[cur] = True
            chain.append(cur)
            cur = nxt_list[cur]
        ids = s[np.array(chain, dtype=np.int64)]
        loops.append(np.stack([ids % span, ids // span], axis=1))
    return loops


def _corners(loop: npt.NDArray[np.int64]) -> FloatArray:
    """The vertices of a closed lattice loop where its direction changes."""
    pts = loop.astype(np.float64)
    d_in = pts - np.roll(pts, 1, axis=0)
    d_out = np.roll(pts, -1, axis=0) - pts
    turn = d_in[:, 0] * d_out[:, 1] - d_in[:, 1] * d_out[:, 0] != 0
    corners = pts[turn]
    return corners if corners.shape[0] >= 2 else pts[:1]


def _simplify_closed(pts: FloatArray, tol: float) -> FloatArray:
    """Douglas-Peucker on a closed polygon: split at vertex 0 and the vertex farthest from it."""
    n = pts.shape[0]
    if n <= 3 or tol <= 0:
        return pts
    far = int(np.argmax(np.sum((pts - pts[0]) ** 2, axis=1)))
    a = douglas_peucker(pts[: far + 1], tol)
    b = douglas_peucker(np.vstack([pts[far:], pts[:1]]), tol)
    return np.vstack([a[:-1], b[:-1]])


# ----------------------------------------------------------------------------- importers


START_SEARCH_MAX_CELLS = 4_000_000
"""Largest raster of the default start-pose search of an imported world [cells] (~350 MB); a
bigger world is searched on a coarser raster (Willow at 0.1 m: 0.34 M cells)."""
_FALLBACK_SEARCH_PAIRS = 100_000_000
"""Most (point x wall) pairs of the fallback start search of a plan without room for the
robot: a bigger plan is searched on a coarser grid [-]."""


def start_search_config(world: World) -> FreeSpaceConfig:
    """The free-space raster of a world's default start-pose search: the default one, coarsened
    until it has at most START_SEARCH_MAX_CELLS cells."""
    base = FreeSpaceConfig()
    x0, y0, x1, y1 = world.bounds
    cells = ((x1 - x0 + 2 * base.margin_m) / base.resolution_m + 1) * (
        (y1 - y0 + 2 * base.margin_m) / base.resolution_m + 1)
    if cells <= START_SEARCH_MAX_CELLS:
        return base
    factor = math.sqrt(cells / START_SEARCH_MAX_CELLS) * 1.01
    return dataclasses.replace(base, resolution_m=base.resolution_m * factor)


def _naming(path: Path, exc: WorldError) -> WorldError:
    """`exc` with the file name in front when its message does not start with it."""
    text = str(exc)
    return exc if text.startswith(str(path)) else WorldError(f"{path}: {text}")


def import_image(path: str | Path, config: ImageImportConfig | None = None) -> World:
    """World from an occupancy image (.pgm/.png): dark pixels are walls, origin lower-left."""
    cfg = config if config is not None else ImageImportConfig()
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".pgm":
        img = read_pgm(p)
    elif suffix == ".png":
        img = read_png(p)
    else:
        raise WorldError(f"{p}: unknown image extension {p.suffix!r} (use .pgm or .png)")
    grey = img[::-1, :]  # row 0 at the bottom
    occ_prob = (255.0 - np.arange(256, dtype=np.float64)) / 255.0  # per grey level
    occupied = (occ_prob > cfg.occupied_thresh)[grey]
    if not np.any(occupied):
        raise WorldError(f"{p}: no occupied (dark) pixels, so no walls")
    origin = (cfg.origin_x_m, cfg.origin_y_m)
    segs = grid_to_segments(occupied, cfg.resolution_m, origin, cfg.simplify_tol_px)
    del occupied
    free = (occ_prob < cfg.free_thresh)[grey]
    try:
        return World(segs, name=p.stem, start_pose=_image_start(segs, p.stem, free, cfg))
    except WorldError as exc:
        raise _naming(p, exc) from None


def _image_start(segs: FloatArray, name: str, free: BoolArray, cfg: ImageImportConfig) -> Pose2D:
    """The start pose of an image world: in its largest enclosed known-free region, else at the
    known-free pixel farthest from anything not known free."""
    world = World(segs, name=name)
    if not np.any(free):
        return enclosed_start_pose(world)
    origin = (cfg.origin_x_m, cfg.origin_y_m)
    try:  # in the largest enclosed known-free region, not in a closed room
        return default_start_pose(world, start_search_config(world),
                                  allowed=known_free_allowed(free, cfg.resolution_m, origin))
    except FreeSpaceError:
        pass  # no room for the robot anywhere: the freest pixel
    # Clearance of free pixels from anything that is not known free [m].
    clearance_px = ndimage.distance_transform_edt(np.pad(free, 1))[1:-1, 1:-1]
    best = int(np.argmax(np.where(free, clearance_px, -1.0)))  # the first, row by row
    iy, ix = divmod(best, free.shape[1])
    centre = np.array([[origin[0] + (ix + 0.5) * cfg.resolution_m,
                        origin[1] + (iy + 0.5) * cfg.resolution_m]])
    return start_pose_from_clearance(world, centre, clearance_px[iy, ix:ix + 1] * cfg.resolution_m)


def import_houseexpo(path: str | Path, data: dict[str, Any] | None = None) -> World:
    """World from a HouseExpo JSON file: `verts` is a closed wall polygon [m]."""
    p = Path(path)
    if data is None:
        data = read_structured(p)
    verts = _as_points(data.get("verts"), p, "verts")
    if verts.shape[0] < 3:
        raise WorldError(f"{p}: 'verts' needs at least 3 points, got {verts.shape[0]}")
    nxt = np.roll(verts, -1, axis=0)
    segs = np.hstack([verts, nxt])
    segs = segs[np.any(segs[:, 0:2] != segs[:, 2:4], axis=1)]  # repeated vertices
    if segs.shape[0] < 3:
        raise WorldError(f"{p}: 'verts' has fewer than 3 distinct points")
    raw_name = data.get("id", p.stem)
    name = str(raw_name)[:MAX_NAME_CHARS] if isinstance(raw_name, str | int) else p.stem
    try:
        return World(segs, name=name or p.stem, start_pose=_plan_start(segs, verts, name))
    except WorldError as exc:
        raise _naming(p, exc) from None


def _plan_start(segs: FloatArray, verts: FloatArray, name: str) -> Pose2D:
    """A plan's start pose: in its largest enclosed free region, else the interior grid point
    farthest from the walls."""
    world = World(segs, name=name)
    try:  # in the largest enclosed free region
        return default_start_pose(world, start_search_config(world))
    except FreeSpaceError:
        pass  # no room for the robot anywhere: the interior point farthest from the walls
    x0, y0, x1, y1 = world.bounds
    points = max(1000, _FALLBACK_SEARCH_PAIRS // verts.shape[0])
    step = max(0.1, math.sqrt((x1 - x0) * (y1 - y0) / points))
    gx, gy = np.meshgrid(np.arange(x0 + step / 2, x1, step), np.arange(y0 + step / 2, y1, step))
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    inside = _inside_polygon(pts, verts)
    pts = pts[inside]
    return start_pose_from_clearance(world, pts, clearance_m(pts, segs))


def _as_points(value: object, path: Path, key: str) -> FloatArray:
    if value is None:
        raise WorldError(f"{path}: missing key {key!r}")
    if isinstance(value, list | tuple) and len(value) > MAX_WORLD_SEGMENTS:
        raise WorldError(f"{path}: {key!r} has {len(value)} points, the limit is "
                         f"{MAX_WORLD_SEGMENTS}")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        raise WorldError(f"{path}: {key!r} must be a list of [x, y] numbers") from exc
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise WorldError(f"{path}: {key!r} must be a list of [x, y] pairs, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.argwhere(~np.isfinite(arr))[0][0])
        raise WorldError(f"{path}: {key!r} point {bad} has a NaN or infinite coordinate")
    if arr.size and float(np.max(np.abs(arr))) > MAX_COORD_M:
        bad = int(np.argwhere(np.abs(arr) > MAX_COORD_M)[0][0])
        raise WorldError(f"{path}: {key!r} point {bad}: |coordinate| must be <= {MAX_COORD_M:g} m "
                         f"(the limit), got {float(np.max(np.abs(arr[bad]))):g}")
    return arr


def _inside_polygon(pts: FloatArray, poly: FloatArray) -> BoolArray:
    """Even-odd rule point-in-polygon test for (K, 2) points against a closed (V, 2) polygon."""
    inside = np.zeros(pts.shape[0], dtype=bool)
    x, y = pts[:, 0], pts[:, 1]
    for (ax, ay), (bx, by) in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        if ay == by:
            continue
        crosses = (ay > y) != (by > y)
        xint = ax + (y - ay) * (bx - ax) / (by - ay)
        inside ^= crosses & (x < xint)
    return inside


def rectangles_to_segments(
    free_rects_m: Sequence[tuple[float, float, float, float]], resolution_m: float = 0.25
) -> FloatArray:
    """(N, 4) walls [m] around the union of free axis-aligned rectangles (x0, y0, x1, y1).

    Everything outside the rectangles is solid. Rectangle corners must lie on the grid of
    `resolution_m` so the walls are exact.
    """
    r = np.asarray(free_rects_m, dtype=np.float64).reshape(-1, 4)
    if r.shape[0] == 0:
        raise WorldError("rectangles_to_segments: no free rectangles")
    if np.any(r[:, 2] <= r[:, 0]) or np.any(r[:, 3] <= r[:, 1]):
        raise WorldError("rectangles_to_segments: a rectangle has x1 <= x0 or y1 <= y0")
    cells = r / resolution_m
    if not np.allclose(cells, np.round(cells), atol=1e-9):
        raise WorldError(f"rectangles_to_segments: corners must be multiples of {resolution_m} m")
    c = np.round(cells).astype(np.int64)
    lo = c[:, 0:2].min(axis=0) - 1
    hi = c[:, 2:4].max(axis=0) + 1
    occ = np.ones((int(hi[1] - lo[1]), int(hi[0] - lo[0])), dtype=bool)
    for x0, y0, x1, y1 in c - np.array([lo[0], lo[1], lo[0], lo[1]]):
        occ[y0:y1, x0:x1] = False
    origin = (float(lo[0] * resolution_m), float(lo[1] * resolution_m))
    return grid_to_segments(occ, resolution_m, origin, simplify_tol_px=0.0, outside_occupied=True)
