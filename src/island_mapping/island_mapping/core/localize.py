"""Pose correction against a line model (Dudek & MacKenzie; paper section 6).

`localize(model, points_robot, initial, config)` moves the pose so that range points, given in
the robot frame [m], fall on the model's segments [m]:

- each iteration transforms the points with the current pose, pairs every point with its nearest
  segment (Euclidean point-to-segment distance) and keeps pairs closer than `max_match_dist_m`;
  the error vector e_j goes from the point to its closest point on that segment;
- Solver.DUDEK_MACKENZIE (default): the translation correction is the weighted sum of the error
  vectors, sum w_j e_j / sum w_j (the original method), applied and iterated until it shrinks
  below `tol_m`; with `estimate_heading` each iteration then takes a rotation step about the
  weighted centroid c of the matched points, dtheta = sum w_j (r_j x e_j) / sum w_j |r_j|^2 with
  r_j = p_j - c (the heading extension);
- Solver.POINT_TO_LINE: one weighted Gauss-Newton step of the point-to-line distances in
  (x, y[, theta]) per iteration (same fixed point, fewer iterations).

Weights: UNIFORM (1) or CAUCHY (1 / (1 + (d / weight_scale_m)^2), d the point's distance).

Degeneracy: the translational normal matrix A = sum w n n^T / sum w (n the unit direction of the
error, or the segment normal for points on their line) has eigenvalues summing to 1; when the
smaller is below `min_constraint` (e.g. every point on two parallel walls of a corridor) the
along-axis position is unconstrained and the result says converged=False even if the steps
vanished. Non-convergence is also reported when `max_iterations` run out or fewer than
`min_matched_fraction` of the points found a segment.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import (
    closest_on_segment_rows,
    closest_on_segments,
    from_frame,
    point_segment_distance,
)
from island_msgs_py.raycast import raycast
from island_msgs_py.types import FloatArray, LineModel, Pose2D, as_segments, wrap_angle

IntArray = npt.NDArray[np.int64]


class LocalizeError(InputError):
    """A LocalizeConfig value or argument is invalid (the message names it)."""


class Weighting(StrEnum):
    """How much a matched point counts in the correction."""

    UNIFORM = "uniform"
    CAUCHY = "cauchy"  # 1 / (1 + (d / weight_scale_m)^2): far matches count less


class Solver(StrEnum):
    """How the correction is computed each iteration."""

    DUDEK_MACKENZIE = "dudek_mackenzie"  # weighted mean error vector + rotation about centroid
    POINT_TO_LINE = "point_to_line"  # weighted Gauss-Newton on point-to-line distances


@dataclass(frozen=True)
class LocalizeConfig:
    """Parameters of the line-model localization (single source of defaults)."""

    max_iterations: int = field(default=100, metadata={"help": "iteration limit [-]"})
    tol_m: float = field(
        default=2e-4, metadata={"help": "converged when the translation step is below this [m]"}
    )
    tol_rad: float = field(
        default=2e-4, metadata={"help": "and the rotation step is below this [rad]"}
    )
    max_match_dist_m: float = field(
        default=0.5,
        metadata={"help": "points farther than this from every segment are not matched [m]"},
    )
    weighting: Weighting = field(
        default=Weighting.CAUCHY, metadata={"help": "weights of matched points: uniform|cauchy"}
    )
    weight_scale_m: float = field(
        default=0.05, metadata={"help": "distance scale of the Cauchy weight [m]"}
    )
    estimate_heading: bool = field(
        default=True, metadata={"help": "also correct the heading (the extension) [bool]"}
    )
    solver: Solver = field(
        default=Solver.DUDEK_MACKENZIE,
        metadata={"help": "correction step: dudek_mackenzie|point_to_line"},
    )
    min_points: int = field(
        default=3, metadata={"help": "fewest matched points needed to localize [-]"}
    )
    min_matched_fraction: float = field(
        default=0.5,
        metadata={"help": "converged only if at least this fraction of points matched [0-1]"},
    )
    min_constraint: float = field(
        default=0.03,
        metadata={"help": "smaller eigenvalue of the normalized normal matrix below which the "
                  "position is unconstrained along one axis (degenerate) [0-0.5]"},
    )

    def __post_init__(self) -> None:
        for name in ("tol_m", "tol_rad", "max_match_dist_m", "weight_scale_m",
                     "min_matched_fraction", "min_constraint"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise LocalizeError(f"LocalizeConfig.{name}: expected a finite number, got {v!r}")
            if v < 0:
                raise LocalizeError(f"LocalizeConfig.{name}: must be >= 0, got {v}")
        for name in ("max_iterations", "min_points"):
            iv = getattr(self, name)
            if isinstance(iv, bool) or not isinstance(iv, int | np.integer) or iv < 1:
                raise LocalizeError(f"LocalizeConfig.{name}: expected an int >= 1, got {iv!r}")
        if self.max_match_dist_m <= 0 or self.weight_scale_m <= 0:
            raise LocalizeError("LocalizeConfig: max_match_dist_m and weight_scale_m must be > 0")
        try:
            object.__setattr__(self, "weighting", Weighting(self.weighting))
            object.__setattr__(self, "solver", Solver(self.solver))
        except ValueError as exc:
            raise LocalizeError(f"LocalizeConfig: {exc}") from None


def point_to_line_config() -> LocalizeConfig:
    """Localization with the Gauss-Newton point-to-line step, the default of the island tracker
    and of route following (the Dudek-MacKenzie step reaches the same fixed point but often
    needs more than its iteration limit)."""
    return LocalizeConfig(solver=Solver.POINT_TO_LINE)


@dataclass(frozen=True)
class LocalizationResult:
    """Outcome of `localize`.

    pose: corrected pose; residual_m: RMS point-to-segment distance of the matched points at that
    pose [m]; iterations: iterations run; converged: steps vanished, the position is constrained
    in both axes and enough points matched; matched_fraction: matched / finite points [0-1];
    constraint: smaller eigenvalue of the normalized normal matrix [0-0.5] (0 = degenerate);
    settled: the steps vanished within max_iterations (true of a fit that slid along a hallway,
    degenerate or not, so not converged).
    """

    pose: Pose2D
    residual_m: float
    iterations: int
    converged: bool
    matched_fraction: float
    constraint: float = 0.0
    settled: bool = False


def _model_segments(model: LineModel | npt.ArrayLike) -> FloatArray:
    if isinstance(model, LineModel):
        return model.segments
    return as_segments(model, "model")


def _clean_points(points_robot: npt.ArrayLike) -> FloatArray:
    arr = np.asarray(points_robot, dtype=np.float64)
    if arr.size == 0:
        return np.zeros((0, 2))
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise LocalizeError(
            f"points_robot: expected an (N, 2) array of robot-frame points [m], got {arr.shape}"
        )
    return arr[np.all(np.isfinite(arr), axis=1)]


def _constraint(normals: FloatArray, w: FloatArray) -> float:
    """Smaller eigenvalue of sum w n n^T / sum w (0 = one axis unconstrained, 0.5 = isotropic)."""
    sw = float(w.sum())
    if sw <= 0:
        return 0.0
    a = (normals * w[:, None]).T @ normals / sw
    return float(np.linalg.eigvalsh(a)[0])


def localize(
    model: LineModel | npt.ArrayLike,
    points_robot: npt.ArrayLike,
    initial: Pose2D,
    config: LocalizeConfig | None = None,
) -> LocalizationResult:
    """Correct `initial` so that `points_robot` (N, 2) [m] fit the model's segments; module doc."""
    cfg = config if config is not None else LocalizeConfig()
    seg = _model_segments(model)
    pts = _clean_points(points_robot)
    if seg.shape[0] == 0 or pts.shape[0] < cfg.min_points:
        return LocalizationResult(initial, math.inf, 0, False, 0.0, 0.0)
    reach = float(np.max(np.hypot(pts[:, 0], pts[:, 1])))
    return _iterate(seg, lambda pose, _seg: (from_frame(pts, pose), None), reach, initial, cfg)


@dataclass(frozen=True, eq=False)
class SonarBeams:
    """Geometry of a sonar ring reading, for `localize_sonar` (e.g. from island_sim's SonarModel).

    axis_rad: (B,) beam axis bearings in the robot frame [rad]; cone_offsets_rad: (C,) ray
    directions within a cone relative to its axis [rad]; ring_radius_m: transducer distance from
    the robot centre [m]; reflect_deg: largest incidence angle giving an echo [deg];
    range_min_m / range_max_m: echo limits from the transducer [m].
    """

    axis_rad: FloatArray
    cone_offsets_rad: FloatArray
    ring_radius_m: float = 0.225
    reflect_deg: float = 30.0
    range_min_m: float = 0.15
    range_max_m: float = 6.5


def localize_sonar(
    model: LineModel | npt.ArrayLike,
    ranges_m: npt.ArrayLike,
    beams: SonarBeams,
    initial: Pose2D,
    config: LocalizeConfig | None = None,
) -> LocalizationResult:
    """Like `localize`, for wide-cone sonar ranges (B,) from the robot centre [m] (inf = none).

    A sonar reports the nearest echo anywhere in its cone, not along its axis; putting the point
    on the axis displaces it off the wall by up to tens of centimetres. Each iteration therefore
    places reading b where the MODEL, seen from the current pose, would have echoed: along the
    cone ray with the nearest valid hit (incidence within reflect_deg, within the range limits;
    the axis when no ray echoes), at the measured range from the transducer, and pairs it with
    the wall that ray hits (visibility-aware: never the hidden back face of a thin wall; the
    nearest segment when no ray echoes). The correction step, weights and convergence test are
    those of `localize`.
    """
    cfg = config if config is not None else LocalizeConfig()
    seg = _model_segments(model)
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    axis = np.asarray(beams.axis_rad, dtype=np.float64).reshape(-1)
    offs = np.asarray(beams.cone_offsets_rad, dtype=np.float64).reshape(-1)
    if r.shape != axis.shape:
        raise LocalizeError(f"localize_sonar: {r.shape[0]} ranges for {axis.shape[0]} beams")
    if offs.size == 0:
        offs = np.zeros(1)
    ok = np.isfinite(r)
    r, axis = r[ok], axis[ok]
    if seg.shape[0] == 0 or r.shape[0] < cfg.min_points:
        return LocalizationResult(initial, math.inf, 0, False, 0.0, 0.0)
    echo = r - beams.ring_radius_m  # distance from the transducer [m]
    cos_min = math.cos(math.radians(beams.reflect_deg)) - 1e-12
    n_b, n_c = axis.shape[0], offs.shape[0]

    def place(pose: FloatArray, seg: FloatArray) -> tuple[FloatArray, IntArray]:
        bearing = pose[2] + axis
        tx = pose[0] + beams.ring_radius_m * np.cos(bearing)
        ty = pose[1] + beams.ring_radius_m * np.sin(bearing)
        ray = (bearing[:, None] + offs[None, :]).reshape(-1)
        hits = raycast(seg, np.stack([np.repeat(tx, n_c), np.repeat(ty, n_c)], axis=1), ray,
                       beams.range_max_m)
        d = hits.distance_m.reshape(n_b, n_c)
        valid = (hits.cos_incidence.reshape(n_b, n_c) >= cos_min) & (d >= beams.range_min_m)
        d = np.where(valid, d, np.inf)
        best = np.argmin(d, axis=1)
        echoes = np.isfinite(d[np.arange(n_b), best])
        chosen = np.where(echoes, offs[best], 0.0)
        phi = bearing + chosen
        wall = np.where(echoes, hits.segment.reshape(n_b, n_c)[np.arange(n_b), best], -1)
        pts = np.stack([tx + echo * np.cos(phi), ty + echo * np.sin(phi)], axis=1)
        return pts, wall.astype(np.int64)

    reach = float(np.max(r))
    return _iterate(seg, place, reach, initial, cfg)


def _iterate(
    seg: FloatArray,
    place: Callable[[FloatArray, FloatArray], tuple[FloatArray, IntArray | None]],
    reach_m: float,
    initial: Pose2D,
    cfg: LocalizeConfig,
) -> LocalizationResult:
    """The correction loop; `place(pose, segments)` gives the data points (N, 2) in the model
    frame and optionally (N,) the segment each must be paired with (-1: the nearest)."""
    pose = initial.as_array()
    # Only segments that a matched point could reach matter.
    near = point_segment_distance(pose[None, 0:2], seg)[0] <= reach_m + cfg.max_match_dist_m + 1.0
    seg = seg[near] if np.any(near) else seg
    seg_len = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
    seg_normal = np.stack([-(seg[:, 3] - seg[:, 1]), seg[:, 2] - seg[:, 0]], axis=1)
    seg_normal /= np.where(seg_len > 0, seg_len, 1.0)[:, None]

    iterations = 0
    steps_small = False
    for iterations in range(1, cfg.max_iterations + 1):  # noqa: B007 (used after the loop)
        world, assoc = place(pose, seg)
        idx, foot, dist = _pair(world, seg, assoc)
        ok = dist <= cfg.max_match_dist_m
        if int(ok.sum()) < cfg.min_points:
            break
        p, e, d = world[ok], foot[ok] - world[ok], dist[ok]
        w = _weights(d, cfg)
        normals = _error_normals(e, d, seg_normal[idx[ok]])
        if cfg.solver is Solver.POINT_TO_LINE:
            dx, dy, dth = _gauss_newton_step(p, e, normals, w, pose, cfg.estimate_heading)
            pose = np.array([pose[0] + dx, pose[1] + dy, pose[2] + dth])
            step_t, step_r = math.hypot(dx, dy), abs(dth)
        else:
            t = (w[:, None] * e).sum(axis=0) / w.sum()
            pose = np.array([pose[0] + t[0], pose[1] + t[1], pose[2]])
            step_t, step_r = float(np.hypot(t[0], t[1])), 0.0
            if cfg.estimate_heading:
                p = p + t
                c = (w[:, None] * p).sum(axis=0) / w.sum()
                r = p - c
                den = float((w * np.sum(r * r, axis=1)).sum())
                num = float((w * (r[:, 0] * (e[:, 1] - t[1]) - r[:, 1] * (e[:, 0] - t[0]))).sum())
                dth = num / den if den > 1e-12 else 0.0
                cs, sn = math.cos(dth), math.sin(dth)
                tx, ty = pose[0] - c[0], pose[1] - c[1]
                pose = np.array(
                    [c[0] + cs * tx - sn * ty, c[1] + sn * tx + cs * ty, pose[2] + dth]
                )
                step_r = abs(dth)
        if step_t < cfg.tol_m and step_r < cfg.tol_rad:
            steps_small = True
            break

    pose[2] = wrap_angle(float(pose[2]))
    world, assoc = place(pose, seg)
    idx, foot, dist = _pair(world, seg, assoc)
    ok = dist <= cfg.max_match_dist_m
    matched = float(ok.mean())
    if not np.any(ok):
        return LocalizationResult(Pose2D.from_array(pose), math.inf, iterations, False, 0.0, 0.0)
    residual = float(np.sqrt(np.mean(dist[ok] ** 2)))
    normals = _error_normals(foot[ok] - world[ok], dist[ok], seg_normal[idx[ok]])
    constraint = _constraint(normals, _weights(dist[ok], cfg))
    converged = (
        steps_small
        and constraint >= cfg.min_constraint
        and matched >= cfg.min_matched_fraction
        and int(ok.sum()) >= cfg.min_points
    )
    return LocalizationResult(
        Pose2D.from_array(pose), residual, iterations, bool(converged), matched, constraint,
        steps_small,
    )


def _pair(
    points: FloatArray, seg: FloatArray, assoc: IntArray | None
) -> tuple[IntArray, FloatArray, FloatArray]:
    """Nearest segments, overridden by `assoc` where it names one (>= 0)."""
    idx, foot, dist = closest_on_segments(points, seg)
    if assoc is None:
        return idx, foot, dist
    has = np.flatnonzero(assoc >= 0)
    if has.size:
        idx[has] = assoc[has]
        foot[has], dist[has] = closest_on_segment_rows(points[has], seg[assoc[has]])
    return idx, foot, dist


def _weights(d: FloatArray, cfg: LocalizeConfig) -> FloatArray:
    if cfg.weighting is Weighting.UNIFORM:
        return np.ones_like(d)
    return np.asarray(1.0 / (1.0 + (d / cfg.weight_scale_m) ** 2))


def _error_normals(e: FloatArray, d: FloatArray, seg_normals: FloatArray) -> FloatArray:
    """Unit direction of each error vector; the segment normal where the point is on its line."""
    safe = np.where(d > 1e-9, d, 1.0)
    return np.where((d > 1e-9)[:, None], e / safe[:, None], seg_normals)


def _gauss_newton_step(
    p: FloatArray,
    e: FloatArray,
    normals: FloatArray,
    w: FloatArray,
    pose: FloatArray,
    with_heading: bool,
) -> tuple[float, float, float]:
    """Weighted least squares of n_j . (delta_t + delta_theta * perp(p_j - t)) = n_j . e_j."""
    res = np.sum(normals * e, axis=1)
    lever = p - pose[0:2]
    jt = normals[:, 0] * (-lever[:, 1]) + normals[:, 1] * lever[:, 0]
    cols = [normals[:, 0], normals[:, 1]] + ([jt] if with_heading else [])
    jac = np.stack(cols, axis=1)
    h = jac.T @ (jac * w[:, None])
    g = jac.T @ (w * res)
    sol, *_ = np.linalg.lstsq(h, g, rcond=1e-10)
    return float(sol[0]), float(sol[1]), float(sol[2]) if with_heading else 0.0


def convergence_region(
    model: LineModel | npt.ArrayLike,
    points_robot: npt.ArrayLike,
    true_pose: Pose2D,
    offsets_m: npt.ArrayLike,
    trials: int,
    rng: np.random.Generator,
    config: LocalizeConfig | None = None,
    success_tol_m: float = 0.02,
    heading_offset_rad: float = 0.0,
) -> FloatArray:
    """Success rate (len(offsets_m),) of `localize` started `offset` [m] away from `true_pose` in
    a random direction (and +-heading_offset_rad [rad] off in heading, random sign).

    A trial succeeds when it converges with a final position error below `success_tol_m` [m].
    """
    offs = np.asarray(offsets_m, dtype=np.float64).reshape(-1)
    if trials < 1:
        raise LocalizeError(f"convergence_region: trials must be >= 1, got {trials}")
    rates = np.zeros(offs.shape[0])
    for i, off in enumerate(offs):
        ok = 0
        for _ in range(trials):
            ang = rng.uniform(-math.pi, math.pi)
            sign = 1.0 if rng.uniform() < 0.5 else -1.0
            start = Pose2D(
                true_pose.x + off * math.cos(ang),
                true_pose.y + off * math.sin(ang),
                wrap_angle(true_pose.theta + sign * heading_offset_rad),
            )
            res = localize(model, points_robot, start, config)
            err = math.hypot(res.pose.x - true_pose.x, res.pose.y - true_pose.y)
            ok += int(res.converged and err < success_tol_m)
        rates[i] = ok / trials
    return rates
