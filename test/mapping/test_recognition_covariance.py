"""Loop closure with the odometry's full covariance (issue 16: a false merge must be rarer than
a missed closure): the relative covariance since an island's origin, and the gate's squared
Mahalanobis distance under it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.builder import BuilderConfig
from island_mapping.core.builder.epsilon import (
    OdometryErrorModel,
    RelativeCovariance,
    motion_jacobian,
    propagate_covariances,
)
from island_mapping.core.builder.recognition import PoseSnapshot, Recognizer
from island_mapping.core.builder.uncertainty import (
    between_covariance,
    mahalanobis2,
    relative_covariance,
)
from island_mapping.core.explore import ExplorerConfig, explorer_hooks
from island_mapping.core.graph import TopoGraph
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

# A T junction at the origin: a corridor along x (y = +-1) with a branch north.
T_WALLS = np.array([[-6, -1, 6, -1], [-6, 1, -1, 1], [1, 1, 6, 1], [-1, 1, -1, 6],
                    [1, 1, 1, 6]], dtype=float)
# The simulated robot's random drift (island_sim OdometryConfig's defaults, heading 4x).
SIM_LIKE = OdometryErrorModel(2e-4, 0.0, 4e-4, 5e-4)


def _path(*legs: tuple[float, float]) -> np.ndarray:
    """Odometry poses (N, 3) of a path of (turn [rad], then drive [m]) legs from the origin,
    in 0.25 m / 0.1 rad steps."""
    poses = [np.zeros(3)]
    for turn, dist in legs:
        n = max(1, math.ceil(abs(turn) / 0.1))
        for _ in range(n):
            x, y, th = poses[-1]
            poses.append(np.array([x, y, th + turn / n]))
        n = max(1, math.ceil(dist / 0.25))
        for _ in range(n):
            x, y, th = poses[-1]
            poses.append(np.array([x + dist / n * math.cos(th), y + dist / n * math.sin(th), th]))
    return np.array(poses)


def test_relative_covariance_equals_the_covariance_of_the_increments_of_a_known_path() -> None:
    """The odometry's covariance carries a large global uncertainty from before the snapshot
    (a long way behind it); what the path from the snapshot on added is recovered exactly from
    the two covariances and the two poses, whatever the path (turns and all)."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(3, 3))
    before = a @ a.T + np.diag([25.0, 16.0, 0.3])  # 5 m, 4 m, 31 deg already
    poses = _path((0.0, 12.0), (math.pi / 2, 7.0), (-2.0, 5.0), (math.pi, 3.0))
    only_path = propagate_covariances(poses, SIM_LIKE)
    total = before.copy()
    tracker = RelativeCovariance()
    tracker.update(_pose(poses[0]), total)
    for k in range(1, len(poses)):
        f = motion_jacobian(_pose(poses[k - 1]), _pose(poses[k]))
        step = only_path[k] - f @ only_path[k - 1] @ f.T  # the increment's own noise
        total = f @ total @ f.T + step
        tracker.update(_pose(poses[k]), total)
    got = relative_covariance(_pose(poses[0]), before, _pose(poses[-1]), total)
    assert np.allclose(got, only_path[-1], atol=1e-9)
    assert np.allclose(got, tracker.p, atol=1e-9)
    assert np.all(np.linalg.eigvalsh(got) >= 0.0)
    # the global covariance alone is far from it: the subtraction is what matters
    assert np.abs(total - only_path[-1]).max() > 10.0


def test_between_covariance_matches_sampled_poses() -> None:
    """The covariance of r in c's frame, first order, against 20000 sampled pairs."""
    rng = np.random.default_rng(4)
    c, r = Pose2D(3.0, -1.0, 0.7), Pose2D(8.0, 2.0, -0.4)
    cov_c, cov_r = np.diag([0.04, 0.09, 0.002]), np.array(
        [[0.05, 0.01, 0.002], [0.01, 0.02, -0.001], [0.002, -0.001, 0.003]])
    cs = rng.multivariate_normal([c.x, c.y, c.theta], cov_c, 20000)
    rs = rng.multivariate_normal([r.x, r.y, r.theta], cov_r, 20000)
    rel = np.array([Pose2D(*r_).relative_to(Pose2D(*c_)).as_array() for c_, r_ in zip(
        cs, rs, strict=True)])
    sampled = np.cov(rel.T)
    assert np.allclose(between_covariance(c, cov_c, r, cov_r), sampled, atol=0.006)


def _pose(row: np.ndarray) -> Pose2D:
    return Pose2D(float(row[0]), float(row[1]), float(row[2]))


def _points(robot: Pose2D, rng: np.random.Generator) -> np.ndarray:
    """Echoes of the T within 5 m of `robot`, in its frame [m]."""
    pts = []
    for x0, y0, x1, y1 in T_WALLS:
        t = np.linspace(0.0, 1.0, max(2, int(math.hypot(x1 - x0, y1 - y0) / 0.2)))[:, None]
        pts.append(np.hstack([x0 + t * (x1 - x0), y0 + t * (y1 - y0)]))
    p = np.concatenate(pts) + rng.normal(0.0, 0.02, (sum(len(q) for q in pts), 2))
    p = p[np.hypot(p[:, 0] - robot.x, p[:, 1] - robot.y) <= 5.0]
    c, s = math.cos(robot.theta), math.sin(robot.theta)
    d = p - np.array([robot.x, robot.y])
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]])


@pytest.mark.parametrize("across", [True, False])
def test_a_recognition_displaced_along_a_long_straight_drive_is_refused(across: bool) -> None:
    """The robot left a T junction east, drove 30 m down its corridor, turned around and came
    back. Odometry's error is then across the corridor (heading times distance), hardly along
    it (distance error). Where odometry puts the junction 2.5 m off across the corridor the
    recognition is kept; 2.5 m along it (a look-alike junction down the corridor), refused,
    though the old isotropic sigma took both."""
    poses = _path((0.0, 30.0), (math.pi, 29.6))
    cov = propagate_covariances(poses, SIM_LIKE)[-1]
    odom_end = _pose(poses[-1])  # (0.4, ~0, pi): back at the junction by odometry
    truth = Pose2D(odom_end.x, odom_end.y, odom_end.theta)  # where the robot is, island frame
    xy = cov[:2, :2]
    w, v = np.linalg.eigh(xy)
    assert w[-1] > 100.0 * w[0]  # a long thin ellipse
    axis = v[:, -1] if across else v[:, 0]
    d = 2.5 * axis
    # a heading error consistent with the offset (the part the covariance ties to it)
    dth = float(cov[2, :2] @ np.linalg.solve(xy, d))
    odom = Pose2D(truth.x + d[0], truth.y + d[1], truth.theta + dth)
    rec = Recognizer(BuilderConfig(revisit=ExplorerConfig().revisit))
    rec.remember(0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
    eps = math.sqrt(w[-1])
    snap = PoseSnapshot(odom, cov, eps, math.sqrt(cov[2, 2]), None, 60.0)
    island = Island(0, LineModel(T_WALLS), ModelType.LINE, 1.0, 0.0)
    found = rec.recognize(_points(truth, np.random.default_rng(9)), odom, snap, [island],
                          star=True)
    assert found is not None and found.island_id == 0
    assert math.hypot(found.pose.x - truth.x, found.pose.y - truth.y) < 0.15
    # the old isotropic distance (the estimate's largest position sigma) takes both
    _, sigma_m, sigma_rad = rec.estimates(0, snap)[0]
    old = (2.5 / sigma_m) ** 2 + (dth / sigma_rad) ** 2
    assert old < 11.34
    gate = explorer_hooks(ExplorerConfig(), TopoGraph).accept_revisit
    assert gate is not None
    assert found.mahalanobis2 is not None
    assert (found.mahalanobis2 <= 11.34) is across
    assert (gate(found, snap, island, True) is None) is across


def test_a_stars_recognition_carries_its_mahalanobis_distance() -> None:
    """A star's recognition goes through the same gate: its distance from the estimate is
    kept when the pose is moved from the anchor to where the robot is after the star."""
    truth = Pose2D(0.4, 0.2, 0.05)
    rec = Recognizer(BuilderConfig(revisit=ExplorerConfig().revisit))
    rec.remember(0, Pose2D(0.0, 0.0, 0.0), np.zeros((3, 3)))
    snap = PoseSnapshot(truth, np.diag([1.0, 1.0, 0.01]), 1.0, 0.1, None, 60.0)
    island = Island(0, LineModel(T_WALLS), ModelType.LINE, 1.0, 0.0)
    now = truth.compose(Pose2D(0.0, 0.0, 1.0))  # the star ended facing elsewhere
    found = rec.recognize_star([_points(truth, np.random.default_rng(2))], truth, now, snap,
                               [island])
    assert found is not None and found.mahalanobis2 is not None
    assert abs(found.pose.theta - now.theta) < 0.05


def test_mahalanobis2_of_an_offset_along_the_short_axis_is_large() -> None:
    """The same 1 m is 1 sigma along the long axis and 10 along the short one."""
    cov = np.diag([0.01, 1.0, 0.01])
    assert mahalanobis2(Pose2D(0, 1, 0), Pose2D(0, 0, 0), cov) == pytest.approx(1.0)
    assert mahalanobis2(Pose2D(1, 0, 0), Pose2D(0, 0, 0), cov) == pytest.approx(100.0)
