"""Exits of an island: the directions in which free space leads away from its origin.

Pure geometry in the island's frame (theta 0 along the hallway the robot arrived on). Sonar line
models are sparse (4-7 segments): a ray cast against the model alone sees gaps where walls were
seen at grazing incidence. So a way counts as free only while it keeps `clearance_m` from the
model's walls AND from the star's echo points (at least `min_points` of them); echo points on
paths the robot drove are noise and are dropped. A way is a *lane*: from the origin sideways by
up to `lane_offset_m` (a side corridor or a door need not start at the origin), then straight
along a heading for `reach_m`. Headings: the island's axes first (buildings are mostly
rectilinear and theta 0 lies along a hallway), then every `heading_step_deg`. Each run of free
lanes is an exit whose heading points from the origin into the opening; lanes within
`merge_deg` of a kept exit are the same exit. The exit facing where the robot came from is the
arrival (`arrival_exit`).

`gate` finds, in an island's model alone, the wall line an exit's ray passes through (a doorway,
a side corridor's mouth): where to stand before it and which way to drive through it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from island_msgs_py.geometry import point_segment_distance, wrap_angles
from island_msgs_py.types import (
    Exit,
    ExitSide,
    FloatArray,
    LineModel,
    wrap_angle,
)
from scipy.spatial import cKDTree

from island_mapping.core.builder.opening import OpeningExit
from island_mapping.core.explore.config import ExitConfig, ExploreError
from island_mapping.core.graph import strategy_displacement

# Spacing of the points sampled along a lane [m]; gates are looked for this far out at least.
_RAY_STEP_M = 0.1
_RAY_START_M = 0.3
# Axes of an island frame [rad].
_AXES_RAD = (0.0, 0.5 * math.pi, math.pi, -0.5 * math.pi)


@dataclass(frozen=True)
class ExitEvidence:
    """What an island's star saw, in the island frame [m].

    segments: (N, 4) the line model; points: (M, 2) echo points; driven: (K, 4) straight paths
    the robot drove (star legs, the approach): free by construction; arrival_rad: the direction
    from the origin toward where the robot came from (None: it did not arrive, island 0);
    looks: (R, 4) the star's readings, echo or not: where the robot was [m], the bearing [rad]
    and the range [m] (inf: no echo), for `look_through`.
    """

    segments: FloatArray
    points: FloatArray
    driven: FloatArray
    arrival_rad: float | None = None
    looks: FloatArray = field(default_factory=lambda: np.zeros((0, 4)))

    def __post_init__(self) -> None:
        # (name, columns, leading columns that must be finite: a look's range may be inf)
        for name, cols, finite in (("segments", 4, 4), ("points", 2, 2), ("driven", 4, 4),
                                   ("looks", 4, 3)):
            a = np.asarray(getattr(self, name), dtype=np.float64)
            if a.size == 0:
                a = np.zeros((0, cols))
            if a.ndim != 2 or a.shape[1] != cols or not np.all(np.isfinite(a[:, :finite])):
                raise ExploreError(f"ExitEvidence.{name}: expected a finite (N, {cols}) array, "
                                   f"got shape {a.shape}")
            object.__setattr__(self, name, a)
        if not np.all(self.looks[:, 3] > 0.0):  # inf is no echo; NaN fails
            raise ExploreError("ExitEvidence.looks: ranges must be > 0 (inf: no echo)")
        if self.arrival_rad is not None and not math.isfinite(self.arrival_rad):
            raise ExploreError(f"ExitEvidence.arrival_rad: not finite ({self.arrival_rad})")


@dataclass(frozen=True)
class Lane:
    """A straight way out: from the origin sideways to `offset_m` along the heading's left
    normal, then along `heading_rad` for reach_m, free of walls and echoes [m, rad]."""

    heading_rad: float
    offset_m: float
    width_m: float  # the free offsets around it, plus the clearance on both sides [m]

    def entry(self, entry_m: float) -> tuple[float, float]:
        """The point entry_m [m] along the lane from where it leaves the origin's line."""
        c, s = math.cos(self.heading_rad), math.sin(self.heading_rad)
        return (-s * self.offset_m + entry_m * c, c * self.offset_m + entry_m * s)


def _obstacle_points(ev: ExitEvidence, cfg: ExitConfig) -> FloatArray:
    pts = ev.points
    if pts.shape[0] == 0:
        return pts
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= cfg.evidence_range_m]
    if ev.driven.shape[0] and pts.shape[0] and cfg.driven_clearance_m > 0:
        near_path = point_segment_distance(pts, ev.driven).min(axis=1) < cfg.driven_clearance_m
        pts = pts[~near_path]
    return pts


def blocked_points(samples: FloatArray, ev: ExitEvidence, cfg: ExitConfig) -> np.ndarray:
    """Which samples (S, 2) [m] lie within clearance_m of a wall of the model or of at least
    min_points echo points (never those within driven_clearance_m of a path the robot
    drove)."""
    blocked = np.zeros(samples.shape[0], dtype=bool)
    if samples.shape[0] == 0:
        return blocked
    off_path = np.ones(samples.shape[0], dtype=bool)
    if ev.driven.shape[0]:  # the robot drove there: neither a wall nor an echo blocks it
        off_path = point_segment_distance(samples, ev.driven).min(axis=1) >= (
            cfg.driven_clearance_m)
    if ev.segments.shape[0]:
        near_wall = point_segment_distance(samples, ev.segments).min(axis=1) < cfg.clearance_m
        blocked |= near_wall & off_path
    pts = _obstacle_points(ev, cfg)
    todo = np.flatnonzero(~blocked & off_path)
    if pts.shape[0] and todo.size:
        counts = np.asarray(cKDTree(pts).query_ball_point(samples[todo], cfg.clearance_m,
                                                            return_length=True))
        blocked[todo[counts >= cfg.min_points]] = True
    return blocked


def candidate_headings(cfg: ExitConfig) -> FloatArray:
    """The headings lanes are tried along: the island's axes first, then every
    heading_step_deg [rad]."""
    step = math.radians(cfg.heading_step_deg)
    others = [wrap_angle(k * step) for k in range(math.ceil(2.0 * math.pi / step - 1e-9))]
    rest = [h for h in others if all(abs(wrap_angle(h - a)) > 1e-6 for a in _AXES_RAD)]
    return np.array([wrap_angle(a) for a in _AXES_RAD] + rest)


def free_lanes(ev: ExitEvidence, cfg: ExitConfig) -> list[Lane]:
    """Every run of free lanes, per candidate heading (widest first within a heading)."""
    headings = candidate_headings(cfg)
    offsets = np.arange(-cfg.lane_offset_m, cfg.lane_offset_m + 1e-9, _RAY_STEP_M)
    along = np.arange(0.0, cfg.reach_m + 1e-9, _RAY_STEP_M)
    chunks, owner = [], []
    for hk, h in enumerate(headings):
        u = np.array([math.cos(h), math.sin(h)])
        n = np.array([-u[1], u[0]])
        for ok, o in enumerate(offsets):
            side = np.arange(0.0, abs(o) + 1e-9, _RAY_STEP_M) * math.copysign(1.0, o)
            pts = np.concatenate([side[:, None] * n, o * n + along[:, None] * u])
            chunks.append(pts)
            owner.append(np.full(len(pts), hk * len(offsets) + ok))
    samples = np.concatenate(chunks)
    blocked = blocked_points(samples, ev, cfg)
    hits = np.bincount(np.concatenate(owner), weights=blocked, minlength=len(headings) * len(
        offsets)).reshape(len(headings), len(offsets))
    lanes = []
    for hk, h in enumerate(headings):
        free = hits[hk] == 0
        if hk < len(_AXES_RAD) and not free[len(offsets) // 2] and look_through(ev, h, cfg):
            lanes.append(Lane(float(h), 0.0, 2.0 * cfg.clearance_m))
        for first, length in _linear_runs(free):
            lo, hi = offsets[first], offsets[first + length - 1]
            lanes.append(Lane(float(h), float(0.5 * (lo + hi)),
                              float(hi - lo) + 2.0 * cfg.clearance_m))
    return lanes


def look_through(ev: ExitEvidence, heading_rad: float, cfg: ExitConfig) -> bool:
    """Does the star see straight out along `heading_rad` (an island axis) past reach_m? At
    least look_min_readings (and look_min_fraction) of the readings taken within look_from_m
    of the origin with a bearing within look_deg of it report no echo, or one beyond reach_m
    plus clearance_m ahead of the origin. A sonar reports the nearest echo anywhere in its
    wide cone as if on its axis, so a door jamb beside a hallway puts echoes, and model lines,
    across the hallway ahead; a wall across it faces these readings and echoes in every one
    of them. Off by look_through."""
    if not cfg.look_through or ev.looks.shape[0] == 0:
        return False
    lk = ev.looks
    near = np.hypot(lk[:, 0], lk[:, 1]) <= cfg.look_from_m
    off = wrap_angles(lk[:, 2] - heading_rad)
    along = near & (np.abs(off) <= math.radians(cfg.look_deg))
    # How far ahead of the origin, along the axis, each reading saw free [m].
    ahead = lk[:, 0] * math.cos(heading_rad) + lk[:, 1] * math.sin(heading_rad) + np.where(
        np.isinf(lk[:, 3]), np.inf, lk[:, 3] * np.cos(off))
    far = int(np.count_nonzero(along & (ahead > cfg.reach_m + cfg.clearance_m)))
    total = int(np.count_nonzero(along))
    return far >= cfg.look_min_readings and far >= cfg.look_min_fraction * total


def _linear_runs(flags: np.ndarray) -> list[tuple[int, int]]:
    """Runs of True as (first index, length)."""
    out, k, n = [], 0, len(flags)
    while k < n:
        if flags[k]:
            j = k
            while j < n and flags[j]:
                j += 1
            out.append((k, j - k))
            k = j
        else:
            k += 1
    return out


def find_exits(ev: ExitEvidence, cfg: ExitConfig | None = None) -> tuple[Exit, ...]:
    """The exits of an island (all unexplored; the arrival's too: see `arrival_exit`), indexed
    0.. in order of heading from -pi. Each is a run of free lanes (`free_lanes`): its heading
    points from the origin to where the lane enters the opening (entry_m along it); the axes of
    the island frame go first, and a lane within merge_deg of a kept exit is the same exit. The
    direction the robot came from is always one (it drove along it)."""
    c = cfg if cfg is not None else ExitConfig()
    kept: list[tuple[float, float]] = []
    for lane in free_lanes(ev, c):
        if lane.width_m < c.min_width_m:
            continue
        ex, ey = lane.entry(c.entry_m)
        h = math.atan2(ey, ex)
        if all(abs(wrap_angle(h - m)) > math.radians(c.merge_deg) for m, _ in kept):
            kept.append((h, lane.width_m))
    if ev.arrival_rad is not None and all(
        abs(wrap_angle(ev.arrival_rad - m)) > math.radians(c.arrival_match_deg) for m, _ in kept
    ):
        kept.append((wrap_angle(ev.arrival_rad), 2.0 * c.clearance_m + c.min_width_m))
    kept.sort(key=lambda e: e[0])
    return tuple(Exit(k, float(h), float(w)) for k, (h, w) in enumerate(kept))


def island_exits(ev: ExitEvidence, cfg: ExitConfig | None = None) -> tuple[Exit, ...]:
    """An island's exits: `find_exits`, through the gates in open space (`through_gates`);
    where no lane stays free reach_m (a small room whose doorway opens on a narrow hallway,
    its far wall nearer than reach_m), the lanes free closed_reach_m."""
    c = cfg if cfg is not None else ExitConfig()
    found = find_exits(ev, c)
    if not found and 0.0 < c.closed_reach_m < c.reach_m:
        found = find_exits(ev, replace(c, reach_m=c.closed_reach_m))
    return through_gates(found, ev, c)


_WIDTH_PROBES_M = (-0.5, 0.0, 0.5)
"""Offsets of the lines across which the free width is measured, each side of the origin [m]."""


def axis_widths(segments: FloatArray) -> tuple[float, float]:
    """The free width around the origin along the island's two axes (x, y) [m]: the nearest
    wall of the model ahead plus behind (left plus right), the narrowest over lines through
    points up to 0.5 m either side of the origin (a hallway's walls may begin just behind it);
    inf where none is seen."""
    model = LineModel(np.asarray(segments, dtype=np.float64).reshape(-1, 4))
    out = []
    for a, b in ((0, 2), (1, 3)):
        n = np.array([-math.sin(_AXES_RAD[a]), math.cos(_AXES_RAD[a])])
        out.append(min(_wall_along(model, _AXES_RAD[a], o * n) + _wall_along(
            model, _AXES_RAD[b], o * n) for o in _WIDTH_PROBES_M))
    return out[0], out[1]


def _wall_along(model: LineModel, heading_rad: float, start: FloatArray) -> float:
    """Distance from `start` to the first wall segment of `model` along heading_rad [m]."""
    segs = model.segments
    if segs.shape[0] == 0:
        return math.inf
    u = np.array([math.cos(heading_rad), math.sin(heading_rad)])
    a, d = segs[:, :2] - start, segs[:, 2:] - segs[:, :2]
    denom = u[0] * d[:, 1] - u[1] * d[:, 0]
    ok = np.abs(denom) > 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[:, 0] * d[:, 1] - a[:, 1] * d[:, 0]) / denom
        s = (a[:, 0] * u[1] - a[:, 1] * u[0]) / denom
    hit = ok & (t > 0) & (s >= 0) & (s <= 1)
    return float(t[hit].min()) if np.any(hit) else math.inf


def through_gates(exits: tuple[Exit, ...], ev: ExitEvidence, cfg: ExitConfig | None = None
                  ) -> tuple[Exit, ...]:
    """In open space (a room or a hall: the model's free width along both island axes at least
    `open_width_m`) the way out is through the gaps in its walls, not toward them: the
    exits whose ray passes a gate (a doorway, a hallway's mouth), and the arrival. In a
    hallway, all of them."""
    c = cfg if cfg is not None else ExitConfig()
    if min(axis_widths(ev.segments)) < c.open_width_m:
        return exits
    arrival = None if ev.arrival_rad is None else arrival_exit(exits, ev.arrival_rad, c)
    model = LineModel(ev.segments)
    keep = [e for e in exits if e is arrival or wall_gap(model, e.heading_rad, c) is not None]
    return tuple(Exit(k, e.heading_rad, e.width_m) for k, e in enumerate(keep))


def wall_gap(model: LineModel, heading_rad: float, cfg: ExitConfig,
             max_m: float = 6.0) -> float | None:
    """Where the ray from the origin along heading_rad first crosses a gap in a wall within
    max_m [m] (its distance [m]): between the ends of two wall segments of the model that
    lie on one line (within gap_line_m of it, gap_line_deg of its direction) and at least
    min_width_m apart, the crossing between them. None when it crosses none: the ray runs
    into a wall, or out where no wall was seen (an unseen corner is no way out)."""
    segs = model.segments
    if segs.shape[0] < 2:
        return None
    u = np.array([math.cos(heading_rad), math.sin(heading_rad)])
    best: float | None = None
    for i in range(segs.shape[0]):
        for j in range(i + 1, segs.shape[0]):
            t = _gap_crossing(segs[i], segs[j], u, cfg)
            if t is not None and t <= max_m and (best is None or t < best):
                best = t
    return best


def _gap_crossing(a: FloatArray, b: FloatArray, u: FloatArray, cfg: ExitConfig
                  ) -> float | None:
    """The distance along the ray u at which it passes between collinear segments a and b
    (through the gap between their nearest ends), or None."""
    da, db = a[2:] - a[:2], b[2:] - b[:2]
    la, lb = float(np.hypot(*da)), float(np.hypot(*db))
    if la < 1e-6 or lb < 1e-6:
        return None
    ua, ub = da / la, db / lb
    if abs(ua[0] * ub[1] - ua[1] * ub[0]) > math.sin(math.radians(cfg.gap_line_deg)):
        return None
    n = np.array([-ua[1], ua[0]])
    if abs(float(n @ (b[:2] - a[:2]))) > cfg.gap_line_m or abs(float(n @ (b[2:] - a[:2]))) > (
        cfg.gap_line_m
    ):
        return None
    sa = sorted((0.0, la))
    sb = sorted((float(ua @ (b[:2] - a[:2])), float(ua @ (b[2:] - a[:2]))))
    lo, hi = (sa[1], sb[0]) if sb[0] >= sa[1] else (sb[1], sa[0])
    if hi - lo < cfg.min_width_m:
        return None  # overlapping or too narrow a gap
    denom = float(u @ n)
    if abs(denom) < 1e-9:
        return None
    t = float(n @ a[:2]) / denom  # the ray meets the wall line at t
    if t <= 0.0:
        return None
    along = float(ua @ (t * u - a[:2]))
    return t if lo < along < hi else None


def opening_exits(exits: tuple[Exit, ...], ev: ExitEvidence, opening: OpeningExit,
                  cfg: ExitConfig | None = None) -> tuple[Exit, ...]:
    """The exits of an island built inside a side opening (theta 0 into it): the arrival, the
    exits leading on into the opening (within `opening_ahead_deg` of theta 0; none behind a
    doorway: the island stands in the room and covers it, and a room's other doorway is
    found from its own hallway), and
    the hallway's continuation past the opening as a side exit (back out to the hallway's
    middle, then a quarter turn the way the follower was going). The hallway behind (the way
    the robot came) is the arrival's."""
    c = cfg if cfg is not None else ExitConfig()
    arrival = None if ev.arrival_rad is None else arrival_exit(exits, ev.arrival_rad, c)
    keep = [e for e in exits if e is arrival or (not opening.narrow and abs(
        e.heading_rad) <= math.radians(c.opening_ahead_deg))]
    out = [Exit(k, e.heading_rad, e.width_m) for k, e in enumerate(keep)]
    # Back at the hallway's middle facing into the opening, a quarter turn away from the
    # side it lay on faces the way the follower was going.
    side = ExitSide.RIGHT if opening.side > 0 else ExitSide.LEFT
    end = strategy_displacement(opening.back)
    turn = -0.5 * math.pi if side is ExitSide.RIGHT else 0.5 * math.pi
    out.append(Exit(len(out), wrap_angle(end.theta + turn), max(opening.width_m, c.min_width_m),
                    prefix=opening.back, side=side))
    return tuple(out)


def nearest_exit(exits: tuple[Exit, ...], heading_rad: float, within_deg: float) -> Exit | None:
    """The exit whose heading lies nearest `heading_rad`, if within `within_deg`."""
    best = min(exits, key=lambda e: abs(wrap_angle(e.heading_rad - heading_rad)), default=None)
    if best is None or abs(wrap_angle(best.heading_rad - heading_rad)) > math.radians(within_deg):
        return None
    return best


def arrival_exit(exits: tuple[Exit, ...], arrival_rad: float, cfg: ExitConfig | None = None
                 ) -> Exit | None:
    """The exit facing where the robot came from (within arrival_match_deg), or None."""
    c = cfg if cfg is not None else ExitConfig()
    return nearest_exit(exits, arrival_rad, c.arrival_match_deg)


@dataclass(frozen=True)
class Gate:
    """Where an exit's ray passes through a wall line of the model: its crossing point and the
    wall's normal pointing out along the exit [m, rad], island frame."""

    x_m: float
    y_m: float
    normal_rad: float
    distance_m: float  # from the origin along the exit heading


def gate(model: LineModel, heading_rad: float, max_m: float = 4.0, end_near_m: float = 1.5
         ) -> Gate | None:
    """The first wall line (a model segment's infinite line, not the segment itself) that the
    ray along `heading_rad` crosses within max_m [m], beside the end of that segment (within
    end_near_m [m]: a doorway or a side corridor's mouth); None when the ray crosses none (an
    exit straight along a hallway)."""
    segs = model.segments
    if segs.shape[0] == 0:
        return None
    u = np.array([math.cos(heading_rad), math.sin(heading_rad)])
    a, b = segs[:, :2], segs[:, 2:]
    d = b - a
    denom = u[0] * d[:, 1] - u[1] * d[:, 0]
    ok = np.abs(denom) > 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[:, 0] * d[:, 1] - a[:, 1] * d[:, 0]) / denom  # along the ray [m]
        s = (a[:, 0] * u[1] - a[:, 1] * u[0]) / denom  # along the segment [-]
    length = np.hypot(d[:, 0], d[:, 1])
    outside = np.maximum(-s, s - 1.0) * length  # how far past the segment's end [m]
    cand = ok & (t > _RAY_START_M) & (t <= max_m) & (outside > 0) & (outside <= end_near_m)
    if not np.any(cand):
        return None
    k = int(np.flatnonzero(cand)[np.argmin(t[cand])])
    normal = np.array([-d[k, 1], d[k, 0]]) / length[k]
    if float(normal @ u) < 0:
        normal = -normal
    p = t[k] * u
    return Gate(float(p[0]), float(p[1]), math.atan2(normal[1], normal[0]), float(t[k]))
