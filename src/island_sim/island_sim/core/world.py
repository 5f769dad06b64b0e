"""Line-segment worlds (numpy only): `World`, start poses, the YAML/JSON form, atomic saving.

A world is a set of wall segments (N, 4) rows (x1, y1, x2, y2) [m] in the world frame, a name
and a start pose. `World.raycast` casts rays with the shared `island_msgs_py.raycast` index.
A world without a start pose gets the enclosed point farthest from the walls
(`enclosed_start_pose`). Loading by name or file of any kind: `world_loader.load_world`.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import clearance_m
from island_msgs_py.json_checks import describe
from island_msgs_py.limits import MAX_COORD_M, MAX_WORLD_FILE_BYTES, MAX_WORLD_SEGMENTS
from island_msgs_py.raycast import RaycastError, RayHits, SegmentIndex
from island_msgs_py.types import FloatArray, Pose2D

from island_msgs_py import inputs

# Bearings tried when choosing the start heading (the longest free ray wins) [-].
_START_BEARINGS = 72
# Most grid points of the start-pose search (enclosed_start_pose) [-].
_START_GRID_POINTS = 10_000
# Most (grid point x wall) pairs of the start-pose search: a world of more than
# _START_SEARCH_PAIRS / _START_GRID_POINTS walls is searched on a coarser grid, so the search
# costs about the same whatever the world's size (200,000 walls: 1,000 points) [-].
_START_SEARCH_PAIRS = 100_000_000
MAX_NAME_CHARS = 256
"""Longest world name [characters]."""


class WorldError(InputError):
    """A world file or world description is malformed; the message names the file and problem."""


@dataclass(frozen=True, eq=False)
class World:
    """Wall segments (N, 4) [m] in the world frame, a name and a default start pose.

    Immutable: the segments are copied into a read-only float64 array. The spatial index used by
    `raycast` is built lazily on first use and cached.
    """

    segments: FloatArray
    name: str = "world"
    start_pose: Pose2D = field(default_factory=lambda: Pose2D(0.0, 0.0, 0.0))
    _index: SegmentIndex | None = field(
        default=None, init=False, repr=False, compare=False, hash=False
    )

    def __post_init__(self) -> None:
        arr = np.array(self.segments, dtype=np.float64, copy=True)
        if arr.size == 0:
            arr = np.zeros((0, 4), dtype=np.float64)
        if arr.ndim != 2 or arr.shape[1] != 4:
            raise WorldError(
                f"world {self.name!r}: segments must be an (N, 4) array, got shape {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            bad = int(np.argwhere(~np.isfinite(arr))[0][0])
            raise WorldError(f"world {self.name!r}: segment {bad} has a NaN or infinite coordinate")
        if arr.size and float(np.max(np.abs(arr))) > MAX_COORD_M:
            bad = int(np.argwhere(np.abs(arr) > MAX_COORD_M)[0][0])
            raise WorldError(f"world {self.name!r}: segment {bad} has a coordinate beyond "
                             f"{MAX_COORD_M:g} m (the limit)")
        arr.setflags(write=False)
        object.__setattr__(self, "segments", arr)

    def __copy__(self) -> World:
        return self  # immutable

    def __deepcopy__(self, memo: dict[int, Any]) -> World:
        return self  # immutable; the cached index holds a lock that cannot be copied

    def __reduce__(self) -> tuple[Any, ...]:
        """Pickled (to a worker process) as its segments, name and start pose: the cached index
        holds a lock, and the copy builds its own on first use."""
        return (World, (np.asarray(self.segments), self.name, self.start_pose))

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) [m] of all segment endpoints (0s for an empty world)."""
        if self.segments.shape[0] == 0:
            return 0.0, 0.0, 0.0, 0.0
        pts = self.segments.reshape(-1, 2)
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])

    @property
    def index(self) -> SegmentIndex:
        """The spatial index over the segments (built once, on first use)."""
        if self._index is None:
            object.__setattr__(self, "_index", SegmentIndex(self.segments))
        assert self._index is not None
        return self._index

    def raycast(
        self, origins: npt.ArrayLike, angles_rad: npt.ArrayLike, max_range_m: float = np.inf
    ) -> RayHits:
        """First hits of rays from `origins` (M, 2) [m] along `angles_rad` (M,).

        Uses the spatial index; the result equals the brute-force `island_msgs_py.raycast.raycast`
        exactly. Mismatched origins and angles raise WorldError.
        """
        try:
            return self.index.raycast(origins, angles_rad, max_range_m)
        except RaycastError as exc:
            raise WorldError(f"world {self.name!r}: {exc}") from None


# ----------------------------------------------------------------------------- start poses


def start_pose_from_clearance(
    world: World, candidates_m: FloatArray, clearances_m: FloatArray
) -> Pose2D:
    """The candidate point with the largest clearance, facing its longest free ray.

    candidates_m: (K, 2) points [m]; clearances_m: (K,) distance to the nearest wall [m].
    """
    if candidates_m.shape[0] == 0:
        raise WorldError(f"world {world.name!r}: cannot choose a start pose, no free space")
    best = int(np.argmax(clearances_m))
    x, y = (float(v) for v in candidates_m[best])
    bearings = np.linspace(-math.pi, math.pi, _START_BEARINGS, endpoint=False)
    ranges = world.raycast(np.array([[x, y]]), bearings).distance_m
    ranges = np.where(np.isfinite(ranges), ranges, -1.0)
    return Pose2D(x, y, float(bearings[int(np.argmax(ranges))]))


def enclosed_start_pose(world: World, step_m: float = 0.25) -> Pose2D:
    """A start pose for a world without one: the enclosed grid point farthest from any wall.

    A point is enclosed when rays in 8 directions all hit a wall.
    """
    if world.segments.shape[0] == 0:
        return Pose2D(0.0, 0.0, 0.0)
    x0, y0, x1, y1 = world.bounds
    side = math.isqrt(min(_START_GRID_POINTS, _START_SEARCH_PAIRS // world.segments.shape[0]))
    nx = max(2, min(side, int((x1 - x0) / step_m)))
    ny = max(2, min(side, int((y1 - y0) / step_m)))
    gx, gy = np.meshgrid(np.linspace(x0, x1, nx + 2)[1:-1], np.linspace(y0, y1, ny + 2)[1:-1])
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
    dirs = np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)
    hits = world.raycast(np.repeat(pts, 8, axis=0), np.tile(dirs, pts.shape[0]))
    enclosed = np.all(np.isfinite(hits.distance_m.reshape(-1, 8)), axis=1)
    if not np.any(enclosed):
        enclosed[:] = True
    pts = pts[enclosed]
    clearance = clearance_m(pts, world.segments)
    return start_pose_from_clearance(world, pts, clearance)


# ----------------------------------------------------------------------------- world files


def read_structured(path: Path) -> dict[str, Any]:
    """The top-level mapping of a YAML or JSON world file, within the limits of
    `island_msgs_py.inputs` (size, UTF-8, nesting, aliases, integer length); WorldError if not."""
    return inputs.read_structured(path, WorldError, MAX_WORLD_FILE_BYTES, "world file")


def _coordinates(row: Any, where: str, form: str) -> list[float]:
    """The numbers of `form` (`[x1, y1, x2, y2]`), finite and within MAX_COORD_M (booleans are
    no numbers); WorldError naming `where` otherwise."""
    count = form.count(",") + 1
    if not isinstance(row, list | tuple) or len(row) != count:
        raise WorldError(f"{where} must be {form}, got {describe(row)}")
    vals = []
    for j, v in enumerate(row):
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise WorldError(f"{where} has a non-numeric value at {j}: {describe(v)}")
        try:
            f = float(v)
        except OverflowError:
            f = math.inf
        if not math.isfinite(f):
            raise WorldError(f"{where} has a NaN or infinite value at {j}: {describe(v)}")
        if abs(f) > MAX_COORD_M:
            raise WorldError(f"{where}: |value {j}| must be <= {MAX_COORD_M:g} m (the limit), "
                             f"got {f:g}")
        vals.append(f)
    return vals


def world_from_dict(data: dict[str, Any], source: str = "<dict>") -> World:
    """A World from {'segments': [[x1, y1, x2, y2], ...] [m], 'name'?, 'start_pose'?: [x, y, th]}.

    Errors name `source`, the field and the limit (missing key, wrong shape, NaN/inf, a
    coordinate beyond MAX_COORD_M, more than MAX_WORLD_SEGMENTS segments, zero length).
    """
    if "segments" not in data:
        raise WorldError(f"{source}: missing key 'segments'")
    raw = data["segments"]
    if not isinstance(raw, list | tuple):
        raise WorldError(f"{source}: 'segments' must be a list of [x1, y1, x2, y2], got "
                         f"{describe(raw)}")
    if len(raw) > MAX_WORLD_SEGMENTS:
        raise WorldError(f"{source}: {len(raw)} segments, the limit is {MAX_WORLD_SEGMENTS}")
    rows = []
    for i, row in enumerate(raw):
        vals = _coordinates(row, f"{source}: segment {i}", "[x1, y1, x2, y2]")
        if vals[0] == vals[2] and vals[1] == vals[3]:
            raise WorldError(f"{source}: segment {i} has zero length: {describe(row)}")
        rows.append(vals)
    if not rows:
        raise WorldError(f"{source}: 'segments' is empty")
    name = data.get("name", Path(source).stem if source != "<dict>" else "world")
    if not isinstance(name, str) or not name or len(name) > MAX_NAME_CHARS:
        raise WorldError(f"{source}: 'name' must be a string of 1 to {MAX_NAME_CHARS} "
                         f"characters, got {describe(name)}")
    segments = np.array(rows, dtype=np.float64)
    if "start_pose" in data and data["start_pose"] is not None:
        x, y, th = _coordinates(data["start_pose"], f"{source}: start_pose", "[x, y, theta]")
        return World(segments, name=name, start_pose=Pose2D(x, y, th))
    world = World(segments, name=name)
    return World(world.segments, name=name, start_pose=enclosed_start_pose(world))


def world_to_dict(world: World) -> dict[str, Any]:
    """The YAML/JSON form of a world (floats kept exact)."""
    sp = world.start_pose
    return {
        "name": world.name,
        "start_pose": [float(sp.x), float(sp.y), float(sp.theta)],
        "segments": [[float(v) for v in row] for row in world.segments.tolist()],
    }


def save_world(world: World, path: str | Path) -> Path:
    """Write `world` atomically as YAML (or JSON for a .json path); returns the path."""
    p = Path(path)
    data = world_to_dict(world)
    if p.suffix.lower() == ".json":
        text = json.dumps(data, indent=1)
    else:
        import yaml

        text = yaml.safe_dump(data, default_flow_style=None, sort_keys=False)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", dir=p.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return p
