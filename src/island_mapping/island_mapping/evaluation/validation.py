"""Validation of the distinctiveness measures against measured localization (paper 8.1, Fig. 2, 3).

Confidence map (as the paper, with several trials per point):
- grid points: cell centres of `resolution_m` over the world's bounds that lie inside the
  walls' closed outlines (`measure.inside_outline`, crossing parity: the free space of traced
  worlds) and at least `clearance_m` from every wall (where the robot's centre can be);
- at each point, `trials` times: a seeded random heading, a sonar scan (island_sim SonarModel,
  `scans_per_trial` scans with the ring turned in place by 360 / (N * scans) deg between them so
  the beams interleave), a start pose offset by a random 10-15 cm in a random direction,
  `localize_sonar` (the cone-aware variant; `localize` on axis points with sonar_aware=False)
  against the WORLD segments from there; error = distance [m] from the estimate to
  the true position (an estimate that `localize` itself reports as not converged counts as a
  failure, error = c, when `unconverged_is_failure`);
- confidence = c - error (paper) normalized to [0, 1]: conf = (c - min(error, c)) / c with
  c = `confidence_c_m` (the largest initial offset: an error of c means no improvement at all),
  averaged over the trials. "Success" at a point: the mean error is below `success_tol_m`.

Comparison of a measure M (R of the line model, or the Fisher score) with the confidence:
- M is normalized to [0, 1] by its maximum over the evaluated points (M / max M; M >= 0);
- how far the confidence itself can be predicted: `spearman_ceiling_ties` (exact ties cap any
  measure's Spearman; a two-valued confidence with success fraction p at sqrt(3 p (1 - p))) and
  `split_half_spearman` / `spearman_ceiling_est` (even vs odd trials, Spearman-Brown: the
  trial-to-trial noise of the mm-level errors of successful trials caps it too);
- residual = M_norm - conf; `frac_residual_gt_0_4` = fraction of points with |residual| > 0.4
  (paper Fig. 2: about 25 %); Spearman rank correlation of M and conf; ROC AUC of M for
  "success" (Mann-Whitney, ties count 1/2).

Parameter fit (the paper proposes it in 8.1): k, c and m of the line measure (std_ref_m and m of
the Fisher score) minimizing the residual statistic; a coarse grid search on the exact statistic
then Nelder-Mead on a smooth surrogate, reusing the cached ray casts (only the cheap sums change).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import clearance_m, ranges_to_points
from island_msgs_py.types import FloatArray, Pose2D
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World
from scipy.optimize import minimize
from scipy.stats import rankdata, spearmanr

from island_mapping.core.fisher import FisherConfig, information_matrices, score_information
from island_mapping.core.localize import LocalizeConfig, SonarBeams, localize, localize_sonar
from island_mapping.core.measure import (
    MeasureConfig,
    RayBundle,
    cast_rays,
    combine,
    constraint_sums,
    grid_points,
    inside_outline,
)

ProgressFn = Callable[[int, int], None]

# Search box of the fits (log of k [1/m], c, m and of std_ref_m [m], m): keeps the sigmoids
# from degenerating into constants that only the max-normalization rescales.
_LINE_LOG_LO = np.log([0.01, 1e-3, 0.5])
_LINE_LOG_HI = np.log([3.0, 10.0, 16.0])
_FISHER_LOG_LO = np.log([1e-3, 0.25])
_FISHER_LOG_HI = np.log([1.0, 8.0])
# Width of the smooth step used as the surrogate of the residual count in the parameter fit.
_SURROGATE_WIDTH = 0.05


class ValidationError(InputError):
    """A ValidationConfig value or argument is invalid (the message names it)."""


@dataclass(frozen=True)
class ValidationConfig:
    """Parameters of the localization-confidence simulation and the comparison."""

    resolution_m: float = field(default=0.5, metadata={"help": "grid spacing [m]"})
    trials: int = field(default=3, metadata={"help": "localization trials per grid point [-]"})
    offset_min_m: float = field(
        default=0.10, metadata={"help": "smallest initial position offset [m]"}
    )
    offset_max_m: float = field(
        default=0.15, metadata={"help": "largest initial position offset [m]"}
    )
    scans_per_trial: int = field(
        default=4,
        metadata={"help": "sonar scans per trial, the ring turned in place between them [-]"},
    )
    clearance_m: float = field(
        default=0.3, metadata={"help": "grid points closer than this to a wall are skipped [m]"}
    )
    confidence_c_m: float = field(
        default=0.15,
        metadata={"help": "the constant c of confidence = c - error; errors >= c score 0 [m]"},
    )
    sonar_aware: bool = field(
        default=True,
        metadata={"help": "localize with the sonar cone model (localize_sonar) instead of "
                  "points on the beam axes (localize) [bool]"},
    )
    unconverged_is_failure: bool = field(
        default=True,
        metadata={"help": "a trial that localize reports as not converged has error c [bool]"},
    )
    success_tol_m: float = field(
        default=0.05, metadata={"help": "a point succeeds when its mean error is below this [m]"}
    )
    residual_threshold: float = field(
        default=0.4, metadata={"help": "the residual statistic counts |residual| above this [-]"}
    )
    seed: int = field(default=0, metadata={"help": "seed of the trial generator [-]"})
    localize: LocalizeConfig = field(
        default_factory=lambda: LocalizeConfig(estimate_heading=False),
        metadata={"help": "localization settings (the paper corrects position only)"},
    )
    sonar: SonarConfig = field(
        default_factory=SonarConfig, metadata={"help": "simulated sonar ring"}
    )

    def __post_init__(self) -> None:
        for name in ("resolution_m", "offset_min_m", "offset_max_m", "clearance_m",
                     "confidence_c_m", "success_tol_m", "residual_threshold"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ValidationError(
                    f"ValidationConfig.{name}: expected a finite number, got {v!r}"
                )
            if v < 0:
                raise ValidationError(f"ValidationConfig.{name}: must be >= 0, got {v}")
        if self.resolution_m <= 0 or self.confidence_c_m <= 0:
            raise ValidationError("ValidationConfig: resolution_m and confidence_c_m must be > 0")
        if self.offset_max_m < self.offset_min_m:
            raise ValidationError("ValidationConfig: offset_max_m must be >= offset_min_m")
        for name in ("trials", "scans_per_trial"):
            iv = getattr(self, name)
            if isinstance(iv, bool) or not isinstance(iv, int | np.integer) or iv < 1:
                raise ValidationError(f"ValidationConfig.{name}: expected an int >= 1, got {iv!r}")


@dataclass(frozen=True, eq=False)
class ConfidenceMap:
    """errors (M, trials) [m], confidence (M,) [0-1], success (M,) bool at points (M, 2) [m]."""

    points: FloatArray
    errors: FloatArray
    converged: npt.NDArray[np.bool_]
    confidence: FloatArray
    success: npt.NDArray[np.bool_]


@dataclass(frozen=True)
class Comparison:
    """Agreement of a measure with the localization confidence (see the module doc)."""

    frac_residual_gt: float
    spearman: float
    auc: float
    n_points: int

    def as_dict(self, threshold: float = 0.4) -> dict[str, float | int | None]:
        def clean(v: float) -> float | None:
            return None if not math.isfinite(v) else round(float(v), 4)

        return {
            f"frac_residual_gt_{str(threshold).replace('.', '_')}": clean(self.frac_residual_gt),
            "spearman": clean(self.spearman),
            "auc": clean(self.auc),
            "n_points": self.n_points,
        }


def free_points(
    world: World, resolution_m: float, cfg: ValidationConfig
) -> tuple[FloatArray, FloatArray, FloatArray, npt.NDArray[np.bool_]]:
    """Grid ticks xs (nx,), ys (ny,) [m], the kept points (M, 2) [m] and the (ny, nx) mask."""
    xs, ys, pts = grid_points(world.bounds, resolution_m)
    if world.segments.shape[0] == 0:
        return xs, ys, pts[:0], np.zeros((ys.shape[0], xs.shape[0]), dtype=bool)
    keep = inside_outline(world, pts)
    # Clearance from every wall.
    keep &= clearance_m(pts, world.segments) >= cfg.clearance_m
    return xs, ys, pts[keep], keep.reshape(ys.shape[0], xs.shape[0])


def confidence_map(
    world: World,
    points: FloatArray,
    cfg: ValidationConfig,
    progress: ProgressFn | None = None,
) -> ConfidenceMap:
    """Simulate scans, perturb, localize: the localization confidence at `points` (M, 2) [m]."""
    rng = np.random.default_rng(cfg.seed)
    sonar = SonarModel(cfg.sonar, seed=cfg.seed)
    m, t, s = points.shape[0], cfg.trials, cfg.scans_per_trial
    heading = rng.uniform(-math.pi, math.pi, (m, t))
    turn = np.arange(s) * (sonar.angle_increment_rad / s)
    poses = np.empty((m, t, s, 3))
    poses[..., 0] = points[:, None, None, 0]
    poses[..., 1] = points[:, None, None, 1]
    poses[..., 2] = heading[:, :, None] + turn[None, None, :]
    ranges = sonar.scan_many(world, poses.reshape(-1, 3), rng).reshape(m, t, s, -1)
    off_r = rng.uniform(cfg.offset_min_m, cfg.offset_max_m, (m, t))
    off_a = rng.uniform(-math.pi, math.pi, (m, t))
    beams = SonarBeams(
        axis_rad=(sonar.angles_rad[None, :] + turn[:, None]).reshape(-1),
        cone_offsets_rad=sonar.ray_offsets_rad,
        ring_radius_m=cfg.sonar.ring_radius_m,
        reflect_deg=cfg.sonar.reflect_deg if not cfg.sonar.ideal else 90.0,
        range_min_m=cfg.sonar.range_min_m,
        range_max_m=cfg.sonar.range_max_m,
    )
    errors = np.empty((m, t))
    conv = np.zeros((m, t), dtype=bool)
    for i in range(m):
        for j in range(t):
            start = Pose2D(
                float(points[i, 0] + off_r[i, j] * math.cos(off_a[i, j])),
                float(points[i, 1] + off_r[i, j] * math.sin(off_a[i, j])),
                float(heading[i, j]),
            )
            if cfg.sonar_aware:
                res = localize_sonar(world.segments, ranges[i, j].reshape(-1), beams, start,
                                     cfg.localize)
            else:
                pts_robot = np.concatenate([
                    ranges_to_points(ranges[i, j, k], sonar.angles_rad + turn[k])
                    for k in range(s)
                ])
                res = localize(world.segments, pts_robot, start, cfg.localize)
            err = math.hypot(res.pose.x - points[i, 0], res.pose.y - points[i, 1])
            conv[i, j] = res.converged
            if cfg.unconverged_is_failure and not res.converged:
                err = max(err, cfg.confidence_c_m)
            errors[i, j] = err
        if progress is not None:
            progress(i + 1, m)
    c = cfg.confidence_c_m
    conf = ((c - np.minimum(errors, c)) / c).mean(axis=1)
    success = errors.mean(axis=1) < cfg.success_tol_m
    return ConfidenceMap(points, errors, conv, conf, success)


def normalize(values: npt.ArrayLike) -> FloatArray:
    """values / max(values) over the points (values >= 0); all-zero stays zero."""
    v = np.clip(np.asarray(values, dtype=np.float64), 0.0, None)
    top = float(v.max()) if v.size else 0.0
    return v / top if top > 0 else np.zeros_like(v)


def roc_auc(scores: npt.ArrayLike, labels: npt.ArrayLike) -> float:
    """Area under the ROC curve of `scores` for boolean `labels` (nan when one class is empty)."""
    s = np.asarray(scores, dtype=np.float64)
    y = np.asarray(labels, dtype=bool)
    n_pos, n_neg = int(y.sum()), int((~y).sum())
    if n_pos == 0 or n_neg == 0:
        return math.nan
    ranks = rankdata(s)
    return float((ranks[y].sum() - n_pos * (n_pos + 1) / 2.0) / (n_pos * n_neg))


def compare(
    measure: npt.ArrayLike, conf: ConfidenceMap, threshold: float = 0.4
) -> Comparison:
    """Residual statistic, Spearman and AUC of a measure (M,) against the confidence map."""
    m = np.asarray(measure, dtype=np.float64)
    if m.shape != conf.confidence.shape:
        raise ValidationError(
            f"compare: {m.shape[0]} measure values for {conf.confidence.shape[0]} points"
        )
    if m.size == 0:
        return Comparison(math.nan, math.nan, math.nan, 0)
    res = normalize(m) - conf.confidence
    frac = float(np.mean(np.abs(res) > threshold))
    if np.ptp(m) == 0 or np.ptp(conf.confidence) == 0:
        rho = math.nan
    else:
        rho = float(spearmanr(m, conf.confidence).statistic)
    return Comparison(frac, rho, roc_auc(m, conf.success), int(m.size))


def spearman_ceiling(confidence: npt.ArrayLike) -> float:
    """The largest Spearman correlation ANY tie-free measure can reach with `confidence`.

    Ties in the confidence (e.g. every successful point at ~1) cap it: a measure ordered exactly
    like the confidence, ties broken arbitrarily, reaches this value and no measure exceeds it.
    For a two-valued confidence with success fraction p it is sqrt(3 p (1 - p)).
    """
    c = np.asarray(confidence, dtype=np.float64)
    if c.size < 2 or np.ptp(c) == 0:
        return math.nan
    return float(spearmanr(rankdata(c, method="ordinal"), c).statistic)


def split_half_reliability(conf: ConfidenceMap, cfg: ValidationConfig) -> dict[str, float | None]:
    """How reproducible the confidence map itself is: the Spearman correlation between the
    confidence from the even and from the odd trials ("split_half_spearman"), its Spearman-Brown
    correction to all trials, and sqrt of that ("spearman_ceiling_est"), roughly the best
    Spearman any measure can reach against a confidence this noisy. None with one trial."""
    if conf.errors.shape[1] < 2:
        return {"split_half_spearman": None, "spearman_ceiling_est": None}
    c = cfg.confidence_c_m

    def conf_of(err: FloatArray) -> FloatArray:
        return np.asarray(((c - np.minimum(err, c)) / c).mean(axis=1))

    a, b = conf_of(conf.errors[:, 0::2]), conf_of(conf.errors[:, 1::2])
    if np.ptp(a) == 0 or np.ptp(b) == 0:
        return {"split_half_spearman": None, "spearman_ceiling_est": None}
    rho = float(spearmanr(a, b).statistic)
    full = 2.0 * rho / (1.0 + rho) if rho > -1.0 else -1.0
    return {
        "split_half_spearman": _clean4(rho),
        "spearman_ceiling_est": _clean4(math.sqrt(full)) if full > 0 else 0.0,
    }


def _clean4(v: float) -> float | None:
    return round(v, 4) if math.isfinite(v) else None


def residuals(measure: npt.ArrayLike, conf: ConfidenceMap) -> FloatArray:
    """normalize(measure) - confidence (M,)."""
    return normalize(measure) - conf.confidence


def _smooth_objective(norm_measure: FloatArray, conf: FloatArray, threshold: float) -> float:
    res = np.abs(norm_measure - conf)
    step = 1.0 / (1.0 + np.exp(-(res - threshold) / _SURROGATE_WIDTH))
    return float(step.mean() + 0.1 * np.mean(res**2))


def _exact_objective(norm_measure: FloatArray, conf: FloatArray, threshold: float) -> float:
    res = np.abs(norm_measure - conf)
    return float(np.mean(res > threshold) + 1e-3 * np.mean(res**2))


def line_values(bundle: RayBundle, cfg: MeasureConfig) -> FloatArray:
    """r at the bundle's points for the config's k, c, m (the rays are reused)."""
    c_par, c_perp = constraint_sums(bundle, cfg.k)
    return combine(c_par, c_perp, cfg.c, cfg.m)[2]


def fit_line_parameters(
    bundle: RayBundle, conf: ConfidenceMap, start: MeasureConfig, threshold: float = 0.4
) -> MeasureConfig:
    """k, c and m minimizing the residual statistic at the bundle's points (eps = 0)."""
    sums: dict[float, tuple[FloatArray, FloatArray]] = {}

    def values(k: float, c: float, m: float) -> FloatArray:
        key = round(k, 6)
        if key not in sums:
            sums[key] = constraint_sums(bundle, k)
        return combine(*sums[key], c, m)[2]

    best = (math.inf, start.k, start.c, start.m)
    for k in (0.05, 0.1, 0.2, 0.3, 0.5, 0.8):
        c_par, c_perp = sums.setdefault(round(k, 6), constraint_sums(bundle, k))
        pos = np.concatenate([c_par[c_par > 0], c_perp[c_perp > 0]])
        if pos.size == 0:
            continue
        for c in np.quantile(pos, [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8]):
            for m in (1.0, 2.0, 4.0, 8.0):
                obj = _exact_objective(normalize(values(k, float(c), m)), conf.confidence,
                                       threshold)
                if obj < best[0]:
                    best = (obj, k, float(c), m)

    def surrogate(x: FloatArray) -> float:
        k, c, m = (float(v) for v in np.exp(np.clip(x, _LINE_LOG_LO, _LINE_LOG_HI)))
        return _smooth_objective(normalize(values(k, c, m)), conf.confidence, threshold)

    x0 = np.log([best[1], best[2], best[3]])
    opt = minimize(surrogate, x0, method="Nelder-Mead",
                   options={"maxiter": 150, "xatol": 1e-3, "fatol": 1e-5})
    k, c, m = (float(v) for v in np.exp(np.clip(opt.x, _LINE_LOG_LO, _LINE_LOG_HI)))
    refined = _exact_objective(normalize(values(k, c, m)), conf.confidence, threshold)
    if refined > best[0]:
        k, c, m = best[1], best[2], best[3]
    return replace(start, k=_sig(k), c=_sig(c), m=_sig(m))


def fit_fisher_parameters(
    info: FloatArray, conf: ConfidenceMap, start: FisherConfig, threshold: float = 0.4
) -> FisherConfig:
    """std_ref_m and m of the Fisher score minimizing the residual statistic."""
    best = (math.inf, start.std_ref_m, start.m)
    for std in (0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2):
        for m in (0.5, 1.0, 2.0, 4.0):
            cfg = replace(start, std_ref_m=std, m=m)
            obj = _exact_objective(normalize(score_information(info, cfg).score),
                                   conf.confidence, threshold)
            if obj < best[0]:
                best = (obj, std, m)

    def surrogate(x: FloatArray) -> float:
        std, m = (float(v) for v in np.exp(np.clip(x, _FISHER_LOG_LO, _FISHER_LOG_HI)))
        cfg = replace(start, std_ref_m=std, m=m)
        return _smooth_objective(normalize(score_information(info, cfg).score), conf.confidence,
                                 threshold)

    opt = minimize(surrogate, np.log([best[1], best[2]]), method="Nelder-Mead",
                   options={"maxiter": 100, "xatol": 1e-3, "fatol": 1e-5})
    std, m = (float(v) for v in np.exp(np.clip(opt.x, _FISHER_LOG_LO, _FISHER_LOG_HI)))
    cfg = replace(start, std_ref_m=std, m=m)
    refined = _exact_objective(normalize(score_information(info, cfg).score), conf.confidence,
                               threshold)
    if refined > best[0]:
        std, m = best[1], best[2]
    return replace(start, std_ref_m=_sig(std), m=_sig(m))


@dataclass(frozen=True, eq=False)
class ValidationReport:
    """Maps (ny, nx) with NaN outside the evaluated points, and the metrics."""

    xs: FloatArray
    ys: FloatArray
    mask: npt.NDArray[np.bool_]
    r_map: FloatArray
    fisher_map: FloatArray
    confidence_map: FloatArray
    r_values: FloatArray
    fisher_values: FloatArray
    confidence: ConfidenceMap
    metrics: dict[str, Any]


def _to_grid(values: FloatArray, mask: npt.NDArray[np.bool_]) -> FloatArray:
    grid = np.full(mask.shape, np.nan)
    grid[mask] = values
    return grid


def run_validation(
    world: World,
    cfg: ValidationConfig | None = None,
    line_cfg: MeasureConfig | None = None,
    fisher_cfg: FisherConfig | None = None,
    fit: bool = True,
    progress: ProgressFn | None = None,
) -> ValidationReport:
    """Confidence map, both measures on the same points, their comparison and the fitted
    parameters (fit on this world; the top-level metrics use the given configs)."""
    vcfg = cfg if cfg is not None else ValidationConfig()
    lcfg = line_cfg if line_cfg is not None else MeasureConfig()
    fcfg = fisher_cfg if fisher_cfg is not None else FisherConfig()
    if lcfg.eps_m > 0:
        raise ValidationError("run_validation: the paper's Fig. 3 uses eps = 0; got eps_m > 0")
    xs, ys, pts, mask = free_points(world, vcfg.resolution_m, vcfg)
    if pts.shape[0] < 3:
        raise ValidationError(
            f"world {world.name!r}: only {pts.shape[0]} grid points inside with clearance "
            f"{vcfg.clearance_m} m at resolution {vcfg.resolution_m} m"
        )
    conf = confidence_map(world, pts, vcfg, progress)
    bundle = cast_rays(world, pts, lcfg.angular_res_deg, lcfg.max_range_m, lcfg.reflect_deg)
    r_vals = line_values(bundle, lcfg)
    info = information_matrices(world, pts, fcfg)
    f_vals = score_information(info, fcfg).score
    thr = vcfg.residual_threshold
    line_cmp, fisher_cmp = compare(r_vals, conf, thr), compare(f_vals, conf, thr)
    metrics: dict[str, Any] = {
        "world": world.name,
        "resolution_m": vcfg.resolution_m,
        "seed": vcfg.seed,
        "trials": vcfg.trials,
        "n_points": int(pts.shape[0]),
        "normalization": "measure / max(measure) over the points; confidence = "
        "(c - min(error, c)) / c averaged over trials",
        "confidence": {
            "c_m": vcfg.confidence_c_m,
            "success_rate": round(float(conf.success.mean()), 4),
            "converged_rate": round(float(conf.converged.mean()), 4),
            "median_error_m": round(float(np.median(conf.errors)), 4),
            "spearman_ceiling_ties": _clean4(spearman_ceiling(conf.confidence)),
            **split_half_reliability(conf, vcfg),
        },
        "line": {**line_cmp.as_dict(thr), "params": _params(lcfg, ("k", "c", "m"))},
        "fisher": {**fisher_cmp.as_dict(thr), "params": _params(fcfg, ("std_ref_m", "m"))},
    }
    if fit:
        lfit = fit_line_parameters(bundle, conf, lcfg, thr)
        ffit = fit_fisher_parameters(info, conf, fcfg, thr)
        metrics["line"]["fitted"] = {
            **compare(line_values(bundle, lfit), conf, thr).as_dict(thr),
            "params": _params(lfit, ("k", "c", "m")),
        }
        metrics["fisher"]["fitted"] = {
            **compare(score_information(info, ffit).score, conf, thr).as_dict(thr),
            "params": _params(ffit, ("std_ref_m", "m")),
        }
    return ValidationReport(
        xs=xs,
        ys=ys,
        mask=mask,
        r_map=_to_grid(r_vals, mask),
        fisher_map=_to_grid(f_vals, mask),
        confidence_map=_to_grid(conf.confidence, mask),
        r_values=r_vals,
        fisher_values=f_vals,
        confidence=conf,
        metrics=metrics,
    )


def _sig(x: float, digits: int = 4) -> float:
    """x rounded to `digits` significant digits (keeps tiny positive values positive)."""
    return float(f"{x:.{digits}g}")


def _params(cfg: MeasureConfig | FisherConfig, names: tuple[str, ...]) -> dict[str, float]:
    d = asdict(cfg)
    return {n: float(d[n]) for n in names}
