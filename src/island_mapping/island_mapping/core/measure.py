"""The distinctiveness measure R of a line model (Simhon & Dudek, eqs. 4-12), vectorized.

Semantics (exactly; anyone can recompute it from this docstring):

- From a point p, rays leave every `angular_res_deg` over 360 deg (ray j at angle j * res).
- Each ray's FIRST hit (occlusion) is found with `island_msgs_py.raycast`, the project's
  only ray caster: distance d [m], hit segment i and incidence cosine |N_i . u|.
- A ray counts for segment i when d <= `max_range_m` and its incidence angle (between the ray
  and the wall normal) is <= `reflect_deg` (specular sonar: steeper rays give no echo).
- Vector influence (eq. 7, 8): V_i = N_i * S_i with S_i = sum over counted rays of
  exp(-k d) |N_i . u| dtheta, dtheta = angular_res_deg in radians. N_i is the unit normal of
  segment i (its sign is irrelevant: only absolute projections are used below).
- Reference vector: the longest V_i (ties: the lowest segment index).
- C_par = sum_i |ref_hat . V_i|, C_perp = sum_i |ref_hat x V_i| (eqs. 9, 10), unfiltered.
- Sigmoid filter (eq. 11): C' = C^m / (c^m + C^m), for both.
- Q = min(C'_par, C'_perp) / max(C'_par, C'_perp), 0 when both are 0 (eq. 12).
- F = min(C'_par, C'_perp) (eq. 5); r = F (1 + Q) / 2 (the integrand of eq. 4).
- R(p, eps) = mean of r over the square [x - eps, x + eps] x [y - eps, y + eps] sampled on a grid
  of step `eps_step_m` centred on p (eqs. 4, 6); eps = 0 gives r at p.

Everything is in metres and radians unless a name says otherwise. All rays of all points go to
the ray caster in one call per chunk; per-(point, segment) sums use `numpy.bincount`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
import numpy.typing as npt
from island_msgs_py.raycast import RayCaster
from island_msgs_py.types import FloatArray, ModelType

from island_mapping.core.fisher import FisherConfig, fisher_measure
from island_mapping.core.rays import (
    MAX_EPS_STEPS,
    MIN_ANGULAR_RES_DEG,
    MeasureError,
    as_caster,
    as_points,
    cast_chunk,
    ray_angles,
    tiled_chunks,
)

# Rays per ray-cast call: small enough to stay in cache (measured 2x faster than 1 << 17).
_RAYS_PER_CHUNK = 1 << 13
# Upper bound on (points x segments) bins held at once by the per-segment bincount.
_BINS_PER_CHUNK = 1 << 23


@dataclass(frozen=True)
class MeasureConfig:
    """Parameters of the line-model distinctiveness measure R (single source of defaults).

    The defaults match the simulated Nomad-200 sonar ring (island_sim SonarConfig): echoes only
    within 30 deg of the wall normal and up to 6.5 m; k, c and m were chosen so that a 3 m wide
    corridor scores r ~ 0 and a crossing of two such corridors scores r > 0.5 (see
    docs/measure.md for the fitted values from the validation).
    """

    k: float = field(
        default=0.3,
        metadata={"help": "decay constant of the range weight W = exp(-k d) (eq. 8) [1/m]"},
    )
    c: float = field(
        default=0.35,
        metadata={"help": "sigmoid cutoff of the filter C^m/(c^m + C^m) (eq. 11) [rad]"},
    )
    m: float = field(
        default=4.0, metadata={"help": "sigmoid exponent (steepness) of the filter (eq. 11) [-]"}
    )
    reflect_deg: float = field(
        default=30.0,
        metadata={"help": "largest incidence angle between ray and wall normal that counts "
                  "(specular reflection) [deg]"},
    )
    max_range_m: float = field(
        default=6.5, metadata={"help": "farthest hit that counts (sensor range) [m]"}
    )
    angular_res_deg: float = field(
        default=2.0, metadata={"help": "angular step between rays over 360 deg [deg]"}
    )
    eps_m: float = field(
        default=0.0,
        metadata={"help": "half side of the square over which r is averaged, R(p, eps) (eq. 4); "
                  "0 = r at p [m]"},
    )
    eps_step_m: float = field(
        default=0.1, metadata={"help": "grid step of the averaging square [m]"}
    )

    def __post_init__(self) -> None:
        for name in ("k", "c", "m", "reflect_deg", "max_range_m", "angular_res_deg", "eps_m",
                     "eps_step_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise MeasureError(f"MeasureConfig.{name}: expected a finite number, got {v!r}")
        if self.k < 0:
            raise MeasureError(f"MeasureConfig.k: must be >= 0 [1/m], got {self.k}")
        if self.c <= 0:
            raise MeasureError(f"MeasureConfig.c: must be > 0, got {self.c}")
        if self.m <= 0:
            raise MeasureError(f"MeasureConfig.m: must be > 0, got {self.m}")
        if not 0.0 < self.reflect_deg <= 90.0:
            raise MeasureError(
                f"MeasureConfig.reflect_deg: must be in (0, 90] deg, got {self.reflect_deg}"
            )
        if self.max_range_m <= 0:
            raise MeasureError(f"MeasureConfig.max_range_m: must be > 0, got {self.max_range_m}")
        if not MIN_ANGULAR_RES_DEG <= self.angular_res_deg <= 90.0:
            raise MeasureError(
                f"MeasureConfig.angular_res_deg: must be in [{MIN_ANGULAR_RES_DEG:g}, 90] deg "
                f"(the limit), got {self.angular_res_deg:g}"
            )
        if self.eps_m < 0:
            raise MeasureError(f"MeasureConfig.eps_m: must be >= 0, got {self.eps_m}")
        if self.eps_step_m <= 0:
            raise MeasureError(f"MeasureConfig.eps_step_m: must be > 0, got {self.eps_step_m}")
        if self.eps_m / self.eps_step_m > MAX_EPS_STEPS:
            raise MeasureError(
                f"MeasureConfig: eps_m / eps_step_m must be <= {MAX_EPS_STEPS} (the limit: "
                f"{(2 * MAX_EPS_STEPS + 1) ** 2} samples per point), got "
                f"{self.eps_m / self.eps_step_m:g}")

    @property
    def n_rays(self) -> int:
        """Rays per point over 360 deg."""
        return max(1, round(360.0 / self.angular_res_deg))


@dataclass(frozen=True, eq=False)
class MeasureResult:
    """Per-point values of the measure; every field is a (P,) array.

    c_par, c_perp: unfiltered constraint sums (eqs. 9, 10) [rad, the unit of the ray integral];
    q: quality ratio of the filtered pair (eq. 12) [0, 1]; f: the smaller filtered value (eq. 5);
    r: F (1 + Q) / 2 at p; r_eps: R(p, eps) (eq. 4), equal to r when eps_m = 0.
    """

    c_par: FloatArray
    c_perp: FloatArray
    q: FloatArray
    f: FloatArray
    r: FloatArray
    r_eps: FloatArray


@dataclass(frozen=True, eq=False)
class RayBundle:
    """The ray-cast part of the measure, independent of k, c and m (cache it to refit them).

    Flat arrays over the counted rays only: `point` (index into the P points), `segment`,
    `distance_m`, `cos_incidence`; plus the (K, 2) unit normals, P, K and dtheta [rad].
    """

    point: npt.NDArray[np.int64]
    segment: npt.NDArray[np.int64]
    distance_m: FloatArray
    cos_incidence: FloatArray
    normals: FloatArray
    n_points: int
    n_segments: int
    dtheta_rad: float


def segment_normals(segments: FloatArray) -> FloatArray:
    """(K, 2) unit normals (left of the direction p1 -> p2) of (K, 4) segments."""
    d = segments[:, 2:4] - segments[:, 0:2]
    length = np.linalg.norm(d, axis=1)
    length = np.where(length > 0, length, 1.0)
    return np.stack([-d[:, 1], d[:, 0]], axis=1) / length[:, None]


def cast_rays(
    segments: npt.ArrayLike | RayCaster,
    points: npt.ArrayLike,
    angular_res_deg: float,
    max_range_m: float,
    reflect_deg: float,
) -> RayBundle:
    """Cast all rays of all `points` (P, 2) [m] and keep the counted ones (range, reflectance).

    Rays go tile by tile to the model's spatial index or, for tiles near few segments, to the
    brute-force caster (`rays.tiled_chunks`; identical hits either way).
    """
    caster = as_caster(segments)
    seg = caster.segments
    pts = as_points(points)
    angles = ray_angles(angular_res_deg)
    n_rays = angles.shape[0]
    p_count, k_count = pts.shape[0], seg.shape[0]
    cos_min = math.cos(math.radians(reflect_deg)) - 1e-12
    keep_p: list[npt.NDArray[np.int64]] = []
    keep_s: list[npt.NDArray[np.int64]] = []
    keep_d: list[FloatArray] = []
    keep_c: list[FloatArray] = []
    if p_count and k_count:
        pts_per_chunk = max(1, _RAYS_PER_CHUNK // n_rays)
        for members, sub in tiled_chunks(pts, seg, max_range_m, pts_per_chunk):
            _, hits = cast_chunk(caster, pts, members, sub, angles, max_range_m)
            ok = (hits.segment >= 0) & (hits.distance_m <= max_range_m)
            ok &= hits.cos_incidence >= cos_min
            idx = np.flatnonzero(ok)
            keep_p.append(members[idx // n_rays])
            keep_s.append(hits.segment[idx])
            keep_d.append(hits.distance_m[idx])
            keep_c.append(hits.cos_incidence[idx])

    def cat_i(xs: list[npt.NDArray[np.int64]]) -> npt.NDArray[np.int64]:
        return np.concatenate(xs).astype(np.int64) if xs else np.zeros(0, dtype=np.int64)

    def cat_f(xs: list[FloatArray]) -> FloatArray:
        return np.concatenate(xs) if xs else np.zeros(0)

    point = cat_i(keep_p)
    order = np.argsort(point, kind="stable")  # tiles visit points out of order
    return RayBundle(
        point=point[order],
        segment=cat_i(keep_s)[order],
        distance_m=cat_f(keep_d)[order],
        cos_incidence=cat_f(keep_c)[order],
        normals=segment_normals(seg),
        n_points=p_count,
        n_segments=k_count,
        dtheta_rad=math.radians(angular_res_deg),
    )


def sigmoid_filter(c_values: FloatArray, cutoff: float, exponent: float) -> FloatArray:
    """C^m / (c^m + C^m) (eq. 11), computed stably as 1 / (1 + (c / C)^m); 0 where C = 0."""
    c_values = np.asarray(c_values, dtype=np.float64)
    out = np.zeros_like(c_values)
    pos = c_values > 0
    with np.errstate(over="ignore"):
        out[pos] = 1.0 / (1.0 + (cutoff / c_values[pos]) ** exponent)
    return out


def constraint_sums(bundle: RayBundle, k: float) -> tuple[FloatArray, FloatArray]:
    """Unfiltered (C_par, C_perp) per point (eqs. 7-10) for decay constant k [1/m]."""
    p_count, k_count = bundle.n_points, bundle.n_segments
    c_par = np.zeros(p_count)
    c_perp = np.zeros(p_count)
    if p_count == 0 or k_count == 0 or bundle.point.size == 0:
        return c_par, c_perp
    weight = np.exp(-k * bundle.distance_m) * bundle.cos_incidence * bundle.dtheta_rad
    # Points in chunks so that the (points x segments) strength table stays bounded.
    pts_per_chunk = max(1, _BINS_PER_CHUNK // k_count)
    bounds = np.searchsorted(bundle.point, np.arange(0, p_count + pts_per_chunk, pts_per_chunk))
    for ci in range(len(bounds) - 1):
        lo, hi = int(bounds[ci]), int(bounds[ci + 1])
        p0 = ci * pts_per_chunk
        p1 = min(p_count, p0 + pts_per_chunk)
        if p1 <= p0:
            break
        n_here = p1 - p0
        flat = (bundle.point[lo:hi] - p0) * k_count + bundle.segment[lo:hi]
        strength = np.bincount(flat, weights=weight[lo:hi], minlength=n_here * k_count)
        strength = strength.reshape(n_here, k_count)  # S_i per point = |V_i|
        ref = np.argmax(strength, axis=1)  # longest V_i, lowest index on ties
        n_ref = bundle.normals[ref]  # (n, 2)
        cos_ang = np.abs(n_ref @ bundle.normals.T)  # (n, K) |ref_hat . N_i|
        sin_ang = np.abs(
            n_ref[:, 0:1] * bundle.normals[None, :, 1] - n_ref[:, 1:2] * bundle.normals[None, :, 0]
        )
        c_par[p0:p1] = np.sum(strength * cos_ang, axis=1)
        c_perp[p0:p1] = np.sum(strength * sin_ang, axis=1)
    return c_par, c_perp


def combine(
    c_par: FloatArray, c_perp: FloatArray, cutoff: float, exponent: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(Q, F, r) from unfiltered constraint sums (eqs. 5, 11, 12 and the integrand of eq. 4)."""
    fp = sigmoid_filter(c_par, cutoff, exponent)
    fq = sigmoid_filter(c_perp, cutoff, exponent)
    lo = np.minimum(fp, fq)
    hi = np.maximum(fp, fq)
    q = np.divide(lo, hi, out=np.zeros_like(lo), where=hi > 0)
    r = lo * (1.0 + q) / 2.0
    return q, lo, r


def eps_offsets(eps_m: float, step_m: float) -> FloatArray:
    """(n, 2) offsets [m] of the averaging square's grid: step_m apart, centred, within +-eps."""
    if eps_m <= 0:
        return np.zeros((1, 2))
    half = math.floor(eps_m / step_m + 1e-9)
    ticks = np.arange(-half, half + 1) * step_m
    gx, gy = np.meshgrid(ticks, ticks, indexing="xy")
    return np.stack([gx.ravel(), gy.ravel()], axis=1)


def measure_from_bundle(bundle: RayBundle, config: MeasureConfig) -> MeasureResult:
    """The measure at the bundle's points (r_eps = r: the bundle holds no averaging grid)."""
    c_par, c_perp = constraint_sums(bundle, config.k)
    q, f, r = combine(c_par, c_perp, config.c, config.m)
    return MeasureResult(c_par, c_perp, q, f, r, r.copy())


def line_measure(
    segments: npt.ArrayLike | RayCaster, points: npt.ArrayLike, config: MeasureConfig | None = None
) -> MeasureResult:
    """The measure at `points` (P, 2) [m] of a line model `segments` (K, 4) [m]; see module doc.

    With config.eps_m > 0, r_eps is the mean of r over each point's averaging square.
    """
    cfg = config if config is not None else MeasureConfig()
    seg = as_caster(segments)
    pts = as_points(points)
    bundle = cast_rays(seg, pts, cfg.angular_res_deg, cfg.max_range_m, cfg.reflect_deg)
    res = measure_from_bundle(bundle, cfg)
    if cfg.eps_m > 0 and pts.shape[0]:
        offs = eps_offsets(cfg.eps_m, cfg.eps_step_m)
        around = (pts[:, None, :] + offs[None, :, :]).reshape(-1, 2)
        sub = cast_rays(seg, around, cfg.angular_res_deg, cfg.max_range_m, cfg.reflect_deg)
        r_around = measure_from_bundle(sub, cfg).r.reshape(pts.shape[0], offs.shape[0])
        return replace(res, r_eps=r_around.mean(axis=1))
    return res


MAX_GRID_POINTS = 4_000_000
"""Most points of one measure grid (a 200 m x 200 m world at 0.1 m) [-]."""


def grid_points(
    bounds: tuple[float, float, float, float], resolution_m: float
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Cell-centre ticks xs (nx,), ys (ny,) [m] covering bounds and the (ny*nx, 2) points."""
    xmin, ymin, xmax, ymax = (float(b) for b in bounds)
    if not all(math.isfinite(b) for b in (xmin, ymin, xmax, ymax)) or xmax < xmin or ymax < ymin:
        raise MeasureError(f"bounds: expected finite (xmin, ymin, xmax, ymax), got {bounds}")
    if not (math.isfinite(resolution_m) and resolution_m > 0):
        raise MeasureError(f"resolution_m: must be > 0, got {resolution_m}")
    nx = max(1, math.floor((xmax - xmin) / resolution_m + 1e-9))
    ny = max(1, math.floor((ymax - ymin) / resolution_m + 1e-9))
    if nx * ny > MAX_GRID_POINTS:
        raise MeasureError(
            f"resolution_m: {resolution_m:g} m makes a grid of {nx} x {ny} points over the "
            f"bounds (the limit is {MAX_GRID_POINTS:,} points)")
    xs = xmin + (np.arange(nx, dtype=np.float64) + 0.5) * resolution_m
    ys = ymin + (np.arange(ny, dtype=np.float64) + 0.5) * resolution_m
    gx, gy = np.meshgrid(xs, ys, indexing="xy")
    pts = np.stack([gx.ravel(), gy.ravel()], axis=1).astype(np.float64)
    return xs, ys, pts


def measure_map(
    segments: npt.ArrayLike | RayCaster,
    bounds: tuple[float, float, float, float],
    resolution_m: float,
    config: MeasureConfig | None = None,
    only_inside: bool = False,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """R(p, eps) on a grid: (xs (nx,), ys (ny,), R (ny, nx)) with cell centres [m];
    R[j, i] is at (xs[i], ys[j]).

    With `only_inside`, only points inside the walls' closed outlines (`inside_outline`) are
    computed and the others are NaN (a building's solid parts and its outside cost nothing).
    With eps_m > 0 and eps_step_m equal to resolution_m, r is cast once per cell of a padded grid
    and R is its box mean (identical values, (2 eps / step + 1)^2 times fewer rays).
    """
    cfg = config if config is not None else MeasureConfig()
    caster = as_caster(segments)
    xs, ys, pts = grid_points(bounds, resolution_m)
    shape = (ys.shape[0], xs.shape[0])
    keep = inside_outline(caster, pts) if only_inside else np.ones(pts.shape[0], dtype=bool)
    if cfg.eps_m > 0 and math.isclose(cfg.eps_step_m, resolution_m, rel_tol=1e-9):
        # The averaging square's grid is the map's grid: R is a box mean of r on a grid padded
        # by the half width, each r cast once instead of once per neighbour.
        half = math.floor(cfg.eps_m / cfg.eps_step_m + 1e-9)
        pad = np.arange(-half, 0) * resolution_m
        pxs = np.concatenate([xs[0] + pad, xs, xs[-1] - pad[::-1]])
        pys = np.concatenate([ys[0] + pad, ys, ys[-1] - pad[::-1]])
        gx, gy = np.meshgrid(pxs, pys, indexing="xy")
        r = line_measure(caster, np.stack([gx.ravel(), gy.ravel()], axis=1),
                         replace(cfg, eps_m=0.0)).r.reshape(pys.shape[0], pxs.shape[0])
        box = _box_mean(r, half)
        return xs, ys, np.where(keep.reshape(shape), box, np.nan)
    values = np.full(pts.shape[0], np.nan)
    if np.any(keep):
        values[keep] = line_measure(caster, pts[keep], cfg).r_eps
    return xs, ys, values.reshape(shape)


def _box_mean(grid: FloatArray, half: int) -> FloatArray:
    """Mean over (2 half + 1)^2 windows of a grid padded by `half` cells: the inner result."""
    size = 2 * half + 1
    c = np.zeros((grid.shape[0] + 1, grid.shape[1] + 1))
    c[1:, 1:] = np.cumsum(np.cumsum(grid, axis=0), axis=1)
    total = c[size:, size:] - c[:-size, size:] - c[size:, :-size] + c[:-size, :-size]
    return np.asarray(total / (size * size))


# Directions [rad] of the parity rays (irrational-ish so that rays through vertices are rare);
# the majority of the three decides.
_PARITY_ANGLES_RAD = (0.1234567, 2.2345678, 4.3456789)
# Distance [m] a parity ray restarts beyond the wall it crossed.
_PARITY_STEP_M = 1e-7
# Most walls a parity ray may cross.
_PARITY_MAX_CROSSINGS = 10_000


def inside_outline(
    segments: npt.ArrayLike | RayCaster, points: npt.ArrayLike
) -> npt.NDArray[np.bool_]:
    """(P,) True where a point is inside the closed outlines of the walls (crossing parity).

    For worlds whose walls trace the free space (built-in worlds, HouseExpo and image imports)
    this is "in free space". Each ray is cast with the model's caster repeatedly from just beyond
    its last hit and the hits are counted; odd = inside. Three directions vote.
    """
    caster = as_caster(segments)
    pts = as_points(points)
    votes = np.zeros(pts.shape[0], dtype=np.int64)
    if caster.segments.shape[0] == 0 or pts.shape[0] == 0:
        return votes > 0
    for ang in _PARITY_ANGLES_RAD:
        u = np.array([math.cos(ang), math.sin(ang)])
        origin = pts.copy()
        count = np.zeros(pts.shape[0], dtype=np.int64)
        active = np.arange(pts.shape[0])
        for _ in range(_PARITY_MAX_CROSSINGS):
            if active.size == 0:
                break
            hits = caster.raycast(origin[active], np.full(active.size, ang))
            hit = hits.segment >= 0
            active = active[hit]
            count[active] += 1
            origin[active] += (hits.distance_m[hit] + _PARITY_STEP_M)[:, None] * u
        votes += count % 2
    return votes >= 2


def evaluate_models(
    segments: npt.ArrayLike,
    point: npt.ArrayLike,
    line_cfg: MeasureConfig | None = None,
    fisher_cfg: FisherConfig | None = None,
) -> dict[ModelType, float]:
    """{LINE: R(p, eps), FISHER: Fisher score} at one point (2,) [m] of a model (K, 4) [m].

    The island builder divides each by its acceptance threshold T_i (eq. 3).
    """
    pt = as_points(point, "point")
    if pt.shape[0] != 1:
        raise MeasureError(f"point: expected one (2,) point, got {pt.shape[0]}")
    fcfg = fisher_cfg if isinstance(fisher_cfg, FisherConfig) else FisherConfig()
    if fisher_cfg is not None and not isinstance(fisher_cfg, FisherConfig):
        raise MeasureError(f"fisher_cfg: expected a FisherConfig, got {type(fisher_cfg).__name__}")
    line = line_measure(segments, pt, line_cfg)
    fish = fisher_measure(segments, pt, fcfg)
    return {ModelType.LINE: float(line.r_eps[0]), ModelType.FISHER: float(fish.score[0])}
