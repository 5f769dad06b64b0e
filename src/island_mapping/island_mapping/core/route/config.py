"""Configuration of route following by the map (one source of defaults for the simulated
evaluation and the explorer node)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from island_msgs_py.errors import InputError

from island_mapping.core.localize import LocalizeConfig, point_to_line_config


class NavigateError(InputError):
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
    unwind_turns: bool = field(
        default=True,
        metadata={"help": "a look's circle turns the way that undoes the net turning of the "
                          "looks and drives so far (else always left) [bool]"},
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
    go_short_m: float = field(
        default=0.6,
        metadata={"help": "a Go step of a strategy that ends this much short of its length "
                          "(and go_short_fraction of it) is a deviation: the route failed [m]"},
    )
    go_short_fraction: float = field(
        default=0.1, metadata={"help": "see go_short_m [-]"}
    )
    doorway_go_m: float = field(
        default=2.5,
        metadata={"help": "a quarter turn followed by a Go no longer than this enters a "
                          "doorway: the robot first stops at the doorway's middle [m]"},
    )
    doorway_search_m: float = field(
        default=0.8,
        metadata={"help": "it looks for the doorway this far back and on [m]"},
    )
    contact_retries: int = field(
        default=2,
        metadata={"help": "a Go step that touches a wall backs off and goes on this many times "
                          "before it stops there [-]"},
    )
    contact_backoff_m: float = field(
        default=0.2, metadata={"help": "how far it backs off [m]"}
    )
    one_wall_band_m: float = field(
        default=0.5,
        metadata={"help": "with one wall seen, the robot keeps half the hallway's width from it "
                          "only when it is within this of that distance already (a room's wall "
                          "farther off is no hallway's: the heading is held instead) [m]"},
    )
    doorway_ahead_m: float = field(
        default=1.6,
        metadata={"help": "echoes this near ahead, either side of the path, bound a doorway the "
                          "robot steers into the middle of [m]"},
    )
    doorway_max_width_m: float = field(
        default=1.6,
        metadata={"help": "a gap ahead narrower than this is a doorway (a hallway's walls, "
                          "farther apart, centre the robot themselves) [m]"},
    )
    passage_side_m: float = field(
        default=0.7,
        metadata={"help": "both side walls nearer than this: a doorway's passage, where only "
                          "the echo straight ahead ends a Go step [m]"},
    )
    route_max_shift_m: float = field(
        default=2.0,
        metadata={"help": "an arrival's fit farther than this from where the route's end puts "
                          "the robot is not trusted (the search along a hallway reaches "
                          "axis_search_steps x axis_search_step_m; beyond, a look-alike) [m]"},
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
        default=20.0,
        metadata={
            "help": "a fit that turned the points farther than this from the estimate's "
            "heading is no arrival candidate [deg]"
        },
    )
    min_fit_constraint: float = field(
        default=0.08,
        metadata={
            "help": "a fit that constrains the position along some axis less than this "
            "(smaller eigenvalue of the normalized normal matrix) is no arrival candidate "
            "[0-0.5]"
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
            "help": "a look-around with fewer echo points than this is too sparse for its fit's "
            "weak axis to mean anything: the search goes along the arrival heading instead [-]"
        },
    )
    dock_tol_m: float = field(
        default=0.05, metadata={"help": "docking at an origin ends within this distance [m]"}
    )
    dock_tol_deg: float = field(default=3.0, metadata={"help": "and this heading [deg]"})
    dock_attempts: int = field(default=3, metadata={"help": "drive-and-relocalize rounds [-]"})
    alias_after_deg: float = field(
        default=3600.0,
        metadata={"help": "after the robot has turned this much (either way, counted by the "
                          "explorer) since it last knew its pose (a trusted fix, a hand back "
                          "at an island's origin), odometry's heading may be a "
                          "quarter turn off: an arrival's fit that fits as well turned by a "
                          "quarter or half turn is not trusted (a square room, a + junction) "
                          "(0: always checked) [deg]"},
    )
    alias_margin: float = field(
        default=0.1,
        metadata={"help": "a turned fit whose matched share of the points is within this of "
                          "the fit's fits as well [-]"},
    )
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
            "passage_side_m",
            "route_max_shift_m",
            "doorway_go_m",
            "go_short_m",
            "go_short_fraction",
            "doorway_search_m",
            "contact_backoff_m",
            "doorway_ahead_m",
            "doorway_max_width_m",
            "one_wall_band_m",
            "max_turn_deg",
            "min_fit_constraint",
            "axis_search_step_m",
            "axis_search_min_constraint",
            "alias_after_deg",
            "alias_margin",
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
        if self.contact_retries < 0:
            raise NavigateError(
                f"NavigateConfig.contact_retries: must be >= 0, got {self.contact_retries}"
            )
        if self.dock_attempts < 1:
            raise NavigateError(
                f"NavigateConfig.dock_attempts: must be >= 1, got {self.dock_attempts}"
            )

    @property
    def steps_per_scan(self) -> int:
        return max(1, round(self.physics_rate_hz / self.sensor_rate_hz))
