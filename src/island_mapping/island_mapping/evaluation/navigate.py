"""Driving the simulated robot by a map's control strategies (paper section 8.2).

Simulator-backed (numpy + island_sim cores, no ROS). `SimDriver` steps a `SimRobot` and its
sonar ring in sensor periods and turns and drives by odometry; `execute_strategy` runs an
edge's strategy on it: `Go d` drives d of odometric travel forward with the hall follower's
perception keeping the robot in the middle of the hallway (a qualitative "follow the hall for
d"), `Rot a` rotates in place by a of odometric heading. `NavigateConfig` holds every parameter
of route following, `SimSetup` what the simulated trips run on. Localizing at an island and
docking: `evaluation.docking`; whole routes and their evaluation: `evaluation.routes`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from island_msgs_py.geometry import ranges_to_points
from island_msgs_py.types import ControlStrategy, FloatArray, Pose2D, PrimitiveKind, wrap_angle
from island_sim.core.hall_follower import HallFollower, HallFollowerConfig
from island_sim.core.robot import OdometryConfig, RobotConfig, SimRobot
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world import World

from island_mapping.core.localize import LocalizeConfig, point_to_line_config


class NavigateError(ValueError):
    """Bad input to route following (the message names what was wrong)."""


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
        default_factory=point_to_line_config,
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


@dataclass
class SimSetup:
    """What the simulated trip runs on: the world, sensor, body, odometry and hall perception."""

    world: World
    sonar: SonarConfig = field(default_factory=SonarConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)
    follower: HallFollowerConfig = field(default_factory=HallFollowerConfig)


class SimDriver:
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
            raise SimTimeoutError()
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


class SimTimeoutError(Exception):
    """The simulated time limit of an edge ran out."""


def _go(sim: SimDriver, distance_m: float, follower: HallFollower) -> None:
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


def execute_strategy(sim: SimDriver, strategy: ControlStrategy, follower: HallFollower) -> None:
    """Run the primitives: Go d [cm] along the hallway, Rot a [deg CCW] in place (odometry)."""
    for s in strategy.steps:
        if s.kind is PrimitiveKind.GO:
            _go(sim, s.metres, follower)
        else:
            sim.rotate_by(math.radians(s.value) if s.value <= 180 else math.radians(s.value - 360))
