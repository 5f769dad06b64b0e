"""The island builder's configuration: the single source of its defaults.

`BuilderConfig` (eq. 3, the attempt rules, where an accepted island's origin goes) holds a
`StarConfig` (the four-corner star the robot drives) and a `RevisitConfig` (recognising an
island the robot already built). Each field's `help` says what it does; docs/builder.md says
why the defaults are what they are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from island_msgs_py.errors import InputError
from island_msgs_py.types import ModelType

from island_mapping.core.fisher import FisherConfig
from island_mapping.core.lines import LineFitConfig
from island_mapping.core.localize import LocalizeConfig, Solver
from island_mapping.core.measure import MeasureConfig


class BuilderError(InputError):
    """Bad input to the island builder (the message names the argument and the problem)."""


def _point_to_line() -> LocalizeConfig:
    """Localization with the Gauss-Newton point-to-line step (the Dudek-MacKenzie step reaches
    the same fixed point but often needs more than its iteration limit)."""
    return LocalizeConfig(solver=Solver.POINT_TO_LINE)


def _check(owner: str, obj: object, names: tuple[str, ...], strict: bool) -> None:
    """Each named field must be a finite number > 0 (strict) or >= 0."""
    for name in names:
        v = getattr(obj, name)
        ok = isinstance(v, int | float) and math.isfinite(v) and (v > 0 if strict else v >= 0)
        if not ok:
            bound = "> 0" if strict else ">= 0"
            raise BuilderError(f"{owner}.{name}: expected a finite number {bound}, got {v!r}")


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
class RevisitConfig:
    """Recognising an island the robot already built (beyond the paper: revisits on a loop).

    Tried whenever the quick check passes (before deferring or starting a star), and on a
    star's points before it becomes a new island: islands whose origin may lie near the
    odometric pose are searched for the scan points; a recognition must converge with a small
    residual, be unambiguous and pass the new-island localization check.
    """

    enabled: bool = field(
        default=True, metadata={"help": "try to recognise known islands before a star [bool]"}
    )
    search_sigmas: float = field(
        default=1.0,
        metadata={
            "help": "the position (heading) search spans this many sigmas of where the "
            "candidate's origin may be: the odometric drift since its origin was last known, "
            "or epsilon plus the error of its link chain from the last island [-]"
        },
    )
    search_min_m: float = field(
        default=0.5, metadata={"help": "smallest position search radius [m]"}
    )
    search_max_m: float = field(
        default=4.0,
        metadata={
            "help": "largest position search radius; candidates that would need a larger "
            "one are not searched (a match could be a look-alike place) [m]"
        },
    )
    search_step_m: float = field(
        default=0.3, metadata={"help": "spacing of the initial guesses of the search [m]"}
    )
    heading_step_deg: float = field(
        default=5.0, metadata={"help": "spacing of the heading guesses [deg]"}
    )
    search_max_deg: float = field(
        default=30.0,
        metadata={
            "help": "largest heading offset searched; candidates whose heading drift "
            "(search_sigmas sigmas) exceeds it are not searched [deg]"
        },
    )
    refine_guesses: int = field(
        default=6,
        metadata={"help": "best-scoring distinct guesses refined by localization [-]"},
    )
    inlier_m: float = field(
        default=0.15,
        metadata={"help": "a point within this of the model counts for a guess's score [m]"},
    )
    max_range_m: float = field(
        default=4.0, metadata={"help": "only echoes up to this range are matched [m]"}
    )
    history_m: float = field(
        default=3.0, metadata={"help": "scan points of this last path length are matched [m]"}
    )
    min_points: int = field(
        default=40, metadata={"help": "fewest recent scan points to try a recognition [-]"}
    )
    max_points: int = field(
        default=200, metadata={"help": "the recent points are thinned evenly to this many [-]"}
    )
    max_residual_m: float = field(
        default=0.15, metadata={"help": "largest RMS residual of a recognition [m]"}
    )
    min_constraint: float = field(
        default=0.1,
        metadata={
            "help": "a recognition's fit must constrain the position along every axis this "
            "much (smaller eigenvalue of the normalized normal matrix; hallway points fit a "
            "hallway anywhere along it) [0-0.5]"
        },
    )
    min_inlier_fraction: float = field(
        default=0.6,
        metadata={"help": "fewest points within inlier_m of the model at the recognised pose [-]"},
    )
    ambiguity_m: float = field(
        default=0.5,
        metadata={
            "help": "refuse when two refined hypotheses that both fit lie farther apart than "
            "this (the model fits at distinct places) [m]"
        },
    )
    rival_sigmas: float = field(
        default=3.0,
        metadata={
            "help": "before a recognition is accepted, every other known island that may be "
            "where the robot is (its odometric estimate within this many sigmas plus "
            "max_dock_m) is searched too, over this many sigmas (within rival_max_m and "
            "star_search_max_deg); if one also fits, the place is a look-alike and the "
            "recognition is refused (0 = no such check) [-]"
        },
    )
    rival_max_m: float = field(
        default=12.0,
        metadata={
            "help": "largest position search radius of that check; its guess grid is "
            "radius / star_search_cells, at most rival_step_m [m]"
        },
    )
    rival_step_m: float = field(
        default=0.6, metadata={"help": "largest spacing of the rival search's guesses [m]"}
    )
    max_dock_m: float = field(
        default=3.0,
        metadata={"help": "the recognised island's origin must be this close to the robot [m]"},
    )
    path_clearance_m: float = field(
        default=0.45,
        metadata={
            "help": "the straight drive to the origin must keep this far from the model's "
            "walls (robot centre) [m]"
        },
    )
    min_loop_m: float = field(
        default=10.0,
        metadata={
            "help": "the last island is a candidate only after this much path since leaving "
            "it (a loop back to it; just after it, driving back is no use) [m]"
        },
    )
    at_star: bool = field(
        default=True,
        metadata={
            "help": "before a star that passed eq. 3 becomes a new island, match its points "
            "(a full circle at the anchor and four legs) against the known islands nearby; "
            "a match is a revisit [bool]"
        },
    )
    star_search_sigmas: float = field(
        default=2.5,
        metadata={"help": "search_sigmas for the star's points [-]"},
    )
    star_search_max_m: float = field(
        default=6.0,
        metadata={
            "help": "largest position search radius of the star's points; a candidate that "
            "would need more is not searched (search_max_m for the star) [m]"
        },
    )
    star_search_max_deg: float = field(
        default=45.0, metadata={"help": "and largest heading search (search_max_deg) [deg]"}
    )
    star_search_cells: int = field(
        default=10,
        metadata={
            "help": "the star's guess grid has at least radius / this spacing, so a wide "
            "search stays a few thousand guesses (localization refines them) [-]"
        },
    )
    star_max_residual_m: float = field(
        default=0.2,
        metadata={
            "help": "largest RMS residual of a recognition from a star's points (echoes from "
            "five places scatter more than a follower's recent points) [m]"
        },
    )
    star_max_points: int = field(
        default=300, metadata={"help": "the star's points are thinned evenly to this many [-]"}
    )
    strategy_min_go_m: float = field(
        default=0.3,
        metadata={
            "help": "an edge's drive onto a recognised origin nearer than this is only the final "
            "turn (the arrival's localization takes up the rest) [m]"
        },
    )
    dock_tol_m: float = field(
        default=0.05, metadata={"help": "docking at the origin ends within this distance [m]"}
    )
    dock_tol_deg: float = field(
        default=3.0, metadata={"help": "and this heading [deg]"}
    )
    dock_looks: int = field(
        default=2,
        metadata={
            "help": "look-around localizations at the origin (turn a full circle, localize, "
            "re-dock if off) [-]"
        },
    )
    unique_island: bool = field(
        default=False,
        metadata={"help": "refuse a recognition when the points fit more than one known island "
                          "(each within its own window) [bool]"},
    )
    ambiguity_inlier_margin: float = field(
        default=1.0,
        metadata={"help": "a second fit (elsewhere in one island, or of another island with "
                          "unique_island) makes a recognition ambiguous only when its inlier "
                          "fraction is within this of the best fit's (1: any fit does) [-]"},
    )
    clip_search: bool = field(
        default=False,
        metadata={"help": "a candidate whose window would exceed the search caps is searched "
                          "within the caps instead of refused (needs unique_island and a "
                          "revisit gate with topological evidence) [bool]"},
    )
    fit_sigma_m: float = field(
        default=0.3, metadata={"help": "a recognised pose's own position error, added to the "
                               "odometric estimate's covariance in its Mahalanobis distance [m]"})
    fit_sigma_deg: float = field(
        default=3.0, metadata={"help": "and its heading error [deg]"})

    def __post_init__(self) -> None:
        _check("RevisitConfig", self, (
            "search_sigmas", "search_min_m", "search_max_m", "search_step_m",
            "heading_step_deg", "inlier_m", "history_m", "max_range_m", "max_residual_m",
            "ambiguity_m", "max_dock_m", "dock_tol_m", "dock_tol_deg", "strategy_min_go_m",
            "star_search_sigmas", "star_max_residual_m", "star_search_max_m",
            "star_search_max_deg", "rival_max_m", "rival_step_m", "fit_sigma_m", "fit_sigma_deg",
        ), strict=True)
        _check("RevisitConfig", self, (
            "search_max_deg", "path_clearance_m", "min_inlier_fraction", "min_loop_m",
            "min_constraint", "rival_sigmas", "ambiguity_inlier_margin",
        ), strict=False)
        for name in ("refine_guesses", "min_points", "max_points", "star_search_cells",
                     "star_max_points"):
            iv = getattr(self, name)
            if iv < 1:
                raise BuilderError(f"RevisitConfig.{name}: expected >= 1, got {iv}")
        if self.dock_looks < 0:
            raise BuilderError(f"RevisitConfig.dock_looks: expected >= 0, got {self.dock_looks}")
        if self.search_min_m > self.search_max_m:
            raise BuilderError(
                f"RevisitConfig.search_min_m ({self.search_min_m}) exceeds search_max_m "
                f"({self.search_max_m})"
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
    star: StarConfig = field(
        default_factory=StarConfig, metadata={"help": "the four-corner star routine"}
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
            "probe_agree_deg",
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
