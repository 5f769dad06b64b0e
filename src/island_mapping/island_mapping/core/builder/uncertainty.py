"""The full 3x3 covariance of the robot's pose relative to a known island's origin, for loop
closure: the candidates' uncertainty and the gate's squared Mahalanobis distance.

Odometry publishes Sigma, its pose covariance in the odometry frame, propagated per step as
Sigma_k = F_k Sigma_{k-1} F_k^T + Q_k, F_k = [[1, 0, -dy_k], [0, 1, dx_k], [0, 0, 1]] (the
step's Jacobian with respect to the pose before it). The F of a path multiply to the Jacobian
of its whole displacement, J = [[1, 0, -(y1 - y0)], [0, 1, x1 - x0], [0, 0, 1]], so
Sigma_1 = J Sigma_0 J^T + P, P the covariance the path's own increments added: the robot's
error relative to where it was at 0. P depends on the two poses' positions and covariances
only, not on the path or on how many messages arrived (`epsilon.RelativeCovariance` unrolls
every message instead). Along a straight drive P is long across the path (heading error times
the distance) and short along it (distance error): a look-alike place displaced along a
corridor lies many sigmas away, one displaced across it does not.
"""

from __future__ import annotations

import math

import numpy as np
from island_msgs_py.types import FloatArray, Pose2D, wrap_angle

# The skew matrix S: d/dphi R(phi) = R(phi) S.
_SKEW = np.array([[0.0, -1.0], [1.0, 0.0]])


def displacement_jacobian(then: Pose2D, now: Pose2D) -> FloatArray:
    """J (3x3): how an error of the pose `then` moves the pose `now` reached from it by a
    known increment (odometry frame)."""
    return np.array([[1.0, 0.0, -(now.y - then.y)], [0.0, 1.0, now.x - then.x],
                     [0.0, 0.0, 1.0]])


def psd(cov: FloatArray) -> FloatArray:
    """`cov` made symmetric with its negative eigenvalues clipped to 0 (a difference of two
    covariances carries numerical noise, and message loss or a reset odometry more)."""
    sym = 0.5 * (cov + cov.T)
    w, v = np.linalg.eigh(sym)
    return np.asarray((v * np.clip(w, 0.0, None)) @ v.T, dtype=np.float64)


def relative_covariance(then: Pose2D, cov_then: FloatArray, now: Pose2D,
                        cov_now: FloatArray) -> FloatArray:
    """P = Sigma_now - J Sigma_then J^T (module docstring), positive semi-definite: the
    covariance of the odometric pose `now` given the pose `then` exactly (odometry axes,
    [m^2, m rad, rad^2])."""
    j = displacement_jacobian(then, now)
    return psd(np.asarray(cov_now, dtype=np.float64) - j @ cov_then @ j.T)


def rotation3(theta_rad: float) -> FloatArray:
    """R(theta) on (x, y), identity on the heading (3x3)."""
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def in_frame(cov: FloatArray, theta_rad: float) -> FloatArray:
    """A pose covariance in odometry axes expressed in the axes of a frame at heading
    theta_rad [rad] (a rotation: R(-theta) cov R(-theta)^T)."""
    r = rotation3(-theta_rad)
    return np.asarray(r @ cov @ r.T, dtype=np.float64)


def between_covariance(c: Pose2D, cov_c: FloatArray, r: Pose2D, cov_r: FloatArray
                       ) -> FloatArray:
    """Covariance of r in c's frame (c^-1 composed with r), c and r two independent poses in
    one frame with covariances in its axes (first order)."""
    rot = rotation3(-c.theta)
    v = np.array([r.x - c.x, r.y - c.y])
    j_c = np.zeros((3, 3))
    j_c[:2, :2] = -rot[:2, :2]
    j_c[:2, 2] = -rot[:2, :2] @ _SKEW @ v
    j_c[2, 2] = -1.0
    return np.asarray(rot @ cov_r @ rot.T + j_c @ cov_c @ j_c.T, dtype=np.float64)


def mahalanobis2(found: Pose2D, expected: Pose2D, cov: FloatArray,
                 floor: FloatArray | None = None) -> float:
    """Squared Mahalanobis distance of pose `found` from `expected` (x, y, heading wrapped)
    under `cov` plus `floor` (3x3, e.g. the fit's own error; default none) [-]."""
    d = np.array([found.x - expected.x, found.y - expected.y,
                  wrap_angle(found.theta - expected.theta)])
    total = np.asarray(cov, dtype=np.float64) + (np.zeros((3, 3)) if floor is None else floor)
    return float(d @ np.linalg.lstsq(total, d, rcond=None)[0])
