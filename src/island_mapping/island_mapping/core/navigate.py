"""Navigating by the map: island to island with no global frame (paper section 8.2), simulated.

Pure (numpy + the island_sim cores, no ROS). `follow_route` drives a simulated robot along a
planned route of islands:

1. localize at the source island: rotate once in place collecting sonar points (in the robot
   frame by odometry), localize them against the island's line model from several initial
   guesses around the current estimate, keep the converged result with the smallest residual;
2. dock: drive by odometry onto the island origin (0, 0, 0) and re-localize, up to
   `dock_attempts` times, until within `dock_tol_m` / `dock_tol_deg`;
3. execute the edge's strategy: `Go d` drives d of odometric travel forward with the hall
   follower's perception keeping the robot in the middle of the hallway (a qualitative "follow
   the hall for d"), `Rot a` rotates in place by a of odometric heading;
4. localize in the next island starting from the estimate (0, 0, 0) (the strategy ends at the
   target origin) and repeat from 2.

An edge succeeds when that localization converged and its pose is within `success_tol_m` and
`success_tol_deg` of the robot's true pose expressed in the island frame (the island's
`origin_truth`, kept for evaluation only). The route succeeds when every edge did and the robot,
docked at the last island, truly stands within the same tolerance of that island's true origin.

`follow_route_global_odometry` is the baseline: the same trip on global odometry alone. The robot
starts with its odometry set to the source island's odometric pose recorded at exploration time,
runs the same strategies, and after each edge drives by odometry to the next island's recorded
odometric pose; no re-localization. It succeeds when it ends within the same tolerance of the
target's true origin.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from island_msgs_py.geometry import closest_on_segments, from_frame, ranges_to_points, to_frame
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    FloatArray,
    Island,
    Pose2D,
    PrimitiveKind,
    wrap_angle,
)
from island_sim.core.hall_follower import HallFollower, HallFollowerConfig
from island_sim.core.robot import OdometryConfig, RobotConfig, SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World

from island_mapping.core.builder import (
    BuilderConfig,
    BuilderEvent,
    CommandMode,
    EventKind,
    IslandBuilder,
)
from island_mapping.core.graph import GraphError, TopoGraph, reverse_strategy
from island_mapping.core.lines import thin_evenly
from island_mapping.core.localize import LocalizationResult, LocalizeConfig, Solver, localize


class NavigateError(ValueError):
    """Bad input to route following (the message names what was wrong)."""


def _point_to_line() -> LocalizeConfig:
    """Localization with the Gauss-Newton point-to-line step (the Dudek-MacKenzie step reaches
    the same fixed point but often needs more than its iteration limit)."""
    return LocalizeConfig(solver=Solver.POINT_TO_LINE)


@dataclass(frozen=True)
class NavigateConfig:
    """Route following and its evaluation."""

    success_tol_m: float = field(
        default=0.25, metadata={"help": "largest position error of a successful localization [m]"}
    )
    success_tol_deg: float = field(
        default=10.0, metadata={"help": "largest heading error of a successful localization [deg]"}
    )
    start_offset_m: float = field(
        default=0.1,
        metadata={
            "help": "the robot starts uniformly within this distance of the source "
            "origin (same start for both methods) [m]"
        },
    )
    start_offset_deg: float = field(
        default=5.0, metadata={"help": "and within this heading of it [deg]"}
    )
    go_speed_mps: float = field(default=0.4, metadata={"help": "speed of Go steps [m/s]"})
    turn_rate_radps: float = field(
        default=0.6, metadata={"help": "largest turn rate of Rot steps and docking [rad/s]"}
    )
    k_heading_per_s: float = field(
        default=2.0, metadata={"help": "turn rate per radian of heading error [1/s]"}
    )
    k_lateral_rad_per_m: float = field(
        default=1.0, metadata={"help": "approach angle per metre off the hallway middle [rad/m]"}
    )
    max_approach_deg: float = field(
        default=20.0, metadata={"help": "largest approach angle when re-centring [deg]"}
    )
    stop_distance_m: float = field(
        default=0.6, metadata={"help": "a Go step ends early at this front range [m]"}
    )
    search_radius_m: float = field(
        default=0.6,
        metadata={
            "help": "initial guesses for localization cover this square half-side "
            "around the estimate [m]"
        },
    )
    search_step_m: float = field(default=0.3, metadata={"help": "spacing of the guesses [m]"})
    search_heading_deg: float = field(
        default=8.0, metadata={"help": "guesses also at +- this heading offset [deg]"}
    )
    max_turn_deg: float = field(
        default=30.0,
        metadata={
            "help": "a fit that turned the points farther than this from the estimate's "
            "heading is no candidate: a + junction fits itself turned by 90-180 deg "
            "(paper_fig4: an arrival 'localized' 2 m and 120 deg off) [deg]"
        },
    )
    min_fit_constraint: float = field(
        default=0.08,
        metadata={
            "help": "a fit that constrains the position along some axis less than this "
            "(smaller eigenvalue of the normalized normal matrix) is no candidate: seen from a "
            "hallway, a junction's model also fits 2 m sideways and turned 24 deg with a "
            "smaller residual than at the true pose (paper_fig4, constraint 0.03) [0-0.5]"
        },
    )
    max_points: int = field(
        default=400, metadata={"help": "localization uses at most this many points [-]"}
    )
    min_agreeing: int = field(
        default=3,
        metadata={
            "help": "stop trying further guesses once this many trusted results agree "
            "within 0.1 m [-]"
        },
    )
    max_residual_m: float = field(
        default=0.15, metadata={"help": "a localization with a larger RMS residual is rejected [m]"}
    )
    axis_search_step_m: float = field(
        default=0.8,
        metadata={
            "help": "when the localization at an island is not trusted, the robot looks "
            "around again at multiples of this along the fit's least constrained axis "
            "(0 = off) [m]"
        },
    )
    axis_search_steps: int = field(
        default=2, metadata={"help": "multiples tried on each side [-]"}
    )
    axis_search_min_constraint: float = field(
        default=0.08,
        metadata={
            "help": "a fit found by that search is trusted only with at least this "
            "constraint (smaller eigenvalue of the normalized normal matrix) [0-0.5]"
        },
    )
    sparse_look_points: int = field(
        default=300,
        metadata={
            "help": "a look-around with fewer echo points than this (a hallway gives 800-1200; "
            "the middle of a crossing, where the beams meet the walls at grazing incidence, "
            "16-150) has no meaningful weak axis: the search goes along the arrival heading [-]"
        },
    )
    dock_tol_m: float = field(
        default=0.05, metadata={"help": "docking at an origin ends within this distance [m]"}
    )
    dock_tol_deg: float = field(default=3.0, metadata={"help": "and this heading [deg]"})
    dock_attempts: int = field(default=3, metadata={"help": "drive-and-relocalize rounds [-]"})
    physics_rate_hz: float = field(default=50.0, metadata={"help": "simulation step rate [Hz]"})
    sensor_rate_hz: float = field(default=10.0, metadata={"help": "sonar scan rate [Hz]"})
    max_edge_time_s: float = field(
        default=900.0, metadata={"help": "simulated time limit of one edge [s]"}
    )
    localize: LocalizeConfig = field(
        default_factory=_point_to_line,
        metadata={"help": "line-model localization (point-to-line Gauss-Newton)"},
    )

    def __post_init__(self) -> None:
        for name in (
            "success_tol_m",
            "success_tol_deg",
            "go_speed_mps",
            "turn_rate_radps",
            "search_step_m",
            "max_residual_m",
            "dock_tol_m",
            "dock_tol_deg",
            "physics_rate_hz",
            "sensor_rate_hz",
            "max_edge_time_s",
        ):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise NavigateError(f"NavigateConfig.{name}: expected a number > 0, got {v!r}")
        for name in (
            "start_offset_m",
            "start_offset_deg",
            "search_radius_m",
            "search_heading_deg",
            "max_turn_deg",
            "min_fit_constraint",
            "axis_search_step_m",
            "axis_search_min_constraint",
        ):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise NavigateError(f"NavigateConfig.{name}: expected a number >= 0, got {v!r}")
        if self.axis_search_steps < 0:
            raise NavigateError(
                f"NavigateConfig.axis_search_steps: must be >= 0, got {self.axis_search_steps}"
            )
        if self.sparse_look_points < 0:
            raise NavigateError(
                f"NavigateConfig.sparse_look_points: must be >= 0, got {self.sparse_look_points}"
            )
        if self.dock_attempts < 1:
            raise NavigateError(
                f"NavigateConfig.dock_attempts: must be >= 1, got {self.dock_attempts}"
            )

    @property
    def steps_per_scan(self) -> int:
        return max(1, round(self.physics_rate_hz / self.sensor_rate_hz))


@dataclass(frozen=True)
class EdgeResult:
    """One edge of a followed route.

    localized: the localization converged with a small residual; error_m / error_deg: its pose
    vs the true pose in the island frame; success: localized and within tolerance.
    """

    source: int
    target: int
    strategy: str
    localized: bool
    error_m: float
    error_deg: float
    success: bool


@dataclass(frozen=True)
class RouteResult:
    """A followed route: per edge results, the final true offset from the target origin."""

    route: tuple[int, ...]
    edges: tuple[EdgeResult, ...]
    final_error_m: float
    final_error_deg: float
    success: bool
    sim_time_s: float


@dataclass(frozen=True)
class RouteEvaluation:
    """Success rates of island navigation and of the global-odometry baseline on the same pairs."""

    pairs: tuple[tuple[int, int], ...]
    islands: tuple[RouteResult, ...]
    baseline: tuple[RouteResult, ...]

    @property
    def islands_success_rate(self) -> float:
        return _rate(self.islands)

    @property
    def baseline_success_rate(self) -> float:
        return _rate(self.baseline)


def _rate(results: Sequence[RouteResult]) -> float:
    return sum(r.success for r in results) / len(results) if results else math.nan


# ---------------------------------------------------------------------------------------------


class _Sim:
    """A SimRobot and a sonar ring stepped in sensor periods; every method returns on sim time."""

    def __init__(
        self,
        world: World,
        robot: SimRobot,
        sonar: SonarModel,
        cfg: NavigateConfig,
        rng: np.random.Generator,
    ) -> None:
        self.world, self.robot, self.sonar, self.cfg, self.rng = world, robot, sonar, cfg, rng
        self.dt = 1.0 / cfg.physics_rate_hz
        self.scan = sonar.scan(world, robot.true_pose, rng)
        self.deadline_s = math.inf

    @property
    def t(self) -> float:
        return self.robot.time_s

    def step(self, v: float, w: float) -> bool:
        """One sensor period under (v [m/s], w [rad/s]); True if a wall stopped the robot."""
        if self.t > self.deadline_s:
            raise _SimTimeoutError()
        blocked = False
        for _ in range(self.cfg.steps_per_scan):
            blocked |= self.robot.step(v, w, self.dt).blocked
        self.scan = self.sonar.scan(self.world, self.robot.true_pose, self.rng)
        return blocked

    def scan_points_odom(self) -> FloatArray:
        """Points of the latest scan in the odometry frame [m]."""
        return ranges_to_points(self.scan, self.sonar.angles_rad, self.robot.odom_pose)

    def rotate_to(self, heading_odom_rad: float) -> None:
        c = self.cfg
        tol = math.radians(0.5)
        while True:
            err = wrap_angle(heading_odom_rad - self.robot.odom_pose.theta)
            if abs(err) <= tol and abs(self.robot.velocity[1]) < 0.05:
                return
            w = float(np.clip(c.k_heading_per_s * err, -c.turn_rate_radps, c.turn_rate_radps))
            self.step(0.0, w)

    def rotate_by(self, angle_rad: float) -> None:
        """Rotate in place by angle_rad of odometric heading (any size, e.g. a full turn)."""
        c = self.cfg
        done, last = 0.0, self.robot.odom_pose.theta
        sign = 1.0 if angle_rad >= 0 else -1.0
        while abs(angle_rad) - abs(done) > math.radians(0.5):
            remaining = abs(angle_rad) - abs(done)
            w = sign * min(c.turn_rate_radps, max(0.1, c.k_heading_per_s * remaining))
            self.step(0.0, w)
            th = self.robot.odom_pose.theta
            done += wrap_angle(th - last)
            last = th
        self.step(0.0, 0.0)

    def go_to(self, target_odom: Pose2D) -> None:
        """Drive by odometry to the target pose: turn to face it, drive, turn to its heading."""
        c = self.cfg
        o = self.robot.odom_pose
        d = math.hypot(target_odom.x - o.x, target_odom.y - o.y)
        if d > 0.02:
            self.rotate_to(math.atan2(target_odom.y - o.y, target_odom.x - o.x))
            while True:
                o = self.robot.odom_pose
                dx, dy = target_odom.x - o.x, target_odom.y - o.y
                d = math.hypot(dx, dy)
                along = dx * math.cos(o.theta) + dy * math.sin(o.theta)
                if along <= 0.01 or d <= 0.01:
                    break
                err = wrap_angle(math.atan2(dy, dx) - o.theta) if d > 0.1 else 0.0
                w = float(np.clip(c.k_heading_per_s * err, -c.turn_rate_radps, c.turn_rate_radps))
                if self.step(min(c.go_speed_mps, 1.5 * along + 0.02), w):
                    break  # a wall is in the way: stop here
        self.rotate_to(target_odom.theta)
        self.step(0.0, 0.0)


class _SimTimeoutError(Exception):
    """The simulated time limit of an edge ran out."""


def _go(sim: _Sim, distance_m: float, follower: HallFollower) -> None:
    """Drive distance_m of odometric travel forward, centred in the hallway by the sonar."""
    c = sim.cfg
    travelled = 0.0
    last = sim.robot.odom_pose
    hold = last.theta  # hallway direction in the odometry frame [rad]
    half_width = 0.5 * follower.config.default_hall_width_m
    max_app = math.radians(c.max_approach_deg)
    while travelled < distance_m - 0.005:
        p = follower.perceive(sim.scan, sim.sonar.angles_rad)
        o = sim.robot.odom_pose
        if p.front_m < c.stop_distance_m:
            break
        if p.wall_angle_rad is not None and abs(p.wall_angle_rad) < math.radians(25.0):
            hold = wrap_angle(o.theta + p.wall_angle_rad)
        use_left = math.isfinite(p.left_dist_m) and not p.left_open
        use_right = math.isfinite(p.right_dist_m) and not p.right_open
        offset = 0.0
        if use_left and use_right:
            offset = 0.5 * (p.left_dist_m - p.right_dist_m)
            half_width = 0.5 * (p.left_dist_m + p.right_dist_m)
        elif use_left:
            offset = p.left_dist_m - half_width
        elif use_right:
            offset = half_width - p.right_dist_m
        approach = float(np.clip(c.k_lateral_rad_per_m * offset, -max_app, max_app))
        err = wrap_angle(hold + approach - o.theta)
        w = float(np.clip(c.k_heading_per_s * err, -c.turn_rate_radps, c.turn_rate_radps))
        remaining = distance_m - travelled
        sim.step(min(c.go_speed_mps, 1.5 * remaining + 0.03), w)
        now = sim.robot.odom_pose
        travelled += math.hypot(now.x - last.x, now.y - last.y)
        last = now
    sim.step(0.0, 0.0)


def execute_strategy(sim: _Sim, strategy: ControlStrategy, follower: HallFollower) -> None:
    """Run the primitives: Go d [cm] along the hallway, Rot a [deg CCW] in place (odometry)."""
    for s in strategy.steps:
        if s.kind is PrimitiveKind.GO:
            _go(sim, s.metres, follower)
        else:
            sim.rotate_by(math.radians(s.value) if s.value <= 180 else math.radians(s.value - 360))


def _look_around(sim: _Sim) -> FloatArray:
    """Rotate once in place collecting scan points; return them in the final robot frame [m]."""
    pts = [sim.scan_points_odom()]
    c = sim.cfg
    done, last = 0.0, sim.robot.odom_pose.theta
    while done < 2.0 * math.pi:
        sim.step(0.0, c.turn_rate_radps)
        th = sim.robot.odom_pose.theta
        done += wrap_angle(th - last)
        last = th
        pts.append(sim.scan_points_odom())
    sim.step(0.0, 0.0)
    return to_frame(np.concatenate(pts, axis=0), sim.robot.odom_pose)


def localize_multi(
    island: Island, points_robot: FloatArray, estimate: Pose2D, cfg: NavigateConfig
) -> tuple[LocalizationResult, bool]:
    """Localize from initial guesses around `estimate`; (best result, trusted).

    The best result is the converged one with the smallest residual (any result when none
    converged); trusted = it converged with a residual below `max_residual_m`. A fit whose
    heading left the estimate's by more than `max_turn_deg`, or that constrains the position
    less than `min_fit_constraint`, counts as not converged.
    """
    r = cfg.search_radius_m
    n = math.floor(r / cfg.search_step_m + 1e-9)
    offs = np.arange(-n, n + 1) * cfg.search_step_m
    dths = (0.0, math.radians(cfg.search_heading_deg), -math.radians(cfg.search_heading_deg))
    guesses = sorted(
        ((dx, dy, dth) for dx in offs for dy in offs for dth in dths),
        key=lambda g: math.hypot(g[0], g[1]) + abs(g[2]),
    )
    points_robot = thin_evenly(points_robot, cfg.max_points)  # evenly: the look-around is redundant
    best: LocalizationResult | None = None
    good: list[Pose2D] = []
    for dx, dy, dth in guesses:
        init = Pose2D(estimate.x + dx, estimate.y + dy, wrap_angle(estimate.theta + dth))
        res = localize(island.model, points_robot, init, cfg.localize)
        turned = abs(wrap_angle(res.pose.theta - estimate.theta)) > math.radians(cfg.max_turn_deg)
        if (turned or res.constraint < cfg.min_fit_constraint) and res.converged:
            res = replace(res, converged=False)
        if best is None or (res.converged, -res.residual_m) > (best.converged, -best.residual_m):
            best = res
        if res.converged and res.residual_m <= cfg.max_residual_m:
            good.append(res.pose)
            # Guesses go outward from the estimate: stop once the nearest good fits agree.
            agree = [p for p in good if math.hypot(p.x - good[0].x, p.y - good[0].y) <= 0.1]
            if len(agree) >= cfg.min_agreeing:
                break
    assert best is not None
    return best, bool(best.converged and best.residual_m <= cfg.max_residual_m)


def _truth_in(island: Island, true_pose: Pose2D) -> Pose2D:
    if island.origin_truth is None:
        raise NavigateError(f"island {island.id} has no origin_truth: cannot evaluate")
    return true_pose.relative_to(island.origin_truth)


def _pose_error(a: Pose2D, b: Pose2D) -> tuple[float, float]:
    return math.hypot(a.x - b.x, a.y - b.y), abs(math.degrees(wrap_angle(a.theta - b.theta)))


def _localize_and_dock(sim: _Sim, island: Island, estimate: Pose2D) -> tuple[bool, float, float]:
    """Localize in the island from the estimate, check against truth, dock at the origin.

    Returns (trusted localization, its position error [m], heading error [deg]) of the FIRST
    localization, or when that is not trusted of the one the search along the hallway ended
    with (the one that says whether the robot found the island); docking does not change it."""
    c = sim.cfg
    pts = _look_around(sim)
    res, trusted = localize_multi(island, pts, estimate, c)
    if not trusted and c.axis_search_step_m > 0 and c.axis_search_steps > 0:
        # Search from the fit nearest the estimate: the smallest residual may be a wrong
        # heading basin (paper_fig4 edge 6->7: 2 of 12 starts failed so, 0 of 12 from here).
        if pts.shape[0] >= c.sparse_look_points:
            near = localize(island.model, thin_evenly(pts, c.max_points), estimate, c.localize)
            res, trusted = _search_along_axis(sim, island, pts, near)
        else:
            # The look heard too little to fit (a crossing's middle: 16 echoes in a full turn)
            # and a fit's weak axis is noise: search from the estimate along the heading the
            # robot arrived on, a hallway's axis (no fit from the estimate is needed for that).
            res, trusted = _search_along_axis(
                sim, island, pts, replace(res, pose=estimate), axis_rad=estimate.theta)
    err_m, err_deg = _pose_error(res.pose, _truth_in(island, sim.robot.true_pose))
    first = (trusted, err_m, err_deg)
    if not trusted:
        return first
    est = res.pose
    for _ in range(c.dock_attempts):
        if math.hypot(est.x, est.y) <= c.dock_tol_m and abs(est.theta) <= math.radians(
            c.dock_tol_deg
        ):
            break
        o = sim.robot.odom_pose
        sim.go_to(o.compose(est.inverse()))  # the island origin in the odometry frame
        pts = _look_around(sim)
        res, ok = localize_multi(island, pts, Pose2D(0.0, 0.0, 0.0), c)
        if not ok:
            break
        est = res.pose
    return first


def unconstrained_axis_rad(island: Island, points_robot: FloatArray, pose: Pose2D,
                           cfg: LocalizeConfig) -> float:
    """Direction in the island frame along which a fit at `pose` is least constrained [rad].

    The eigenvector of the smallest eigenvalue of sum n n^T over the matched points (n the unit
    direction from a point to its nearest model segment): in a hallway, the hallway's axis.
    """
    pts = from_frame(points_robot, pose)
    _, foot, dist = closest_on_segments(pts, island.model.segments)
    ok = (dist <= cfg.max_match_dist_m) & (dist > 1e-6)
    if not np.any(ok):
        return pose.theta
    n = (foot[ok] - pts[ok]) / dist[ok, None]
    _, vecs = np.linalg.eigh(n.T @ n)
    return math.atan2(float(vecs[1, 0]), float(vecs[0, 0]))


def _search_along_axis(
    sim: _Sim, island: Island, pts: FloatArray, fit: LocalizationResult,
    axis_rad: float | None = None,
) -> tuple[LocalizationResult, bool]:
    """After an untrusted localization: look around again at points along its weak axis.

    A strategy may end well along a hallway from the target origin (e.g. an edge recorded across
    dismissed attempts); there the look-around fits the island only in a degenerate basin (the
    along-hallway position unconstrained). The robot drives by odometry to +-k * step along that
    axis (k = 1..axis_search_steps, nearer first) from where it stood, looks around and localizes
    from the fit's prediction; it accepts the first trusted fit whose constraint is at least
    `axis_search_min_constraint` (points on a plain hallway alias along it with a constraint
    just above the convergence threshold, so a search needs a clearly constrained fit).
    `axis_rad` [rad, island frame]: search along this direction instead of the fit's weakest.
    """
    c = sim.cfg
    at = sim.robot.odom_pose
    origin_odom = at.compose(fit.pose.inverse())  # where the fit puts the island origin
    if axis_rad is None:  # the fit's weakest direction [rad, island frame]
        axis_rad = unconstrained_axis_rad(island, pts, fit.pose, c.localize)
    axis = origin_odom.theta + axis_rad
    best, trusted = fit, False
    for k in range(1, c.axis_search_steps + 1):
        for sign in (1.0, -1.0):
            d = sign * k * c.axis_search_step_m
            sim.go_to(Pose2D(at.x + d * math.cos(axis), at.y + d * math.sin(axis), at.theta))
            predicted = sim.robot.odom_pose.relative_to(origin_odom)
            res, ok = localize_multi(island, _look_around(sim), predicted, c)
            if ok and res.constraint >= c.axis_search_min_constraint:
                return res, True
            best = res
    return best, trusted


def _random_start(island: Island, cfg: NavigateConfig, rng: np.random.Generator) -> Pose2D:
    if island.origin_truth is None:
        raise NavigateError(f"island {island.id} has no origin_truth: cannot place the robot")
    rad = cfg.start_offset_m * math.sqrt(float(rng.uniform()))
    ang = float(rng.uniform(-math.pi, math.pi))
    dth = math.radians(cfg.start_offset_deg) * float(rng.uniform(-1.0, 1.0))
    return island.origin_truth.compose(Pose2D(rad * math.cos(ang), rad * math.sin(ang), dth))


@dataclass
class SimSetup:
    """What the simulated trip runs on: the world, sensor, body, odometry and hall perception."""

    world: World
    sonar: SonarConfig = field(default_factory=SonarConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    follower: HallFollowerConfig = field(default_factory=HallFollowerConfig)


def _route_edges(graph: TopoGraph, route: Sequence[int]) -> list[Edge]:
    if len(route) < 1:
        raise NavigateError("route: needs at least one island")
    edges = []
    for a, b in itertools.pairwise(route):
        try:
            edges.append(graph.get_edge(a, b))
        except (GraphError, KeyError):
            raise NavigateError(f"route: no edge {a}->{b} in the graph") from None
    return edges


def follow_route(
    graph: TopoGraph,
    route: Sequence[int],
    setup: SimSetup,
    cfg: NavigateConfig | None = None,
    rng: np.random.Generator | None = None,
    start: Pose2D | None = None,
) -> RouteResult:
    """Follow `route` (island ids joined by edges of `graph`) by island localization."""
    c = cfg if cfg is not None else NavigateConfig()
    gen = rng if rng is not None else np.random.default_rng(0)
    edges = _route_edges(graph, route)
    src = graph.get_island(route[0])
    true_start = start if start is not None else _random_start(src, c, gen)
    robot = SimRobot(setup.world, true_start, gen, setup.robot, setup.odometry)
    sim = _Sim(setup.world, robot, SonarModel(setup.sonar), c, gen)
    follower = HallFollower(setup.follower)
    results: list[EdgeResult] = []
    ok_all = True
    try:
        sim.deadline_s = sim.t + c.max_edge_time_s
        trusted, _, _ = _localize_and_dock(sim, src, Pose2D(0.0, 0.0, 0.0))
        ok_all = trusted
        for e in edges if ok_all else []:
            sim.deadline_s = sim.t + c.max_edge_time_s
            execute_strategy(sim, e.strategy, follower)
            trusted, err_m, err_deg = _localize_and_dock(
                sim, graph.get_island(e.target), Pose2D(0.0, 0.0, 0.0)
            )
            good = trusted and err_m <= c.success_tol_m and err_deg <= c.success_tol_deg
            results.append(
                EdgeResult(e.source, e.target, str(e.strategy), trusted, err_m, err_deg, good)
            )
            if not good:
                ok_all = False
                break
    except _SimTimeoutError:
        ok_all = False
    target = graph.get_island(route[-1])
    fin_m, fin_deg = _pose_error(_truth_in(target, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
    success = ok_all and fin_m <= c.success_tol_m and fin_deg <= c.success_tol_deg
    return RouteResult(tuple(route), tuple(results), fin_m, fin_deg, success, sim.t)


def follow_route_global_odometry(
    graph: TopoGraph,
    route: Sequence[int],
    origins_odom: Mapping[int, Pose2D],
    setup: SimSetup,
    cfg: NavigateConfig | None = None,
    rng: np.random.Generator | None = None,
    start: Pose2D | None = None,
) -> RouteResult:
    """The baseline: the same trip on global odometry alone (see the module docstring)."""
    c = cfg if cfg is not None else NavigateConfig()
    gen = rng if rng is not None else np.random.default_rng(0)
    edges = _route_edges(graph, route)
    for i in route:
        if i not in origins_odom:
            raise NavigateError(f"baseline: no recorded odometric pose of island {i}")
    src = graph.get_island(route[0])
    true_start = start if start is not None else _random_start(src, c, gen)
    robot = SimRobot(
        setup.world, true_start, gen, setup.robot, setup.odometry, odom_start=origins_odom[route[0]]
    )
    sim = _Sim(setup.world, robot, SonarModel(setup.sonar), c, gen)
    follower = HallFollower(setup.follower)
    results: list[EdgeResult] = []
    ok = True
    try:
        for e in edges:
            sim.deadline_s = sim.t + c.max_edge_time_s
            execute_strategy(sim, e.strategy, follower)
            sim.go_to(origins_odom[e.target])
            tgt = graph.get_island(e.target)
            err_m, err_deg = _pose_error(_truth_in(tgt, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
            good = err_m <= c.success_tol_m and err_deg <= c.success_tol_deg
            results.append(
                EdgeResult(e.source, e.target, str(e.strategy), False, err_m, err_deg, good)
            )
    except _SimTimeoutError:
        ok = False
    target = graph.get_island(route[-1])
    fin_m, fin_deg = _pose_error(_truth_in(target, robot.true_pose), Pose2D(0.0, 0.0, 0.0))
    success = ok and fin_m <= c.success_tol_m and fin_deg <= c.success_tol_deg
    return RouteResult(tuple(route), tuple(results), fin_m, fin_deg, success, sim.t)


def with_reverse_edges(graph: TopoGraph) -> TopoGraph:
    """A copy of the graph where every edge also exists backwards (graph.reverse_strategy)."""
    edges = list(graph.iter_edges())
    have = {(e.source, e.target) for e in edges}
    for e in list(edges):
        if (e.target, e.source) not in have:
            edges.append(
                Edge(
                    e.target,
                    e.source,
                    reverse_strategy(e.strategy),
                    e.weight,
                    e.length_m,
                    e.expected_error_m,
                )
            )
            have.add((e.target, e.source))
    return TopoGraph.from_parts(graph.islands(), edges)


def evaluate_routes(
    graph: TopoGraph,
    setup: SimSetup,
    n_pairs: int,
    rng: np.random.Generator,
    origins_odom: Mapping[int, Pose2D],
    cfg: NavigateConfig | None = None,
) -> RouteEvaluation:
    """Success rates of `follow_route` and of the baseline over random island pairs.

    Pairs are drawn uniformly among ordered pairs of distinct islands joined by a route in the
    graph with every edge also usable backwards; both methods start from the same true pose.
    """
    c = cfg if cfg is not None else NavigateConfig()
    if n_pairs < 1:
        raise NavigateError(f"n_pairs: must be >= 1, got {n_pairs}")
    g2 = with_reverse_edges(graph)
    ids = g2.island_ids()
    if len(ids) < 2:
        raise NavigateError(f"evaluate_routes: needs at least 2 islands, the graph has {len(ids)}")
    pairs: list[tuple[int, int]] = []
    isl: list[RouteResult] = []
    base: list[RouteResult] = []
    for k in range(n_pairs):
        a, b = (int(x) for x in rng.choice(ids, size=2, replace=False))
        try:
            route = g2.plan_route(a, b).islands
        except GraphError:
            continue
        start = _random_start(g2.get_island(a), c, rng)
        seed = int(rng.integers(2**31))
        isl.append(follow_route(g2, route, setup, c, np.random.default_rng(seed), start))
        base.append(
            follow_route_global_odometry(
                g2, route, origins_odom, setup, c, np.random.default_rng(seed), start
            )
        )
        pairs.append((a, b))
        del k
    return RouteEvaluation(tuple(pairs), tuple(isl), tuple(base))


# ---------------------------------------------------------------------------------------------
# Localization in the island the robot is near (the island_builder_node's localizer behaviour).


@dataclass(frozen=True)
class TrackerConfig:
    """Continuous localization in the nearest island while the robot is within its model."""

    window_scans: int = field(
        default=20, metadata={"help": "scans whose points (by odometry) are localized together [-]"}
    )
    every_n_scans: int = field(
        default=5, metadata={"help": "localize on every n-th scan (CPU budget) [-]"}
    )
    max_extent_m: float = field(
        default=8.0,
        metadata={
            "help": "an island counts as near within its model's extent (farthest "
            "endpoint from its origin), capped at this [m]"
        },
    )
    max_residual_m: float = field(
        default=0.15, metadata={"help": "a localization with a larger RMS residual is ignored [m]"}
    )
    localize: LocalizeConfig = field(
        default_factory=_point_to_line,
        metadata={"help": "line-model localization (point-to-line Gauss-Newton)"},
    )

    def __post_init__(self) -> None:
        if self.window_scans < 1 or self.every_n_scans < 1:
            raise NavigateError("TrackerConfig: window_scans and every_n_scans must be >= 1")
        if not (math.isfinite(self.max_extent_m) and self.max_extent_m > 0):
            raise NavigateError(f"TrackerConfig.max_extent_m: must be > 0, got {self.max_extent_m}")


@dataclass(frozen=True)
class IslandFix:
    """A localization in an island's frame: pose [m, rad], 3x3 covariance, the island."""

    island_id: int
    frame_id: str
    pose: Pose2D
    covariance: FloatArray
    residual_m: float


class IslandTracker:
    """Localizes the robot in the island it is near, scan after scan, from odometry.

    Each island's origin is known in the odometry frame when it is added (where it was built);
    every trusted localization refines that placement, so the estimate follows the drift.
    """

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else TrackerConfig()
        self._islands: dict[
            int, tuple[Island, Pose2D, float]
        ] = {}  # id -> (island, origin, extent)
        self._window: list[FloatArray] = []  # recent scan points in the odometry frame [m]
        self._count = 0
        self.fixes = 0

    def add_island(self, island: Island, origin_odom: Pose2D) -> None:
        """An island and the odometry pose of its origin."""
        seg = island.model.segments
        ext = float(np.max(np.hypot(seg[:, [0, 2]], seg[:, [1, 3]]))) if len(seg) else 0.0
        self._islands[island.id] = (island, origin_odom, min(ext, self.config.max_extent_m))

    def origin_odom(self, island_id: int) -> Pose2D:
        return self._islands[island_id][1]

    def nearest(self, odom_pose: Pose2D) -> int | None:
        """The island whose origin is nearest, if the robot is within that island's extent."""
        best, best_d = None, math.inf
        for i, (_, origin, ext) in self._islands.items():
            d = math.hypot(odom_pose.x - origin.x, odom_pose.y - origin.y)
            if d <= ext and d < best_d:
                best, best_d = i, d
        return best

    def on_scan(
        self, odom_pose: Pose2D, ranges_m: FloatArray, angles_rad: FloatArray
    ) -> IslandFix | None:
        """Add a scan (robot frame) at an odometry pose; a fix when one is due and trusted."""
        self._window.append(ranges_to_points(ranges_m, angles_rad, odom_pose))
        del self._window[: -self.config.window_scans]
        self._count += 1
        if self._count % self.config.every_n_scans:
            return None
        near = self.nearest(odom_pose)
        if near is None:
            return None
        island, origin, ext = self._islands[near]
        robot_pts = to_frame(np.concatenate(self._window, axis=0), odom_pose)
        res = localize(island.model, robot_pts, odom_pose.relative_to(origin), self.config.localize)
        if not res.converged or res.residual_m > self.config.max_residual_m:
            return None
        # Re-place the island origin in the odometry frame so the two agree now.
        self._islands[near] = (island, odom_pose.compose(res.pose.inverse()), ext)
        self.fixes += 1
        var = max(res.residual_m, 0.01) ** 2 / max(res.constraint, 1e-3)
        cov = np.diag([var, var, var / 4.0])  # heading var: residual over a ~2 m lever [rad^2]
        return IslandFix(island.id, island.frame_id, res.pose, cov, res.residual_m)


# ---------------------------------------------------------------------------------------------
# Exploration without ROS: the same closed loop the nodes run (simulator, hall follower, builder).


@dataclass(frozen=True)
class ExplorationResult:
    """What an exploration produced.

    islands, edges: the map; origins_odom: each island origin's odometric pose when it was built
    (for the global-odometry baseline); events: every builder event with its time; truth_path,
    odom_path: (K, 3) poses [m, m, rad] at every scan; collisions: wall contacts of the robot.
    """

    islands: tuple[Island, ...]
    edges: tuple[Edge, ...]
    origins_odom: Mapping[int, Pose2D]
    events: tuple[BuilderEvent, ...]
    truth_path: FloatArray
    odom_path: FloatArray
    collisions: int

    def graph(self) -> TopoGraph:
        return TopoGraph.from_parts(self.islands, self.edges)


def explore(
    setup: SimSetup,
    sim_s: float,
    builder_cfg: BuilderConfig | None = None,
    rng: np.random.Generator | None = None,
    start: Pose2D | None = None,
    physics_rate_hz: float = 50.0,
    sensor_rate_hz: float = 10.0,
) -> ExplorationResult:
    """Explore `setup.world` for `sim_s` simulated seconds from `start` (default: the world's).

    Per sensor period: a scan at the true pose; the builder decides; FOLLOW lets the hall
    follower drive (its strategy feeds the builder), DRIVE pauses it and applies the builder's
    twist; when an island is handed back the follower's strategy record restarts.
    """
    gen = rng if rng is not None else np.random.default_rng(0)
    world = setup.world
    robot = SimRobot(world, start or world.start_pose, gen, setup.robot, setup.odometry)
    sonar = SonarModel(setup.sonar)
    follower = HallFollower(setup.follower, np.random.default_rng(int(gen.integers(2**31))))
    builder = IslandBuilder(builder_cfg)
    steps = max(1, round(physics_rate_hz / sensor_rate_hz))
    dt = 1.0 / physics_rate_hz
    events: list[BuilderEvent] = []
    truth, odom = [], []
    builder.on_odometry(0.0, robot.odom_pose, robot.odom_covariance)
    builder.on_ground_truth(robot.true_pose)
    for _ in range(int(sim_s * sensor_rate_hz)):
        t = robot.time_s
        ranges = sonar.scan(world, robot.true_pose, gen)
        builder.set_strategy(follower.strategy())
        builder.on_scan(t, ranges, sonar.angles_rad)
        cmd = builder.command(t)
        events.extend(cmd.events)
        if any(
            e.kind is EventKind.HANDED_BACK and e.accepted_island_id is not None for e in cmd.events
        ):
            follower.reset_strategy()
        follower.set_enabled(cmd.mode is CommandMode.FOLLOW)
        v, w = follower.update(ranges, sonar.angles_rad, robot.odom_pose, t)
        if cmd.mode is CommandMode.DRIVE:
            v, w = cmd.v_mps, cmd.w_radps
        truth.append(robot.true_pose.as_array())
        odom.append(robot.odom_pose.as_array())
        for _ in range(steps):
            robot.step(v, w, dt)
            builder.on_odometry(robot.time_s, robot.odom_pose, robot.odom_covariance)
            builder.on_ground_truth(robot.true_pose)
    return ExplorationResult(
        tuple(builder.islands),
        tuple(builder.edges),
        dict(builder.island_origins_odom),
        tuple(events),
        np.array(truth).reshape(-1, 3),
        np.array(odom).reshape(-1, 3),
        robot.collisions,
    )
