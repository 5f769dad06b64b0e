"""Eq. 3 of the paper: epsilon, the bound E_min / epsilon, and the normalized measure
max_i(R_i / T_i) that must exceed it.

epsilon is sqrt(largest eigenvalue of the xy block of P), P the covariance of the odometric pose
relative to the last island's origin, rebuilt from the odometry's propagated covariance
(`RelativeCovariance`). `Measures` is the line fit and model evaluation the decisions use
(`CoreMeasures`: core.lines and core.measure; tests may pass stand-ins).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from island_msgs_py.geometry import relative_poses
from island_msgs_py.types import FloatArray, LineModel, ModelType, Pose2D, wrap_angle

from island_mapping.core.builder.calibration import OdometryCalibration
from island_mapping.core.builder.config import BuilderConfig, BuilderError
from island_mapping.core.lines import fit_lines
from island_mapping.core.measure import evaluate_models

# A covariance difference below this is numerical noise [m^2].
_COV_EPS_M2 = 1e-12

FitFn = Callable[[FloatArray], LineModel]
EvaluateFn = Callable[[FloatArray, FloatArray], Mapping[ModelType, float]]


class RelativeCovariance:
    """Covariance of the odometric pose relative to an anchor pose, from the odometry covariance.

    The odometry publishes Sigma, the covariance of its pose in the odometry frame, propagated
    step by step as Sigma_k = F_k Sigma_{k-1} F_k^T + Q_k (F_k the Jacobian of the motion
    increment, Q_k the increment's noise). Simply subtracting Sigma_anchor would also count how
    the heading uncertainty the robot already had at the anchor swings the position (that is
    global error, not error relative to the island). So this tracker recovers each step's injected
    noise Q_k = Sigma_k - F_k Sigma_{k-1} F_k^T from consecutive messages and propagates
    P_k = F_k P_{k-1} F_k^T + Q_k with P = 0 at the anchor: the covariance of the current pose
    given the anchor pose exactly, i.e. the error accumulated since the robot last knew where it
    was. epsilon = sqrt(largest eigenvalue of P's xy block) [m].
    """

    def __init__(self) -> None:
        self._prev_pose: Pose2D | None = None
        self._prev_cov = np.zeros((3, 3))
        self.p = np.zeros((3, 3))

    def reset(self) -> None:
        """The robot knows where it is now (an island origin): P = 0."""
        self.p = np.zeros((3, 3))

    def update(self, pose: Pose2D, cov: FloatArray) -> None:
        """Feed one odometry message (pose [m, rad], 3x3 covariance)."""
        if self._prev_pose is not None:
            f = motion_jacobian(self._prev_pose, pose)
            q = cov - f @ self._prev_cov @ f.T
            q = 0.5 * (q + q.T)
            # Keep the injected noise positive semi-definite (numerical noise, message loss).
            w, v = np.linalg.eigh(q)
            q = (v * np.clip(w, 0.0, None)) @ v.T
            self.p = f @ self.p @ f.T + q
            self.p = 0.5 * (self.p + self.p.T)
        self._prev_pose = pose
        self._prev_cov = cov.copy()

    @property
    def epsilon_m(self) -> float:
        """sqrt of the largest eigenvalue of the relative xy covariance [m]."""
        lam = float(np.max(np.linalg.eigvalsh(self.p[:2, :2])))
        return math.sqrt(lam) if lam > _COV_EPS_M2 else 0.0

    @property
    def heading_sigma_rad(self) -> float:
        """sqrt of the relative heading variance [rad]."""
        return math.sqrt(max(float(self.p[2, 2]), 0.0))


class OdometryTrack:
    """The latest odometric pose [m, rad] and its 3x3 covariance, with the error accumulated
    since the last island's origin (`rel`, eq. 3's epsilon) and since an attempt's anchor
    (`star`, while an attempt is under way)."""

    def __init__(self, calibration: OdometryCalibration | None = None) -> None:
        self.pose: Pose2D | None = None
        self.cov = np.zeros((3, 3))
        self.calibration = calibration  # fed every pose (core.builder.calibration)
        self.turned_rad = 0.0  # signed odometric turn since the first pose [rad]
        self.rel = RelativeCovariance()
        self.star: RelativeCovariance | None = None

    def update(self, pose: Pose2D, cov: FloatArray) -> float:
        """Feed one odometry message; the distance moved since the previous one [m]."""
        moved = 0.0 if self.pose is None else math.hypot(pose.x - self.pose.x,
                                                         pose.y - self.pose.y)
        if self.pose is not None:
            self.turned_rad += wrap_angle(pose.theta - self.pose.theta)
        self.pose, self.cov = pose, cov
        if self.calibration is not None:
            self.calibration.update(pose)
        self.rel.update(pose, cov)
        if self.star is not None:
            self.star.update(pose, cov)
        return moved

    def anchor_star(self) -> None:
        """An attempt starts at the latest pose: the star's own error restarts from 0."""
        assert self.pose is not None
        self.star = RelativeCovariance()
        self.star.update(self.pose, self.cov)


def motion_jacobian(prev: Pose2D, pose: Pose2D) -> FloatArray:
    """F, the Jacobian of the pose after the motion prev -> pose with respect to prev (3x3):
    the step is a signed travel along the mid heading (reversing gives negative travel)."""
    dth = wrap_angle(pose.theta - prev.theta)
    ds = math.hypot(pose.x - prev.x, pose.y - prev.y)
    mid = prev.theta + 0.5 * dth
    if (pose.x - prev.x) * math.cos(mid) + (pose.y - prev.y) * math.sin(mid) < 0:
        ds = -ds
    return np.array(
        [[1.0, 0.0, -ds * math.sin(mid)], [0.0, 1.0, ds * math.cos(mid)], [0.0, 0.0, 1.0]]
    )


@dataclass(frozen=True)
class OdometryErrorModel:
    """Variance growth of raw odometry, per metre driven and per radian turned (a robot whose
    odometry publishes no covariance: a log).

    Defaults: least-squares fit (`fit_odometry_error_model`) of the squared per-scan differences
    between raw-odometry increments and GMapping-corrected increments over the whole Intel log
    (909 steps, 500 m, 283 rad turned); a median step of 0.67 m / 22 deg differs by 5.3 cm / 2.6
    deg. The corrected poses serve only to calibrate these four numbers.
    """

    var_xy_per_m_m2: float = field(
        default=0.0047,
        metadata={"help": "position variance (x plus y) added per metre driven [m^2/m]"},
    )
    var_xy_per_rad_m2: float = field(
        default=0.0062,
        metadata={"help": "position variance (x plus y) added per radian turned [m^2/rad]"},
    )
    var_theta_per_m_rad2: float = field(
        default=0.0056, metadata={"help": "heading variance added per metre driven [rad^2/m]"}
    )
    var_theta_per_rad_rad2: float = field(
        default=0.0020, metadata={"help": "heading variance added per radian turned [rad^2/rad]"}
    )

    def __post_init__(self) -> None:
        for name in ("var_xy_per_m_m2", "var_xy_per_rad_m2", "var_theta_per_m_rad2",
                     "var_theta_per_rad_rad2"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise BuilderError(
                    f"OdometryErrorModel.{name}: expected a number >= 0, got {v!r}")

    def step_noise(self, increment: FloatArray) -> FloatArray:
        """Q (3x3): the noise an increment (dx [m], dy [m], dtheta [rad]) adds, isotropic in
        x and y (the model's position variance is x plus y, so each axis gets half)."""
        d = math.hypot(float(increment[0]), float(increment[1]))
        turn = abs(float(increment[2]))
        q_xy = self.var_xy_per_m_m2 * d + self.var_xy_per_rad_m2 * turn
        q_th = self.var_theta_per_m_rad2 * d + self.var_theta_per_rad_rad2 * turn
        return np.diag([0.5 * q_xy, 0.5 * q_xy, q_th])


def propagate_covariances(poses: FloatArray, model: OdometryErrorModel) -> FloatArray:
    """(N, 3, 3) covariances of odometry poses (N, 3) as an odometry would publish them: 0 at
    the first, then Sigma_k = F_k Sigma_{k-1} F_k^T + Q_k (F_k the motion Jacobian of the
    step, Q_k the model's noise of its increment) -- what `RelativeCovariance` unrolls."""
    p = np.asarray(poses, dtype=np.float64)
    out = np.zeros((p.shape[0], 3, 3))
    for k in range(1, p.shape[0]):
        a, b = Pose2D(*(float(v) for v in p[k - 1])), Pose2D(*(float(v) for v in p[k]))
        f = motion_jacobian(a, b)
        inc = relative_poses(p[k - 1], p[k])[0]
        out[k] = f @ out[k - 1] @ f.T + model.step_noise(inc)
    return out


def fit_odometry_error_model(raw_increments: FloatArray,
                             true_increments: FloatArray) -> OdometryErrorModel:
    """Non-negative least squares of squared increment errors on (distance [m], |turn| [rad]):
    raw and true increments (N, 3) of the same steps, N >= 2."""
    from scipy.optimize import nnls

    raw = np.asarray(raw_increments, dtype=np.float64)
    tru = np.asarray(true_increments, dtype=np.float64)
    if raw.ndim != 2 or raw.shape[1:] != (3,) or raw.shape != tru.shape or raw.shape[0] < 2:
        raise BuilderError("fit_odometry_error_model: need >= 2 matching (N, 3) increments, got "
                           f"{raw.shape} and {tru.shape}")
    err = relative_poses(tru, raw)
    a = np.stack([np.hypot(tru[:, 0], tru[:, 1]), np.abs(tru[:, 2])], axis=1)
    xy, _ = nnls(a, err[:, 0] ** 2 + err[:, 1] ** 2)
    th, _ = nnls(a, err[:, 2] ** 2)
    return OdometryErrorModel(float(xy[0]), float(xy[1]), float(th[0]), float(th[1]))


def eq3_bound(cfg: BuilderConfig, epsilon_m: float) -> float:
    """The right side of eq. 3, E_min / epsilon, floored at `bound_floor` [-]."""
    if epsilon_m <= 0:
        return math.inf
    return max(cfg.e_min_m / epsilon_m, cfg.bound_floor)


def normalized_measures(
    cfg: BuilderConfig, measures: Mapping[ModelType, float]
) -> tuple[ModelType, float]:
    """(argmax, max) of R_i / T_i over the model types; NaN measures count as 0."""
    best_t, best = ModelType.LINE, -math.inf
    for t in ModelType:
        r = float(measures.get(t, 0.0))
        v = r / cfg.threshold(t) if math.isfinite(r) else 0.0
        if v > best:
            best_t, best = t, v
    return best_t, max(best, 0.0)


class CoreMeasures:
    """The project's line fitting (core.lines) and model-type evaluation (core.measure)."""

    def __init__(self, config: BuilderConfig) -> None:
        self._config = config

    def fit(self, points: FloatArray) -> LineModel:
        """Line model of (N, 2) points [m]."""
        return fit_lines(points, self._config.line_fit)

    def evaluate(self, segments: FloatArray, point: FloatArray) -> Mapping[ModelType, float]:
        """{model type: measure} of segments (N, 4) [m] at point (2,) [m]."""
        return evaluate_models(segments, point, self._config.measure, self._config.fisher)


@dataclass(frozen=True)
class Measures:
    """The line fit and the model-type evaluation the builder's decisions use, with the
    thresholds T_i that normalize them (`cfg`)."""

    cfg: BuilderConfig
    fit: FitFn
    evaluate: EvaluateFn

    @staticmethod
    def of(cfg: BuilderConfig, fit: FitFn | None = None,
           evaluate: EvaluateFn | None = None) -> Measures:
        """The core fit and evaluation, either replaced by a stand-in when given."""
        if fit is None or evaluate is None:
            core = CoreMeasures(cfg)
            fit = fit if fit is not None else core.fit
            evaluate = evaluate if evaluate is not None else core.evaluate
        return Measures(cfg, fit, evaluate)

    def at(self, model: LineModel, p: FloatArray) -> float:
        """The model's normalized measure max_i(R_i / T_i) at the point p (2,) [m]."""
        _, r = normalized_measures(self.cfg, self.evaluate(model.segments, p))
        return r

    def of_points(self, points: FloatArray, at: FloatArray) -> tuple[ModelType, float, LineModel]:
        """Fit lines to (N, 2) points and evaluate every model type at `at` (2,): (the best
        type, its normalized measure, the model); 0 without a model."""
        if points.shape[0] < 2:
            return ModelType.LINE, 0.0, LineModel()
        model = self.fit(points)
        if len(model) == 0:
            return ModelType.LINE, 0.0, model
        t, best = normalized_measures(self.cfg, self.evaluate(model.segments, at))
        return t, best, model
