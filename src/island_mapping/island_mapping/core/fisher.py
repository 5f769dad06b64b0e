"""A second model type: Fisher information of range-finder localization (Censi 2007).

For a range sensor at pose (x, y, theta) and a ray of world angle phi hitting a wall of unit
normal angle alpha at range rho, with beta = alpha - phi the incidence angle, the derivative of
the range with respect to the pose is (Censi, "An accurate closed-form estimate of ICP's
covariance", 2007 / "On achievable accuracy for range-finder localization", ICRA 2007)

    J = [cos(alpha) / cos(beta), sin(alpha) / cos(beta), rho tan(beta)]   (up to a common sign)

and with independent Gaussian range noise of std sigma(rho) = sigma0 + sigma_per_m * rho the
Fisher information matrix is I = sum_rays J^T J / sigma^2 (3 x 3; units 1/m^2, 1/(m rad), 1/rad^2).
The rays are the measure's rays (every `angular_res_deg` over 360 deg, the same first-hit ray
caster, counted only when rho <= `max_range_m` and |beta| <= `reflect_deg`).

The Cramer-Rao bound of the position (heading unknown) is the inverse of the Schur complement
I_t = I_xy - I_xt I_tt^-1 I_tx (2 x 2, [1/m^2]). With lambda_min <= lambda_max its eigenvalues:

- `min_eig` = lambda_min [1/m^2] (1/sqrt(lambda_min) is the std bound of the worst direction [m]);
- `cond` = lambda_max / lambda_min (inf when lambda_min = 0);
- `score` = g (1 + q) / 2 with g = lambda_min^m / (lambda_c^m + lambda_min^m),
  lambda_c = 1 / std_ref_m^2, and q = lambda_min / lambda_max: the same shape as the line
  measure's r = F (1 + Q) / 2, so 0 <= score < 1, 0 when a direction is unconstrained.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.raycast import RayCaster
from island_msgs_py.types import FloatArray

from island_mapping.core.rays import (
    MIN_ANGULAR_RES_DEG,
    as_caster,
    as_points,
    cast_chunk,
    ray_angles,
    tiled_chunks,
)

# Rays per ray-cast call (bounds the temporaries of the brute-force caster).
_RAYS_PER_CHUNK = 1 << 13
# Heading information below this [1/rad^2] is treated as none when forming the Schur complement.
_TINY_INFO = 1e-12


class FisherError(InputError):
    """A FisherConfig value or an argument is invalid (the message names it)."""


@dataclass(frozen=True)
class FisherConfig:
    """Parameters of the Fisher-information model type (single source of defaults)."""

    sigma_m: float = field(
        default=0.03, metadata={"help": "range noise std at zero range, sigma0 [m]"}
    )
    sigma_per_m: float = field(
        default=0.01, metadata={"help": "growth of the range noise std with range [m/m]"}
    )
    reflect_deg: float = field(
        default=30.0,
        metadata={"help": "largest incidence angle of a ray that returns an echo [deg]"},
    )
    max_range_m: float = field(default=6.5, metadata={"help": "farthest counted hit [m]"})
    angular_res_deg: float = field(
        default=2.0, metadata={"help": "angular step between rays over 360 deg [deg]"}
    )
    std_ref_m: float = field(
        default=0.02,
        metadata={"help": "position std bound at which the score's sigmoid is 1/2; "
                  "lambda_c = 1/std_ref_m^2 [m]"},
    )
    m: float = field(default=1.0, metadata={"help": "exponent of the score's sigmoid [-]"})

    def __post_init__(self) -> None:
        for name in ("sigma_m", "sigma_per_m", "reflect_deg", "max_range_m", "angular_res_deg",
                     "std_ref_m", "m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise FisherError(f"FisherConfig.{name}: expected a finite number, got {v!r}")
        if self.sigma_m <= 0 or self.sigma_per_m < 0:
            raise FisherError("FisherConfig: sigma_m must be > 0 and sigma_per_m >= 0")
        if not 0.0 < self.reflect_deg < 90.0:
            raise FisherError(
                f"FisherConfig.reflect_deg: must be in (0, 90) deg, got {self.reflect_deg}"
            )
        if self.max_range_m <= 0 or self.std_ref_m <= 0 or self.m <= 0:
            raise FisherError("FisherConfig: max_range_m, std_ref_m and m must be > 0")
        if not MIN_ANGULAR_RES_DEG <= self.angular_res_deg <= 90.0:
            raise FisherError(
                f"FisherConfig.angular_res_deg: must be in [{MIN_ANGULAR_RES_DEG:g}, 90] deg "
                f"(the limit), got {self.angular_res_deg:g}"
            )


@dataclass(frozen=True, eq=False)
class FisherResult:
    """Per point: info (P, 3, 3) Fisher information [1/m^2, 1/(m rad), 1/rad^2];
    min_eig (P,) [1/m^2], cond (P,) [-], score (P,) in [0, 1)."""

    info: FloatArray
    min_eig: FloatArray
    cond: FloatArray
    score: FloatArray


def information_matrices(
    segments: npt.ArrayLike | RayCaster, points: npt.ArrayLike, config: FisherConfig
) -> FloatArray:
    """(P, 3, 3) Fisher information at `points` (P, 2) [m] for the model `segments` (K, 4)."""
    caster = as_caster(segments)
    seg = caster.segments
    pts = as_points(points)
    angles = ray_angles(config.angular_res_deg)
    n_rays = angles.shape[0]
    info = np.zeros((pts.shape[0], 3, 3))
    if pts.shape[0] == 0 or seg.shape[0] == 0:
        return info
    cos_min = math.cos(math.radians(config.reflect_deg)) - 1e-12
    per_chunk = max(1, _RAYS_PER_CHUNK // n_rays)
    for members, sub in tiled_chunks(pts, seg, config.max_range_m, per_chunk):
        nc = members.shape[0]
        ang, hits = cast_chunk(caster, pts, members, sub, angles, config.max_range_m)
        ok = (hits.segment >= 0) & (hits.cos_incidence >= cos_min)
        rho = np.where(ok, hits.distance_m, 0.0)
        u = np.stack([np.cos(ang), np.sin(ang)], axis=1)
        n = np.stack([np.cos(hits.normal_angle), np.sin(hits.normal_angle)], axis=1)
        n_dot_u = np.sum(n * u, axis=1)  # = -cos(beta) with the normal facing the sensor
        n_dot_up = n[:, 0] * (-u[:, 1]) + n[:, 1] * u[:, 0]  # n . d u / d phi
        safe = np.where(ok, n_dot_u, -1.0)
        jac = np.zeros((ang.shape[0], 3))
        jac[:, 0] = -n[:, 0] / safe
        jac[:, 1] = -n[:, 1] / safe
        jac[:, 2] = -rho * n_dot_up / safe
        sigma = config.sigma_m + config.sigma_per_m * rho
        w = np.where(ok, 1.0 / sigma**2, 0.0)
        outer = jac[:, :, None] * jac[:, None, :] * w[:, None, None]
        info[members] = outer.reshape(nc, n_rays, 3, 3).sum(axis=1)
    return info


def translational_information(info: FloatArray) -> FloatArray:
    """(P, 2, 2) Schur complement I_xy - I_xt I_tt^-1 I_tx (heading marginalized) [1/m^2]."""
    a = info[:, 0:2, 0:2]
    b = info[:, 0:2, 2]
    c = info[:, 2, 2]
    inv_c = np.where(c > _TINY_INFO, 1.0 / np.where(c > _TINY_INFO, c, 1.0), 0.0)
    return np.asarray(a - b[:, :, None] * b[:, None, :] * inv_c[:, None, None])


def fisher_measure(
    segments: npt.ArrayLike | RayCaster, points: npt.ArrayLike, config: FisherConfig | None = None
) -> FisherResult:
    """Fisher information, worst-direction eigenvalue, conditioning and score (module doc)."""
    cfg = config if config is not None else FisherConfig()
    info = information_matrices(segments, points, cfg)
    return score_information(info, cfg)


def score_information(info: FloatArray, cfg: FisherConfig) -> FisherResult:
    """min_eig, cond and score from (P, 3, 3) information matrices (see module doc)."""
    it = translational_information(info)
    evals = np.linalg.eigvalsh(it) if it.shape[0] else np.zeros((0, 2))
    lo = np.clip(evals[:, 0], 0.0, None)
    hi = np.clip(evals[:, 1], 0.0, None)
    # Eigenvalues below this fraction of the largest are round-off, not information.
    lo = np.where(lo > 1e-9 * np.maximum(hi, 1.0), lo, 0.0)
    q = np.divide(lo, hi, out=np.zeros_like(lo), where=hi > 0)
    cond = np.divide(hi, lo, out=np.full_like(lo, np.inf), where=lo > 0)
    lam_c = 1.0 / cfg.std_ref_m**2
    g = np.zeros_like(lo)
    pos = lo > 0
    g[pos] = 1.0 / (1.0 + (lam_c / lo[pos]) ** cfg.m)
    return FisherResult(info=info, min_eig=lo, cond=cond, score=g * (1.0 + q) / 2.0)
