"""The island builder's configuration: the single source of its defaults.

`BuilderConfig` (eq. 3, the attempt rules, where an accepted island's origin goes) holds a
`StarConfig` (the four-corner star the robot drives), an `OpeningConfig` (side openings as
places, `opening_config`) and a `RevisitConfig` (recognising an island the robot already built,
`revisit_config`); `BuilderError` is re-exported from `errors`. Each field's `help` says what
it does; docs/builder.md says why the defaults are what they are.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from island_msgs_py.types import ModelType

from island_mapping.core.builder.calibration import CalibrationConfig
from island_mapping.core.builder.errors import BuilderError
from island_mapping.core.builder.errors import check_numbers as _check

__all__ = ["BuilderConfig", "BuilderError", "OpeningConfig", "RevisitConfig", "StarConfig"]
from island_mapping.core.builder.opening_config import OpeningConfig
from island_mapping.core.builder.revisit_config import RevisitConfig
from island_mapping.core.fisher import FisherConfig
from island_mapping.core.lines import LineFitConfig
from island_mapping.core.localize import LocalizeConfig, Solver
from island_mapping.core.measure import MeasureConfig


def _point_to_line() -> LocalizeConfig:
    """Localization with the Gauss-Newton point-to-line step (the Dudek-MacKenzie step reaches
    the same fixed point but often needs more than its iteration limit)."""
    return LocalizeConfig(solver=Solver.POINT_TO_LINE)


@dataclass(frozen=True)
class StarConfig:
    """The star routine that collects data at four corners around the island origin."""

    leg_length_m: float = field(
        default=1.2,
        metadata={
            "help": "longest leg from the origin to a corner (ahead, left, behind, right) [m]"
        },
    )
    min_leg_m: float = field(
        default=0.3,
        metadata={"help": "legs the free space allows only shorter than this are skipped [m]"},
    )
    clearance_m: float = field(
        default=0.7,
        metadata={"help": "a leg stops this far (robot centre) before the nearest echo ahead [m]"},
    )
    ahead_halfwidth_deg: float = field(
        default=25.0,
        metadata={"help": "beams within this bearing of the heading count as ahead [deg]"},
    )
    speed_mps: float = field(default=0.3, metadata={"help": "driving speed on the legs [m/s]"})
    turn_rate_radps: float = field(
        default=0.8, metadata={"help": "largest turn rate when rotating in place [rad/s]"}
    )
    unwind_turns: bool = field(
        default=True,
        metadata={"help": "a star's legs and a look's circle turn the way that undoes the "
                          "robot's net turning so far (else always left) [bool]"},
    )
    heading_gain_per_s: float = field(
        default=2.0, metadata={"help": "proportional gain of heading control [1/s]"}
    )
    position_tol_m: float = field(
        default=0.03, metadata={"help": "a leg end is reached within this distance [m]"}
    )
    heading_tol_deg: float = field(
        default=2.0, metadata={"help": "a rotation is done within this heading error [deg]"}
    )
    drive_heading_err_deg: float = field(
        default=20.0,
        metadata={
            "help": "on a leg, turn in place instead of driving while the heading is off the "
            "leg's line by more than this [deg]"
        },
    )

    def __post_init__(self) -> None:
        _check("StarConfig", self, (
            "leg_length_m", "min_leg_m", "clearance_m", "ahead_halfwidth_deg", "speed_mps",
            "turn_rate_radps", "heading_gain_per_s", "position_tol_m", "heading_tol_deg",
            "drive_heading_err_deg",
        ), strict=True)
        if self.min_leg_m > self.leg_length_m:
            raise BuilderError(
                f"StarConfig.min_leg_m ({self.min_leg_m}) exceeds leg_length_m "
                f"({self.leg_length_m})"
            )


@dataclass(frozen=True)
class BuilderConfig:
    """Eq. 3, the attempt rules and the placement of an accepted island's origin."""

    e_min_m: float = field(
        default=0.3,
        metadata={"help": "E_min: accumulated odometry error bound that triggers an attempt [m]"},
    )
    threshold_line: float = field(
        default=0.25,
        metadata={"help": "T_line: acceptance threshold of the line-model measure R [-]"},
    )
    threshold_fisher: float = field(
        default=0.8, metadata={"help": "T_fisher: acceptance threshold of the Fisher score [-]"}
    )
    bound_floor: float = field(
        default=0.6,
        metadata={
            "help": "the eq. 3 bound E_min/epsilon never drops below this, so a very lost "
            "robot still refuses featureless places (0 = the paper's eq. 3 exactly) [-]"
        },
    )
    quick_reject_fraction: float = field(
        default=0.3,
        metadata={
            "help": "the attempt fails at once when the quick check's best normalized "
            "measure is below this fraction of the bound [-]"
        },
    )
    quick_history_m: float = field(
        default=1.0,
        metadata={"help": "the quick check uses scan points seen over this last path length [m]"},
    )
    retry_distance_m: float = field(
        default=1.0,
        metadata={
            "help": "path length to follow after a failed or dismissed attempt before "
            "the next one [m]"
        },
    )
    vicinity_m: float = field(
        default=4.0,
        metadata={
            "help": "no attempt while the robot is within this odometric distance of the last "
            "island's origin: it is still within that island's reach, whatever epsilon says "
            "(0 = off) [m]"
        },
    )
    settled_go_m: float = field(
        default=1.0,
        metadata={
            "help": "after a turn, the hall follower must have gone straight this far before an "
            "attempt may start, so an island's origin and theta 0 lie along a hallway, never "
            "mid-turn or facing a wall (0 = off) [m]"
        },
    )
    defer_while_rising: bool = field(
        default=True,
        metadata={
            "help": "when the quick check passes, keep following while its measure still rises "
            "(by more than defer_rise_fraction per defer_step_m) so the star starts near the "
            "measure's peak rather than where a feature first comes into sonar range [bool]"
        },
    )
    defer_step_m: float = field(
        default=0.5, metadata={"help": "path between quick checks while deferring [m]"}
    )
    defer_rise_fraction: float = field(
        default=0.05, metadata={"help": "relative rise of the quick measure that defers [-]"}
    )
    defer_max_m: float = field(
        default=4.0, metadata={"help": "longest path an attempt is deferred [m]"}
    )
    defer_timeout_s: float = field(
        default=5.0,
        metadata={
            "help": "a deferred attempt starts anyway after this long without reaching "
            "the next check (the robot stopped), once the hall follower is not turning [s]"
        },
    )
    dismiss_min_legs: int = field(
        default=2, metadata={"help": "legs of the star done before an attempt may be dismissed [-]"}
    )
    dismiss_fraction: float = field(
        default=0.5,
        metadata={
            "help": "dismiss when the best normalized measure so far is below this "
            "fraction of the bound [-]"
        },
    )
    complete_star: bool = field(
        default=True,
        metadata={
            "help": "once the measure passes eq. 3, still drive the remaining legs so the "
            "island's model is complete; false = accept at once [bool]"
        },
    )
    register_legs: bool = field(
        default=True,
        metadata={
            "help": "register each star leg's echoes onto the model the earlier legs built and "
            "turn them, and the anchor, by the heading found, weighted against odometry's "
            "heading variance since the anchor (a Kalman gain with register_sigma_deg) [bool]"
        },
    )
    register_sigma_deg: float = field(
        default=2.5,
        metadata={
            "help": "heading error of one leg's registration onto the earlier legs' model [deg]"
        },
    )
    origin_at_peak: bool = field(
        default=True,
        metadata={
            "help": "put an accepted island's origin where its own model's measure peaks along "
            "the star legs the robot drove, not where the attempt started; the edge gets the "
            "drive from the anchor to the origin [bool]"
        },
    )
    peak_step_m: float = field(
        default=0.2, metadata={"help": "spacing of the candidate origins along the legs [m]"}
    )
    peak_ahead_m: float = field(
        default=3.0,
        metadata={
            "help": "also search for the peak beyond the ahead leg, along the arrival heading, "
            "up to this far from the anchor (within the anchor's free range ahead, the drives "
            "there from the anchor and from the robot clear of the model's walls). Such an "
            "origin is probed (driven to, looked around from, checked, its look added to the "
            "model) before it is kept. 0 = off [m]"
        },
    )
    peak_behind: bool = field(
        default=False,
        metadata={
            "help": "with peak_ahead_m > 0, also search beyond the back leg, within the "
            "straight path the hall follower reported driving up to the anchor [bool]"
        },
    )
    peak_min_gain: float = field(
        default=0.1,
        metadata={
            "help": "move the origin only when the peak's normalized measure beats the "
            "anchor's by this fraction [-]"
        },
    )
    peak_ahead_min_gain: float = field(
        default=0.1,
        metadata={
            "help": "the gain that moves the origin ahead along the driven ahead leg (the move "
            "adds only a Go to the edge and asks for no probe) [-]"
        },
    )
    origin_feature_radius_m: float = field(
        default=3.0,
        metadata={
            "help": "when the origin the peak search chose sees, in the island's own model, "
            "only parallel walls within this distance (a plain hallway), move it to the best "
            "point along the driven legs that sees walls in two directions and still passes "
            "the acceptance bound; failing that, probe the best such point past the legs "
            "(ahead, or back along the straight path the robot came by); after a probe whose "
            "look's model still shows a plain hallway there, climb once on to the peak further "
            "on. 0 = off [m]"
        },
    )
    verify_localization: bool = field(
        default=True,
        metadata={
            "help": "before accepting, localize the points seen at the origin (the star turns "
            "there through a full circle) against the new model from guesses offset by "
            "verify_offset_m; accept only if every guess comes back to the origin [bool]"
        },
    )
    verify_offset_m: float = field(
        default=0.3, metadata={"help": "offset of the verification guesses [m]"}
    )
    verify_tol_m: float = field(
        default=0.1, metadata={"help": "a verification localization must end this close [m]"}
    )
    probe_turn_deg: float = field(
        default=8.0,
        metadata={
            "help": "the check of an origin past the legs also starts from guesses turned by "
            "+- this, as navigation's localization does [deg]"
        },
    )
    probe_agree_deg: float = field(
        default=4.0,
        metadata={"help": "and all its fits must agree in heading within this [deg]"},
    )
    probe_climbs: int = field(
        default=0,
        metadata={
            "help": "after a probe passes, search on from there with the model its look "
            "completed and probe again at most this many times while the peak moves on "
            "(0 = off) [-]"
        },
    )
    centre_radius_m: float = field(
        default=0.1,
        metadata={
            "help": "scans taken within this distance of the origin count as seen from it [m]"
        },
    )
    accept_on_legs: bool = field(
        default=False,
        metadata={
            "help": "eq. 3 checks the region the star surveyed: the best normalized measure "
            "at the anchor or along the driven legs (not in a plain hallway) must pass the "
            "bound, and the origin goes there; off: at the anchor only [bool]"
        },
    )
    origin_seen_radius_m: float = field(
        default=0.15,
        metadata={"help": "with accept_on_legs, scans taken this near the chosen origin are "
                          "what the new-island check localizes [m]"},
    )
    drive_stall_s: float = field(
        default=8.0,
        metadata={"help": "a drive (a star leg, back to an opening's middle, onto an origin, "
                          "docking) that moves the robot less than 2 cm / 2 deg for this long "
                          "ends where the robot is (it pushes at a wall); 0 = never [s]"},
    )
    build_first_island: bool = field(
        default=True,
        metadata={"help": "build island 0 at the start pose before following (paper 8.2) [bool]"},
    )
    first_island_min_measure: float = field(
        default=0.0,
        metadata={
            "help": "island 0 is accepted when its best normalized measure exceeds this "
            "(0 = always: the start is a node by definition) [-]"
        },
    )
    edge_path_tolerance_m: float = field(
        default=0.5,
        metadata={"help": "an edge's strategy is the way the follower drove by odometry, "
                          "simplified to a polyline within this (core.builder.path_record); "
                          "0 = the follower's own record of its primitives [m]"},
    )
    edge_shortcut_m: float = field(
        default=0.0,
        metadata={"help": "an edge's way is kept without its loops: where it came back within "
                          "this of a point passed edge_loop_m earlier, the lap (a room walked "
                          "round, a shuttle) is cut (core.graph.without_loops); 0: kept [m]"},
    )
    edge_loop_m: float = field(
        default=3.0,
        metadata={"help": "see edge_shortcut_m: the shortest stretch of the way that counts as "
                          "a loop [m]"},
    )
    star: StarConfig = field(
        default_factory=StarConfig, metadata={"help": "the four-corner star routine"}
    )
    calibration: CalibrationConfig = field(
        default_factory=CalibrationConfig,
        metadata={"help": "the odometry's systematic heading error, learnt from docks "
                          "(core.builder.calibration)"},
    )
    opening: OpeningConfig = field(
        default_factory=OpeningConfig,
        metadata={"help": "side openings as places to attempt islands at (core.builder.opening)"},
    )
    revisit: RevisitConfig = field(
        default_factory=RevisitConfig, metadata={"help": "recognising islands already built"}
    )
    localize: LocalizeConfig = field(
        default_factory=_point_to_line,
        metadata={"help": "localization of the verification (point-to-line Gauss-Newton)"},
    )
    line_fit: LineFitConfig = field(
        default_factory=LineFitConfig, metadata={"help": "line fitting of the collected points"}
    )
    measure: MeasureConfig = field(
        default_factory=MeasureConfig, metadata={"help": "the line-model measure R (T_line)"}
    )
    fisher: FisherConfig = field(
        default_factory=FisherConfig, metadata={"help": "the Fisher-information score (T_fisher)"}
    )

    def __post_init__(self) -> None:
        _check("BuilderConfig", self, (
            "e_min_m", "threshold_line", "threshold_fisher", "quick_history_m", "peak_step_m",
            "register_sigma_deg",
        ), strict=True)
        _check("BuilderConfig", self, (
            "bound_floor", "quick_reject_fraction", "retry_distance_m", "vicinity_m",
            "settled_go_m", "dismiss_fraction", "first_island_min_measure", "peak_min_gain",
            "peak_ahead_min_gain", "peak_ahead_m", "origin_feature_radius_m", "probe_turn_deg",
            "probe_agree_deg", "origin_seen_radius_m", "drive_stall_s", "edge_path_tolerance_m",
            "edge_shortcut_m", "edge_loop_m",
        ), strict=False)
        if isinstance(self.probe_climbs, bool) or not isinstance(self.probe_climbs, int) or (
            self.probe_climbs < 0
        ):
            raise BuilderError(
                f"BuilderConfig.probe_climbs: expected an int >= 0, got {self.probe_climbs!r}"
            )
        if not 1 <= self.dismiss_min_legs <= 4:
            raise BuilderError(
                f"BuilderConfig.dismiss_min_legs: expected 1..4, got {self.dismiss_min_legs}"
            )

    def threshold(self, model_type: ModelType) -> float:
        """T_i of a model type."""
        return self.threshold_line if model_type is ModelType.LINE else self.threshold_fisher
