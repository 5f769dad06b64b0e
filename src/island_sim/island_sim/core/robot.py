"""A differential-drive robot with drifting wheel odometry (numpy only).

The TRUE pose follows the (speed- and acceleration-limited) commanded velocities by exact arc
integration and stops at walls (the robot is a disk). The ODOMETRIC pose integrates what wheel
encoders would report: the true wheel travel seen through wrong wheel radii and a wrong wheelbase
(systematic drift, Borenstein's E_d / E_b) plus Gaussian random drift whose variance grows with
the distance travelled and the angle turned. The odometric pose covariance is propagated with the
standard first-order (Jacobian) rule, so the accumulated error estimate epsilon (the paper's eq. 3)
is known at every step. Ground truth is kept separately and is never used by the odometry.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.types import FloatArray, Pose2D, wrap_angle

from island_sim.core.near_walls import WallClearance
from island_sim.core.world import World

# Below this |dtheta| [rad] the arc update uses its series form (avoids 0/0 for straight moves).
_SMALL_TURN_RAD = 1e-9
# Margin [m] under which an already-overlapping robot may still move when it gains clearance.
_CLEARANCE_EPS_M = 1e-9


class RobotError(InputError):
    """A robot/odometry configuration or step argument is invalid; the message names the field."""


def check_finite(cls: str, values: dict[str, float]) -> None:
    """RobotError naming `cls`.field unless every value is a finite number (bool is not)."""
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise RobotError(f"{cls}.{name}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise RobotError(f"{cls}.{name}: expected a finite number, got {value!r}")


@dataclass(frozen=True)
class RobotConfig:
    """Body and motion limits of the simulated robot (a Nomad-200-like disk)."""

    radius_m: float = field(default=0.25, metadata={"help": "radius of the robot's disk [m]",
                                                    "range": (0.0, math.inf)})
    wheelbase_m: float = field(
        default=0.5, metadata={"help": "true distance between the two drive wheels [m]",
                               "range": (0.0, math.inf)}
    )
    max_linear_speed_mps: float = field(
        default=0.6, metadata={"help": "largest forward/backward speed [m/s]",
                               "range": (0.0, math.inf)}
    )
    max_angular_speed_radps: float = field(
        default=1.2, metadata={"help": "largest turn rate [rad/s]", "range": (0.0, math.inf)}
    )
    max_linear_accel_mps2: float = field(
        default=1.0, metadata={"help": "largest change of linear speed [m/s^2]",
                               "range": (0.0, math.inf)}
    )
    max_angular_accel_radps2: float = field(
        default=4.0, metadata={"help": "largest change of turn rate [rad/s^2]",
                               "range": (0.0, math.inf)}
    )

    def __post_init__(self) -> None:
        vals = {
            "radius_m": self.radius_m,
            "wheelbase_m": self.wheelbase_m,
            "max_linear_speed_mps": self.max_linear_speed_mps,
            "max_angular_speed_radps": self.max_angular_speed_radps,
            "max_linear_accel_mps2": self.max_linear_accel_mps2,
            "max_angular_accel_radps2": self.max_angular_accel_radps2,
        }
        check_finite("RobotConfig", vals)
        if self.radius_m < 0:
            raise RobotError(f"RobotConfig.radius_m: must be >= 0, got {self.radius_m}")
        for name in list(vals)[1:]:
            if vals[name] <= 0:
                raise RobotError(f"RobotConfig.{name}: must be > 0, got {vals[name]}")


@dataclass(frozen=True)
class OdometryConfig:
    """Systematic and random drift of the wheel odometry.

    Systematic: the right/left wheel radii differ from the nominal radius the odometry assumes by
    a relative `wheel_radius_ratio_error` (right = 1 + e/2, left = 1 - e/2 times nominal), and the
    true wheelbase is (1 + `wheelbase_error`) times the nominal one. Random: per step, the
    odometric travel ds and rotation dtheta get zero-mean Gaussian errors with
    var(ds) = `var_dist_m2_per_m` |ds|, var(dtheta) = `var_heading_rad2_per_m` |ds| +
    `var_heading_rad2_per_rad` |dtheta| and correlation `dist_heading_correlation`.
    """

    wheel_radius_ratio_error: float = field(
        default=0.0005,
        metadata={"help": "relative difference of right vs left wheel radius (E_d - 1); the "
                  "odometric path of a straight drive curves by about -e / wheelbase [1/m] [-]",
                  "range": (-1.0, 1.0)},
    )
    wheelbase_error: float = field(
        default=0.005,
        metadata={"help": "relative error of the true vs nominal wheelbase (E_b - 1); scales "
                  "every odometric rotation by about 1 + e [-]", "range": (-1.0, math.inf)},
    )
    var_dist_m2_per_m: float = field(
        default=1e-4, metadata={"help": "variance of travelled distance per metre [m^2/m]",
                                "range": (0.0, math.inf)}
    )
    var_heading_rad2_per_m: float = field(
        default=1e-4, metadata={"help": "heading variance per metre travelled [rad^2/m]",
                                "range": (0.0, math.inf)}
    )
    var_heading_rad2_per_rad: float = field(
        default=5e-4, metadata={"help": "heading variance per radian turned [rad^2/rad]",
                                "range": (0.0, math.inf)}
    )
    dist_heading_correlation: float = field(
        default=0.0,
        metadata={"help": "correlation of the distance and heading errors of one step, in "
                  "[-1, 1] (the cross term of the per-step covariance) [-]", "range": (-1.0, 1.0)},
    )

    def __post_init__(self) -> None:
        vals = {
            "wheel_radius_ratio_error": self.wheel_radius_ratio_error,
            "wheelbase_error": self.wheelbase_error,
            "var_dist_m2_per_m": self.var_dist_m2_per_m,
            "var_heading_rad2_per_m": self.var_heading_rad2_per_m,
            "var_heading_rad2_per_rad": self.var_heading_rad2_per_rad,
            "dist_heading_correlation": self.dist_heading_correlation,
        }
        check_finite("OdometryConfig", vals)
        if not -1.0 < self.wheel_radius_ratio_error < 1.0:
            raise RobotError("OdometryConfig.wheel_radius_ratio_error: must be in (-1, 1), got "
                             f"{self.wheel_radius_ratio_error}")
        if self.wheelbase_error <= -1.0:
            raise RobotError(
                f"OdometryConfig.wheelbase_error: must be > -1, got {self.wheelbase_error}"
            )
        for name in ("var_dist_m2_per_m", "var_heading_rad2_per_m", "var_heading_rad2_per_rad"):
            if vals[name] < 0:
                raise RobotError(f"OdometryConfig.{name}: must be >= 0, got {vals[name]}")
        if not -1.0 <= self.dist_heading_correlation <= 1.0:
            raise RobotError("OdometryConfig.dist_heading_correlation: must be in [-1, 1], got "
                             f"{self.dist_heading_correlation}")

    @staticmethod
    def exact() -> OdometryConfig:
        """Odometry without any drift (for tests)."""
        return OdometryConfig(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


def arc_update(pose: FloatArray, ds_m: float, dtheta_rad: float) -> FloatArray:
    """Pose (3,) [m, m, rad] after driving the arc of length `ds_m` turning by `dtheta_rad`."""
    x, y, th = float(pose[0]), float(pose[1]), float(pose[2])
    if abs(dtheta_rad) < _SMALL_TURN_RAD:
        mid = th + 0.5 * dtheta_rad
        nx, ny = x + ds_m * math.cos(mid), y + ds_m * math.sin(mid)
    else:
        r = ds_m / dtheta_rad
        nx = x + r * (math.sin(th + dtheta_rad) - math.sin(th))
        ny = y - r * (math.cos(th + dtheta_rad) - math.cos(th))
    return np.array([nx, ny, wrap_angle(th + dtheta_rad)], dtype=np.float64)


def propagate_covariance(
    cov: FloatArray, theta_rad: float, ds_m: float, dtheta_rad: float, q: FloatArray
) -> FloatArray:
    """First-order propagation of the 3x3 pose covariance through one odometry increment.

    `q` (2, 2) is the covariance of the increment (ds [m], dtheta [rad]); the Jacobians are those
    of the midpoint motion model at heading `theta_rad` before the step.
    """
    mid = theta_rad + 0.5 * dtheta_rad
    c, s = math.cos(mid), math.sin(mid)
    f = np.array([[1.0, 0.0, -ds_m * s], [0.0, 1.0, ds_m * c], [0.0, 0.0, 1.0]])
    g = np.array([[c, -0.5 * ds_m * s], [s, 0.5 * ds_m * c], [0.0, 1.0]])
    out = f @ cov @ f.T + g @ q @ g.T
    return 0.5 * (out + out.T)


def epsilon_from_covariance(cov: npt.ArrayLike) -> float:
    """Accumulated position error estimate [m]: sqrt of the largest eigenvalue of the xy block."""
    c = np.asarray(cov, dtype=np.float64)
    ev = np.linalg.eigvalsh(c[:2, :2])
    return float(math.sqrt(max(float(ev[-1]), 0.0)))


@dataclass(frozen=True)
class StepResult:
    """What one physics step did: true and odometric increments, and whether a wall stopped it."""

    ds_true_m: float
    dtheta_true_rad: float
    ds_odom_m: float
    dtheta_odom_rad: float
    blocked: bool


class SimRobot:
    """True pose, odometric pose and odometry covariance of one simulated robot.

    `odom_start` is where the odometry frame places the robot at t = 0 (default: the true start,
    so /odom and /ground_truth coincide at the start and their gap is the accumulated drift).
    `track_covariance=False` skips propagating the odometry covariance (a third of a step's
    cost) for users that never read it; `odom_covariance` and `epsilon_m` then raise.
    """

    def __init__(
        self,
        world: World | None,
        start: Pose2D,
        rng: np.random.Generator,
        robot: RobotConfig | None = None,
        odometry: OdometryConfig | None = None,
        odom_start: Pose2D | None = None,
        *,
        track_covariance: bool = True,
    ) -> None:
        if not isinstance(rng, np.random.Generator):
            raise RobotError(f"SimRobot: rng must be a numpy.random.Generator, got {type(rng)}")
        self.robot = robot if robot is not None else RobotConfig()
        self.odometry = odometry if odometry is not None else OdometryConfig()
        self._walls = WallClearance(
            world.segments if world is not None else np.zeros((0, 4), dtype=np.float64)
        )
        self._rng = rng
        self._true = start.as_array()
        self._odom = (odom_start if odom_start is not None else start).as_array()
        self._cov: FloatArray = np.zeros((3, 3), dtype=np.float64)
        self._track_cov = bool(track_covariance)
        self._v = 0.0
        self._w = 0.0
        self.time_s = 0.0
        self.distance_m = 0.0  # true distance travelled [m]
        self.collisions = 0  # number of times a wall stopped the robot (rising edges)
        self.blocked_steps = 0
        self._was_blocked = False
        self._clearance_cache: float | None = None  # centre-to-wall distance at the true pose
        o = self.odometry
        b_nominal = self.robot.wheelbase_m / (1.0 + o.wheelbase_error)
        self._b_true = self.robot.wheelbase_m
        self._b_nominal = b_nominal
        self._scale_r = 1.0 / (1.0 + 0.5 * o.wheel_radius_ratio_error)
        self._scale_l = 1.0 / (1.0 - 0.5 * o.wheel_radius_ratio_error)

    # --- state ---------------------------------------------------------------------------------
    @property
    def true_pose(self) -> Pose2D:
        return Pose2D.from_array(self._true)

    @property
    def odom_pose(self) -> Pose2D:
        return Pose2D.from_array(self._odom)

    @property
    def odom_covariance(self) -> FloatArray:
        """(3, 3) covariance of the odometric pose (x [m], y [m], theta [rad])."""
        return self._covariance().copy()

    @property
    def epsilon_m(self) -> float:
        """Accumulated odometry error estimate [m] (sqrt of the largest xy eigenvalue)."""
        return epsilon_from_covariance(self._covariance())

    def _covariance(self) -> FloatArray:
        if not self._track_cov:
            raise RobotError("SimRobot: made with track_covariance=False, no covariance kept")
        return self._cov

    @property
    def velocity(self) -> tuple[float, float]:
        """Current true (v [m/s], w [rad/s]) after acceleration limits."""
        return self._v, self._w

    @property
    def clearance_m(self) -> float:
        """Distance from the robot's centre to the nearest wall minus its radius [m]."""
        return self._centre_clearance_m() - self.robot.radius_m

    def _centre_clearance_m(self) -> float:
        if self._clearance_cache is None:
            self._clearance_cache = self._walls.at(float(self._true[0]), float(self._true[1]))
        return self._clearance_cache

    # --- odometry model ------------------------------------------------------------------------
    def systematic_increment(self, ds_m: float, dtheta_rad: float) -> tuple[float, float]:
        """(ds, dtheta) the encoders report for a true (ds, dtheta), before random drift."""
        s_r = (ds_m + 0.5 * self._b_true * dtheta_rad) * self._scale_r
        s_l = (ds_m - 0.5 * self._b_true * dtheta_rad) * self._scale_l
        return 0.5 * (s_r + s_l), (s_r - s_l) / self._b_nominal

    def increment_covariance(self, ds_m: float, dtheta_rad: float) -> FloatArray:
        """(2, 2) covariance of the random error of one increment (ds [m], dtheta [rad])."""
        o = self.odometry
        v_d = o.var_dist_m2_per_m * abs(ds_m)
        v_t = o.var_heading_rad2_per_m * abs(ds_m) + o.var_heading_rad2_per_rad * abs(dtheta_rad)
        c = o.dist_heading_correlation * math.sqrt(v_d * v_t)
        return np.array([[v_d, c], [c, v_t]], dtype=np.float64)

    # --- stepping ------------------------------------------------------------------------------
    def _limit(self, v_cmd: float, w_cmd: float, dt_s: float) -> None:
        r = self.robot
        v_cmd = min(max(v_cmd, -r.max_linear_speed_mps), r.max_linear_speed_mps)
        w_cmd = min(max(w_cmd, -r.max_angular_speed_radps), r.max_angular_speed_radps)
        dv = r.max_linear_accel_mps2 * dt_s
        dw = r.max_angular_accel_radps2 * dt_s
        self._v += min(max(v_cmd - self._v, -dv), dv)
        self._w += min(max(w_cmd - self._w, -dw), dw)

    def step(self, v_cmd_mps: float, w_cmd_radps: float, dt_s: float) -> StepResult:
        """Advance by `dt_s` [s] under the commanded (v [m/s], w [rad/s])."""
        if not (math.isfinite(v_cmd_mps) and math.isfinite(w_cmd_radps)):
            raise RobotError(f"SimRobot.step: command must be finite, got ({v_cmd_mps}, "
                             f"{w_cmd_radps})")
        if not (math.isfinite(dt_s) and dt_s > 0):
            raise RobotError(f"SimRobot.step: dt_s must be > 0, got {dt_s}")
        self._limit(v_cmd_mps, w_cmd_radps, dt_s)
        ds, dth = self._v * dt_s, self._w * dt_s
        blocked = False
        moved: FloatArray | None = None  # the true pose after an unblocked translation
        if ds != 0.0:
            cand = arc_update(self._true, ds, dth)
            before = self._centre_clearance_m()
            after = self._walls.at(float(cand[0]), float(cand[1]))
            if after < self.robot.radius_m and after < before - _CLEARANCE_EPS_M:
                blocked = True  # the disk would enter a wall: the wheels stop, rotation only
                ds = 0.0
                self._v = 0.0
            else:
                self._clearance_cache = after
                moved = cand
        self._true = moved if moved is not None else arc_update(self._true, ds, dth)
        self.distance_m += abs(ds)
        if blocked:
            self.blocked_steps += 1
            if not self._was_blocked:
                self.collisions += 1
        self._was_blocked = blocked
        ds_o, dth_o = self.systematic_increment(ds, dth)
        q = self.increment_covariance(ds_o, dth_o)
        z = self._rng.standard_normal(2)  # always two draws: the stream does not depend on motion
        sd_d, sd_t = math.sqrt(q[0, 0]), math.sqrt(q[1, 1])
        rho = self.odometry.dist_heading_correlation
        ds_o += sd_d * float(z[0])
        dth_o += sd_t * (rho * float(z[0]) + math.sqrt(max(1.0 - rho * rho, 0.0)) * float(z[1]))
        theta_before = float(self._odom[2])
        self._odom = arc_update(self._odom, ds_o, dth_o)
        if self._track_cov:
            self._cov = propagate_covariance(self._cov, theta_before, ds_o, dth_o, q)
        self.time_s += dt_s
        return StepResult(ds, dth, ds_o, dth_o, blocked)
