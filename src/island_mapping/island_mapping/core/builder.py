"""The island builder: where to build islands of reliability (paper sections 5 and 8.2, eq. 3).

Pure decision logic (numpy only, no ROS). The node feeds it odometry, sonar scans and the hall
follower's executed strategy, and asks it once per scan what to do (`command`):

- FOLLOW: let the hall follower drive;
- DRIVE(v, w): the builder drives (the star routine that collects data at four corners).

and which events happened (attempt started, failed at once, island accepted, attempt dismissed).

The decisions (see docs/builder.md):

- epsilon, the estimated accumulated error since the robot last knew where it was, is
  sqrt(largest eigenvalue of the xy block of P), P the covariance of the odometric pose relative
  to the last island's origin, rebuilt from the odometry's propagated covariance
  (`RelativeCovariance`).
- When epsilon > E_min the robot is "lost" and attempts an island. A quick check fits lines to
  the points seen over the last metres of travel and evaluates every model type at the robot; if
  even a generous fraction of the eq. 3 bound is out of reach the attempt fails at once (a dot in
  the paper's Fig. 4a) and the robot keeps following, retrying after `retry_distance_m`.
- Otherwise the star: the attempt pose becomes the island origin (0, 0, 0); the robot drives legs
  of up to `leg_length_m` ahead, left, behind and right of it (each leg shortened so it stays in
  free space as the sonar sees it, skipped if too short), reversing back to the centre after each
  leg, accumulating scan points in the origin frame by odometry. After each leg it fits lines and
  evaluates every model type at the origin: the island is acceptable when
  max_i(R_i / T_i) > max(E_min / epsilon, bound_floor) (eq. 3); the attempt is dismissed once
  `dismiss_min_legs` legs are done and the best normalized measure is below `dismiss_fraction`
  of the bound (a partial star). An acceptable star is completed, then the points seen from the
  origin must localize back onto it from offset guesses (`verify_localization`), else it is
  dismissed too. Either way the robot faces the origin's heading again before handing back, so
  the hall follower's strategy continues from where it was.
- The first island is built at the start pose (the paper's robot begins at a starting node) with
  the full star and accepted whatever its measure (`first_island_min_measure` can demand more).
"""

from __future__ import annotations

import bisect
import heapq
import math
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import numpy.typing as npt
from island_msgs_py.types import (
    ControlStrategy,
    Edge,
    FloatArray,
    Island,
    LineModel,
    ModelType,
    Pose2D,
    PrimitiveKind,
    StrategyPrimitive,
    wrap_angle,
)

from island_mapping.core.fisher import FisherConfig
from island_mapping.core.graph import normalize_strategy
from island_mapping.core.lines import (
    LineFitConfig,
    fit_lines,
    point_segment_distance,
    thin_evenly,
)
from island_mapping.core.localize import LocalizeConfig, Solver, localize
from island_mapping.core.measure import MeasureConfig, evaluate_models
from island_mapping.core.placement import PlaceKind, PlacementConfig, classify_place
from island_msgs_py import json_io

# A covariance difference below this is numerical noise [m^2].
_COV_EPS_M2 = 1e-12


class BuilderError(ValueError):
    """Bad input to the island builder (the message names the argument and the problem)."""


REGISTER_GATE_SIGMAS = 3.0
"""A leg's registered turn is kept within this many sigmas of its innovation (odometry's heading
variance plus register_sigma_deg's): 99.7 % of right fits pass, a wrong wall's 90 deg does not."""


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
            "leg's line by more than this (measured live: a leg begun while the follower was "
            "still being paused started 46 deg off, swung wider and touched a wall) [deg]"
        },
    )

    def __post_init__(self) -> None:
        for name in (
            "leg_length_m",
            "min_leg_m",
            "clearance_m",
            "ahead_halfwidth_deg",
            "speed_mps",
            "turn_rate_radps",
            "heading_gain_per_s",
            "position_tol_m",
            "heading_tol_deg",
            "drive_heading_err_deg",
        ):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise BuilderError(f"StarConfig.{name}: expected a finite number > 0, got {v!r}")
        if self.min_leg_m > self.leg_length_m:
            raise BuilderError(
                f"StarConfig.min_leg_m ({self.min_leg_m}) exceeds leg_length_m "
                f"({self.leg_length_m})"
            )


@dataclass(frozen=True)
class RevisitConfig:
    """Recognising an island the robot already built (beyond the paper: revisits on a loop).

    Tried whenever the quick check passes (before deferring or starting a star): islands whose
    origin lies near the odometric pose are searched for the recent scan points; a recognition
    must converge with a small residual and pass the new-island localization check.
    """

    enabled: bool = field(
        default=True, metadata={"help": "try to recognise known islands before a star [bool]"}
    )
    search_sigmas: float = field(
        default=1.0,
        metadata={
            "help": "the position (heading) search spans this many sigmas of where the "
            "candidate's origin may be: the odometric drift since its origin was last known, "
            "or epsilon plus the error of its link to the last island (the odometry's "
            "covariance is conservative: measured errors were 0.2-1 sigma) [-]"
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
            "much (smaller eigenvalue of the normalized normal matrix; hallway points alias "
            "along it: paper_fig4's false recognitions, 1.7-6.9 m off, had 0.03-0.06, true "
            "ones 0.17-0.47) [0-0.5]"
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
            "(a full circle at the anchor and four legs: far richer than the points seen "
            "while following) against the known islands nearby; a match is a revisit [bool]"
        },
    )
    star_search_sigmas: float = field(
        default=2.5,
        metadata={
            "help": "search_sigmas for the star's points: a second lap's odometric estimate of "
            "an island was found 1.5 sigma off (paper_fig4), and the star's fit can afford "
            "a wide search [-]"
        },
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
            "help": "largest RMS residual of a recognition from a star's points: echoes from "
            "five places and wide cones near walls scatter more (a true match in a box corridor "
            "had 0.152 m; the false ones found in paper_fig4 had 0.11-0.14, so the residual "
            "does not guard against look-alikes, the constraint and ambiguity tests do) [m]"
        },
    )
    star_max_points: int = field(
        default=300, metadata={"help": "the star's points are thinned evenly to this many [-]"}
    )
    strategy_min_go_m: float = field(
        default=0.3,
        metadata={
            "help": "an edge's drive onto a recognised origin nearer than this is only the final "
            "turn (the arrival's localization takes up the rest; a turn-around to go 10 cm "
            "and a turn back made edges fragile) [m]"
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

    def __post_init__(self) -> None:
        for name in (
            "search_sigmas",
            "search_min_m",
            "search_max_m",
            "search_step_m",
            "heading_step_deg",
            "inlier_m",
            "history_m",
            "max_range_m",
            "max_residual_m",
            "ambiguity_m",
            "max_dock_m",
            "dock_tol_m",
            "dock_tol_deg",
            "strategy_min_go_m",
            "star_search_sigmas",
            "star_max_residual_m",
            "star_search_max_m",
            "star_search_max_deg",
            "rival_max_m",
            "rival_step_m",
        ):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise BuilderError(
                    f"RevisitConfig.{name}: expected a finite number > 0, got {v!r}"
                )
        for name in ("search_max_deg", "path_clearance_m", "min_inlier_fraction", "min_loop_m",
                     "min_constraint", "rival_sigmas"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise BuilderError(
                    f"RevisitConfig.{name}: expected a finite number >= 0, got {v!r}"
                )
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
    """Eq. 3 and the attempt rules of the island builder."""

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
            "island's origin: it is still within that island's reach (star legs 1.2 m plus the "
            "sonar's dense range), so it is not lost whatever epsilon says (epsilon carries the "
            "star's turning drift and passed E_min 4 m on, which put a second island just past "
            "a junction whose mouth already had one) [m]"
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
            "the next check (the robot stopped), once the hall follower is not turning (at a "
            "dead end it turns round in place: live seed 9 anchored an island mid-turn, 43 deg "
            "off the corridor, and going on from it failed 4 of 20 routes) [s]"
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
            "island's model is complete (the paper's Fig. 4a shows full stars for built "
            "islands); false = accept at once [bool]"
        },
    )
    register_legs: bool = field(
        default=True,
        metadata={
            "help": "register each star leg's echoes onto the model the earlier legs built and "
            "turn them, and the anchor, by the heading found, weighted against odometry's "
            "heading variance since the anchor (a Kalman gain with register_sigma_deg): every "
            "turn at the anchor adds heading noise, which otherwise turns the later legs' walls "
            "in the island's model [bool]"
        },
    )
    register_sigma_deg: float = field(
        default=2.5,
        metadata={
            "help": "heading error of one leg's registration onto the earlier legs' sonar "
            "model (a partial view through 25 deg cones: 2-4 deg seen on paper_fig4) [deg]"
        },
    )
    origin_at_peak: bool = field(
        default=True,
        metadata={
            "help": "put an accepted island's origin where its own model's measure peaks along "
            "the star legs the robot drove (not where the attempt happened to start: the quick "
            "check passes a few metres before a junction, or just past a door); the edge gets "
            "the drive from the anchor to the origin [bool]"
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
            "there from the anchor and from the robot clear of the model's walls): the "
            "junction the robot was heading into; and beyond the back leg, within the straight "
            "path the robot came along: the junction it has just left; the model's reach "
            "(about 2 m past the anchor along a hallway, where its walls end) limits it in "
            "practice. Such an origin is "
            "probed (driven to, looked around from, checked, its look added to the model) "
            "before it is kept. 0 = off: islands may then stay 1-1.5 m short of a junction's "
            "mouth, where only the hallway's walls are in view within 3 m [m]"
        },
    )
    peak_behind: bool = field(
        default=False,
        metadata={
            "help": "with peak_ahead_m > 0, also search beyond the back leg, within the "
            "straight path the hall follower reported driving up to the anchor (free space): "
            "an attempt that starts 2-3 m past a junction the robot has just left [bool]"
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
            "help": "the gain that moves the origin ahead along the driven ahead leg (the "
            "arrival heading, seen close by the star: the move adds only a Go to the edge and "
            "no probe). The default is peak_min_gain's: live paper_fig4 with 0.02 put 1 of 123 "
            "islands in plain hallways on twelve seeds (5 of 120 with 0.1), but routes were "
            "224/240 against 237/240 (seeds 9 and 10: 11/20 and 16/20 against 19/20 and 20/20, "
            "a false recognition and a weakly localizable island; reproduced by a rerun) [-]"
        },
    )
    origin_feature_radius_m: float = field(
        default=3.0,
        metadata={
            "help": "when the origin the peak search chose sees, in the island's own model, "
            "only parallel walls within this distance (a plain hallway: nothing fixes the "
            "position along it), move it to the best point along the driven legs that sees "
            "walls in two directions and still passes the acceptance bound; failing that, "
            "probe the best such point past the legs (ahead, or back along the straight path "
            "the robot came by, as peak_behind would: an attempt started 1-3 m past a "
            "junction); after a probe whose look's model still shows a plain hallway at the probed "
            "origin, climb once on to the peak further on (as probe_climbs 1 would). The same "
            "rule as the evaluation's placement check, on the sonar model instead of the "
            "world. 0 = off [m]"
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
            "+- this, as navigation's localization does (navigation.search_heading_deg) [deg]"
        },
    )
    probe_agree_deg: float = field(
        default=4.0,
        metadata={
            "help": "and all its fits must agree in heading within this (an origin moved 1.6 m "
            "on to the end of a corridor passed the position test, then arrivals there "
            "localized 10-14 deg off in 5 of 20 routes) [deg]"
        },
    )
    probe_climbs: int = field(
        default=0,
        metadata={
            "help": "after a probe passes, search on from there with the model its look "
            "completed (the star saw a junction's near side only) and probe again at most this "
            "many times while the peak moves on. 0 = off, the default: live paper_fig4 with 1 "
            "put 0 of 59 islands in plain hallways on six seeds, but on six more one climb "
            "went on 0.8 m to a door whose model then had an 11.8 deg heading error (routes "
            "10/20; 104/120 on those seeds against 116/120 with 0) [-]"
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
        for name in ("e_min_m", "threshold_line", "threshold_fisher", "quick_history_m",
                     "peak_step_m", "register_sigma_deg"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise BuilderError(f"BuilderConfig.{name}: expected a finite number > 0, got {v!r}")
        for name in (
            "bound_floor",
            "quick_reject_fraction",
            "retry_distance_m",
            "vicinity_m",
            "settled_go_m",
            "dismiss_fraction",
            "first_island_min_measure",
            "peak_min_gain",
            "peak_ahead_min_gain",
            "peak_ahead_m",
            "origin_feature_radius_m",
            "probe_turn_deg",
            "probe_agree_deg",
        ):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise BuilderError(
                    f"BuilderConfig.{name}: expected a finite number >= 0, got {v!r}"
                )
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
            prev = self._prev_pose
            dth = wrap_angle(pose.theta - prev.theta)
            ds = math.hypot(pose.x - prev.x, pose.y - prev.y)
            # Signed travel along the mid heading (reversing gives ds < 0).
            mid = prev.theta + 0.5 * dth
            if (pose.x - prev.x) * math.cos(mid) + (pose.y - prev.y) * math.sin(mid) < 0:
                ds = -ds
            f = np.array(
                [[1.0, 0.0, -ds * math.sin(mid)], [0.0, 1.0, ds * math.cos(mid)], [0.0, 0.0, 1.0]]
            )
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


# ---------------------------------------------------------------------------------------------
# Measuring a point cloud: fit a line model, evaluate every model type at a point.


FitFn = Callable[[FloatArray], LineModel]
EvaluateFn = Callable[[FloatArray, FloatArray], Mapping[ModelType, float]]


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


# ---------------------------------------------------------------------------------------------
# Commands and events.


class CommandMode(StrEnum):
    FOLLOW = "follow"  # the hall follower drives
    DRIVE = "drive"  # the builder drives: publish (v, w)


class DismissReason(StrEnum):
    MEASURE = "measure"  # max_i(R_i/T_i) did not reach the eq. 3 bound
    LOCALIZATION_CHECK = "localization_check"  # the origin's own data did not localize


class EventKind(StrEnum):
    ATTEMPT_STARTED = "attempt_started"
    ATTEMPT_FAILED_AT_ONCE = "attempt_failed_at_once"
    ISLAND_ACCEPTED = "island_accepted"
    ATTEMPT_DISMISSED = "attempt_dismissed"
    HANDED_BACK = "handed_back"  # the robot is back at the origin facing theta 0
    ISLAND_REVISITED = "island_revisited"  # a known island recognised: no new island


@dataclass(frozen=True)
class BuilderEvent:
    """Something the builder decided.

    anchor_odom: the attempt pose in the odometry frame; legs_m: the legs driven so far as
    (bearing in the origin frame [rad], length [m]); measure: the best normalized measure
    max_i(R_i/T_i) so far; bound: E_min/epsilon at the attempt; partial: a dismissed star that
    did not do all four legs. island_revisited: revisited_island_id, island_pose (the robot in
    that island's frame when recognised [m, rad]), residual_m (RMS of the fit [m]) and, when it
    was added or made cheaper, the edge from the previous island.
    """

    kind: EventKind
    t_s: float
    odom_pose: Pose2D
    epsilon_m: float
    anchor_odom: Pose2D | None = None
    measure: float = 0.0
    bound: float = 0.0
    legs_m: tuple[tuple[float, float], ...] = ()
    partial: bool = False
    island: Island | None = None
    edge: Edge | None = None
    accepted_island_id: int | None = None
    reason: DismissReason | None = None
    revisited_island_id: int | None = None
    island_pose: Pose2D | None = None
    residual_m: float | None = None


@dataclass(frozen=True)
class BuilderCommand:
    """What to do now: FOLLOW, or DRIVE with v [m/s] and w [rad/s]; events since the last call."""

    mode: CommandMode
    v_mps: float = 0.0
    w_radps: float = 0.0
    events: tuple[BuilderEvent, ...] = ()


class _State(StrEnum):
    WAITING = "waiting"  # no odometry/scan yet
    FOLLOWING = "following"
    STAR = "star"
    RETURNING = "returning"  # back to the origin, facing theta 0, then hand back
    DOCKING = "docking"  # onto a recognised island's origin, then hand back
    PROBING = "probing"  # to an origin past the star's legs: look around there, verify it


class _LegPhase(StrEnum):
    TURN = "turn"  # rotate to the leg's bearing
    OUT = "out"  # drive forward to the corner
    BACK = "back"  # reverse to the centre


# Leg bearings in the origin frame: ahead, left, behind, right [rad].
_LEG_BEARINGS_RAD = (0.0, 0.5 * math.pi, math.pi, -0.5 * math.pi)


class _DockPhase(StrEnum):
    GO = "go"  # drive to the (estimated) origin
    ALIGN = "align"  # turn to the origin's heading
    LOOK = "look"  # turn a full circle collecting scans, then localize


@dataclass
class _Look:
    """Go onto an origin, align with it, turn a full circle collecting scans (dock, probe)."""

    phase: _DockPhase = field(default=_DockPhase.GO, kw_only=True)
    turned_rad: float = field(default=0.0, kw_only=True)
    prev_theta: float = field(default=0.0, kw_only=True)
    points: list[FloatArray] = field(default_factory=list, kw_only=True)  # odometry frame [m]


@dataclass
class _Dock(_Look):
    island: Island
    target: Pose2D  # the island origin in the odometry frame (estimated) [m, rad]
    looks_left: int


@dataclass
class _Probe(_Look):
    """An origin past the driven legs, checked on the spot before the island is accepted."""

    model: LineModel  # the star's model in the anchor frame [m]
    shift: Pose2D  # the candidate origin in the anchor frame
    measure: float  # its normalized measure
    fallback: Pose2D  # the best origin along the driven legs, if the check fails
    fallback_measure: float
    fallback_model: LineModel | None = None  # the model kept with the fallback (None: model)
    climbs: int = 0  # probes passed before this one


@dataclass(frozen=True)
class Recognition:
    """A known island found in the recent scan points: the robot's pose in its frame."""

    island_id: int
    pose: Pose2D  # the robot in the island frame [m, rad]
    residual_m: float
    inlier_fraction: float


@dataclass
class _Attempt:
    anchor: Pose2D  # odometry pose of the island origin
    anchor_truth: Pose2D | None
    anchor_cov: FloatArray
    epsilon_m: float
    bound: float
    first: bool
    points: list[FloatArray] = field(default_factory=list)  # in the origin frame [m]
    centre_points: list[FloatArray] = field(default_factory=list)  # seen from the origin [m]
    # Echoes within revisit.max_range_m, in the origin frame, for recognising a known island [m]
    near_points: list[FloatArray] = field(default_factory=list)
    leg: int = 0
    phase: _LegPhase = _LegPhase.TURN
    leg_length_m: float = 0.0
    legs_done: list[tuple[float, float]] = field(default_factory=list)
    # Where the current leg's scans begin in points, centre_points and near_points.
    leg_marks: tuple[int, ...] = (0, 0, 0)
    # Heading variance of the pose in the anchor frame after the last leg registration, and
    # odometry's relative heading variance then [rad^2].
    heading_var_rad2: float = 0.0
    odom_var_seen_rad2: float = 0.0
    ahead_free_m: float = 0.0  # nearest echo ahead of the anchor when the attempt started [m]
    behind_free_m: float = 0.0  # straight path the follower drove up to the anchor [m]
    probe: _Probe | None = None
    best: float = 0.0
    best_type: ModelType = ModelType.LINE
    model: LineModel | None = None
    outcome: EventKind | None = None  # set when accepted or dismissed

    def point_lists(self) -> tuple[list[FloatArray], list[FloatArray], list[FloatArray]]:
        """points, centre_points, near_points: the scans kept in the anchor frame (the order
        of leg_marks)."""
        return self.points, self.centre_points, self.near_points


class IslandBuilder:
    """The island builder state machine (see the module docstring).

    Call `on_odometry` for every odometry message, `on_scan` for every scan, `set_strategy`
    whenever the hall follower publishes its executed strategy, `on_ground_truth` (evaluation
    only: stamped on islands as origin_truth), and `command(t)` once per scan.
    """

    def __init__(
        self,
        config: BuilderConfig | None = None,
        fit: FitFn | None = None,
        evaluate: EvaluateFn | None = None,
    ) -> None:
        self.config = config if config is not None else BuilderConfig()
        if fit is None or evaluate is None:
            core = CoreMeasures(self.config)
            fit = fit if fit is not None else core.fit
            evaluate = evaluate if evaluate is not None else core.evaluate
        self._fit = fit
        self._evaluate = evaluate
        radius = self.config.origin_feature_radius_m
        self._placement = PlacementConfig(radius_m=radius) if radius > 0.0 else None
        self._state = _State.WAITING
        self._odom: Pose2D | None = None
        self._cov = np.zeros((3, 3))
        self._rel = RelativeCovariance()  # error since the last island origin
        self._star_rel: RelativeCovariance | None = None  # error since the attempt's anchor
        self._truth: Pose2D | None = None
        self._last_scan: tuple[FloatArray, FloatArray] | None = None
        self._path_m = 0.0  # odometric path length while following [m]
        self._recent: deque[tuple[float, FloatArray]] = deque()  # (path_m, points in odom frame)
        self._revisit_recent: deque[tuple[float, FloatArray]] = deque()  # same, longer
        # Where each island's origin was last known in the odometry frame, and the odometry
        # covariance then (the search for revisits grows with the drift since).
        self._known: dict[int, tuple[Pose2D, FloatArray]] = {}
        self._dock: _Dock | None = None
        # Odometric pose of island b's origin in island a's frame, measured on an edge a -> b
        # (one stretch of odometry), with its position and heading sigmas [m, rad].
        self._links: dict[tuple[int, int], tuple[Pose2D, float, float]] = {}
        self._last_island: Island | None = None
        self._island_path_start_m = 0.0  # path length when the last island was handed back
        self._retry_at_path_m = 0.0
        self._defer_prev: float | None = None  # quick measure at the last deferral
        self._defer_m = 0.0  # path followed while deferring [m]
        self._defer_t_s = 0.0  # time of the last deferral [s]
        self._strategy = ControlStrategy(())
        self._attempt: _Attempt | None = None
        self._events: list[BuilderEvent] = []
        self._t = 0.0
        self.islands: list[Island] = []
        self.edges: list[Edge] = []
        self.island_origins_odom: dict[int, Pose2D] = {}
        self.counts: dict[EventKind, int] = {k: 0 for k in EventKind}
        # Why refined revisit hypotheses were refused (diagnostics): reason -> count.
        self.revisit_refusals: dict[str, int] = {}
        # Origins past the star's legs: checked on the spot and kept, or fallen back from.
        self.probes: dict[str, int] = {"kept": 0, "fell_back": 0}

    # ----- inputs -----

    def on_odometry(self, t_s: float, odom_pose: Pose2D, cov3x3: npt.ArrayLike) -> None:
        """Latest odometry pose and its 3x3 covariance (x, y, theta) [m, rad]."""
        cov = np.asarray(cov3x3, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise BuilderError(
                f"on_odometry: covariance must be a finite 3x3 matrix, got shape {cov.shape}"
            )
        if not math.isfinite(t_s):
            raise BuilderError(f"on_odometry: time must be finite, got {t_s}")
        if self._odom is not None and self._state is _State.FOLLOWING:
            self._path_m += math.hypot(odom_pose.x - self._odom.x, odom_pose.y - self._odom.y)
        self._odom = odom_pose
        self._cov = cov
        self._rel.update(odom_pose, cov)
        if self._star_rel is not None:
            self._star_rel.update(odom_pose, cov)
        self._t = max(self._t, t_s)

    def on_ground_truth(self, pose: Pose2D) -> None:
        """The simulator's true pose, stored on islands as origin_truth for evaluation only."""
        self._truth = pose

    def set_strategy(self, strategy: ControlStrategy) -> None:
        """The hall follower's strategy executed since its last reset (at the last island)."""
        self._strategy = strategy

    def on_scan(self, t_s: float, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike) -> None:
        """A sonar scan: ranges from the robot centre [m] (inf = no echo) at robot-frame angles."""
        r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
        a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
        if r.shape != a.shape:
            raise BuilderError(f"on_scan: {r.shape[0]} ranges but {a.shape[0]} angles")
        if not math.isfinite(t_s):
            raise BuilderError(f"on_scan: time must be finite, got {t_s}")
        self._t = max(self._t, t_s)
        self._last_scan = (r, a)
        if self._odom is None:
            return
        pts = _scan_points(r, a, self._odom)
        near = r <= self.config.revisit.max_range_m  # far sonar echoes are wide cones
        near_pts = _scan_points(r[near], a[near], self._odom)  # for recognising known islands
        if self._state is _State.STAR and self._attempt is not None:
            att = self._attempt
            local = _to_frame(pts, att.anchor)
            att.points.append(local)
            rel = self._odom.relative_to(att.anchor)
            if math.hypot(rel.x, rel.y) <= self.config.centre_radius_m:
                att.centre_points.append(local)
            att.near_points.append(_to_frame(near_pts, att.anchor))
        look = self._look()
        if look is not None:
            if look.phase is _DockPhase.LOOK:
                look.points.append(pts)
            return
        self._recent.append((self._path_m, pts))
        while self._recent and self._recent[0][0] < self._path_m - self.config.quick_history_m:
            self._recent.popleft()
        if self._state is _State.FOLLOWING:
            hist = self._revisit_recent
            hist.append((self._path_m, near_pts))
            while hist and hist[0][0] < self._path_m - self.config.revisit.history_m:
                hist.popleft()

    # ----- queries -----

    @property
    def state(self) -> str:
        return self._state.value

    @property
    def epsilon_m(self) -> float:
        """The current epsilon [m] (see `RelativeCovariance`)."""
        return self._rel.epsilon_m

    @property
    def last_island(self) -> Island | None:
        return self._last_island

    # ----- the decision step -----

    def command(self, t_s: float) -> BuilderCommand:
        """What to do now (call once per scan) and the events since the last call."""
        self._t = max(self._t, t_s)
        v, w = 0.0, 0.0
        if self._state is _State.WAITING:
            if self._odom is not None and self._last_scan is not None:
                if self.config.build_first_island:
                    self._start_attempt(first=True)
                else:
                    self._rel.reset()
                    self._state = _State.FOLLOWING
        if self._state is _State.FOLLOWING:
            self._maybe_attempt()
        if self._state is _State.STAR:
            v, w = self._star_step()
        if self._state is _State.PROBING:
            v, w = self._probe_step()
        if self._state is _State.RETURNING:
            v, w = self._return_step()
        if self._state is _State.DOCKING:
            v, w = self._dock_step()
        mode = (
            CommandMode.DRIVE
            if self._state in (_State.STAR, _State.RETURNING, _State.DOCKING)
            else (CommandMode.FOLLOW if self._state is _State.FOLLOWING else CommandMode.DRIVE)
        )
        events, self._events = tuple(self._events), []
        return BuilderCommand(mode, v, w, events)

    # ----- internals -----

    def _emit(self, kind: EventKind, epsilon_m: float | None = None, **kw: object) -> None:
        assert self._odom is not None
        self.counts[kind] += 1
        eps = self.epsilon_m if epsilon_m is None else epsilon_m
        self._events.append(
            BuilderEvent(kind, self._t, self._odom, eps, **kw)  # type: ignore[arg-type]
        )

    def _measure(self, points: FloatArray, at: FloatArray) -> tuple[ModelType, float, LineModel]:
        if points.shape[0] < 2:
            return ModelType.LINE, 0.0, LineModel()
        model = self._fit(points)
        if len(model) == 0:
            return ModelType.LINE, 0.0, model
        t, best = normalized_measures(self.config, self._evaluate(model.segments, at))
        return t, best, model

    def _follower_settled(self) -> bool:
        """True unless the hall follower is turning or has not yet gone `settled_go_m` straight
        since its last turn (from the strategy it reports; an empty record counts as settled)."""
        steps = self._strategy.steps
        if not steps or self.config.settled_go_m <= 0:
            return True
        if self._follower_turning():
            return False
        last = steps[-1]
        turned_before = any(s.kind is PrimitiveKind.ROT for s in steps[:-1])
        return not turned_before or last.metres >= self.config.settled_go_m

    def _follower_turning(self) -> bool:
        """Is the hall follower's latest primitive a turn (it records turns as they go on)?"""
        steps = self._strategy.steps
        return bool(steps) and steps[-1].kind is PrimitiveKind.ROT

    def _maybe_attempt(self) -> None:
        eps = self.epsilon_m
        if eps <= self.config.e_min_m:
            return
        stalled = (
            self._defer_prev is not None and self._t - self._defer_t_s > self.config.defer_timeout_s
        )
        if stalled and self._follower_turning():
            return  # anchored mid-turn, theta 0 would lie across the hallway: wait for its end
        if stalled:  # deferring, but the robot stopped moving on: attempt here
            self._defer_prev, self._defer_m = None, 0.0
            if not self._try_revisit():
                self._start_attempt(first=False)
            return
        if self._path_m < self._retry_at_path_m or not self._follower_settled():
            return
        if self._in_last_island_vicinity():
            return
        assert self._odom is not None
        bound = eq3_bound(self.config, eps)
        pts = (
            np.concatenate([p for _, p in self._recent], axis=0)
            if self._recent
            else np.zeros((0, 2))
        )
        _, quick, _ = self._measure(pts, np.array([self._odom.x, self._odom.y]))
        cfg = self.config
        if quick < cfg.quick_reject_fraction * bound:
            self._defer_prev, self._defer_m = None, 0.0
            self._retry_at_path_m = self._path_m + cfg.retry_distance_m
            self._emit(
                EventKind.ATTEMPT_FAILED_AT_ONCE,
                anchor_odom=self._odom,
                measure=quick,
                bound=bound,
            )
            return
        if self._try_revisit():  # a place worth an island: is it one the robot already has?
            self._defer_prev, self._defer_m = None, 0.0
            return
        rising = self._defer_prev is None or quick > self._defer_prev * (
            1.0 + cfg.defer_rise_fraction
        )
        if cfg.defer_while_rising and rising and self._defer_m < cfg.defer_max_m:
            # The place is getting better as the robot goes on: anchor further ahead.
            self._defer_prev = quick
            self._defer_t_s = self._t
            self._defer_m += cfg.defer_step_m
            self._retry_at_path_m = self._path_m + cfg.defer_step_m
            return
        self._defer_prev, self._defer_m = None, 0.0
        self._start_attempt(first=False)

    def _in_last_island_vicinity(self) -> bool:
        """Is the robot within vicinity_m of the last island's origin (odometry)?"""
        last = self._last_island
        if last is None or last.id not in self._known or self._odom is None:
            return False
        origin = self._known[last.id][0]
        dist = math.hypot(self._odom.x - origin.x, self._odom.y - origin.y)
        return dist < self.config.vicinity_m

    def _start_attempt(self, first: bool) -> None:
        assert self._odom is not None and self._last_scan is not None
        eps = self.epsilon_m
        bound = eq3_bound(self.config, eps) if not first else self.config.first_island_min_measure
        self._attempt = _Attempt(
            anchor=self._odom,
            anchor_truth=self._truth,
            anchor_cov=self._cov.copy(),
            epsilon_m=eps,
            bound=bound,
            first=first,
        )
        self._attempt.ahead_free_m = self._ahead_free_m()
        steps = self._strategy.steps
        if steps and steps[-1].kind is PrimitiveKind.GO:
            self._attempt.behind_free_m = steps[-1].metres
        first_pts = _to_frame(_scan_points(*self._last_scan, self._odom), self._odom)
        self._attempt.points.append(first_pts)
        self._attempt.centre_points.append(first_pts)
        self._star_rel = RelativeCovariance()
        self._star_rel.update(self._odom, self._cov)
        self._state = _State.STAR
        self._emit(EventKind.ATTEMPT_STARTED, anchor_odom=self._odom, bound=bound)

    def _pose_in_anchor(self) -> Pose2D:
        assert self._odom is not None and self._attempt is not None
        return self._odom.relative_to(self._attempt.anchor)

    def _ahead_free_m(self) -> float:
        """Nearest echo within the ahead cone of the latest scan (from the robot centre) [m]."""
        if self._last_scan is None:
            return 0.0
        r, a = self._last_scan
        half = math.radians(self.config.star.ahead_halfwidth_deg)
        wrapped = np.arctan2(np.sin(a), np.cos(a))
        sel = np.abs(wrapped) <= half
        vals = r[sel & np.isfinite(r)]
        return float(vals.min()) if vals.size else math.inf

    def _turn_to(self, heading_rad: float) -> tuple[float, float] | None:
        """(0, w) toward the heading in the origin frame, or None when already there."""
        sc = self.config.star
        err = wrap_angle(heading_rad - self._pose_in_anchor().theta)
        if abs(err) <= math.radians(sc.heading_tol_deg):
            return None
        w = float(np.clip(sc.heading_gain_per_s * err, -sc.turn_rate_radps, sc.turn_rate_radps))
        return 0.0, w

    def _star_step(self) -> tuple[float, float]:
        att = self._attempt
        assert att is not None
        sc = self.config.star
        while att.leg < len(_LEG_BEARINGS_RAD):
            bearing = _LEG_BEARINGS_RAD[att.leg]
            if att.phase is _LegPhase.TURN:
                cmd = self._turn_to(bearing)
                if cmd is not None:
                    return cmd
                free = self._ahead_free_m() - sc.clearance_m
                att.leg_length_m = min(sc.leg_length_m, free)
                if att.leg_length_m < sc.min_leg_m:
                    att.leg += 1  # this corner is not reachable: skip it
                    continue
                att.phase = _LegPhase.OUT
            pose = self._pose_in_anchor()
            u = np.array([math.cos(bearing), math.sin(bearing)])
            along = float(u @ np.array([pose.x, pose.y]))
            lateral = float(np.array([-u[1], u[0]]) @ np.array([pose.x, pose.y]))
            if att.phase is _LegPhase.OUT:
                remaining = att.leg_length_m - along
                blocked = self._ahead_free_m() < sc.clearance_m
                if remaining > sc.position_tol_m and not blocked:
                    return self._drive_line(bearing, lateral, min(sc.speed_mps, remaining * 2.0))
                att.legs_done.append((bearing, max(along, 0.0)))
                att.phase = _LegPhase.BACK
                if self.config.register_legs:
                    self._register_leg(att)
                if self._evaluate_attempt():
                    return 0.0, 0.0
            if att.phase is _LegPhase.BACK:
                if along > sc.position_tol_m:
                    return self._drive_line(bearing, lateral, -min(sc.speed_mps, along * 2.0))
                att.leg += 1
                att.phase = _LegPhase.TURN
                att.leg_marks = tuple(len(lst) for lst in att.point_lists())
        # All legs done without a decision.
        if att.first or att.best > att.bound:
            self._accept()
        else:
            self._dismiss(partial=False)
        return 0.0, 0.0

    def _drive_line(self, bearing: float, lateral_m: float, v: float) -> tuple[float, float]:
        """Drive along the leg's line through the origin (forward or reversing), holding heading."""
        sc = self.config.star
        heading_err = wrap_angle(bearing - self._pose_in_anchor().theta)
        if abs(heading_err) > math.radians(sc.drive_heading_err_deg):
            return 0.0, self._turn_rate(heading_err)
        # Steer back onto the line: a lateral offset to the left calls for a right turn going
        # forward and a left turn reversing.
        steer = heading_err - math.copysign(1.0, v) * 1.5 * lateral_m
        w = float(np.clip(sc.heading_gain_per_s * steer, -sc.turn_rate_radps, sc.turn_rate_radps))
        return v, w

    def _register_leg(self, att: _Attempt) -> None:
        """Register the current leg's echoes (since the turn that began it) onto the model of
        the earlier legs, and turn them, and the anchor (so the robot's pose in it too), by the
        heading found times the gain var / (var + register_sigma^2), var the heading variance
        odometry added since the last registration plus what that one left. Only the heading:
        a partial view constrains a hallway's position along it poorly. Nothing when this is
        the first leg driven or the fit is refused."""
        i = att.leg_marks[0]
        if i == 0 or i == len(att.points) or self._star_rel is None:
            return
        model = self._fit(np.concatenate(att.points[:i], axis=0))
        if len(model) == 0:
            return
        odom_var = float(self._star_rel.p[2, 2])
        var = att.heading_var_rad2 + max(odom_var - att.odom_var_seen_rad2, 0.0)
        sigma2 = math.radians(self.config.register_sigma_deg) ** 2
        found = self._leg_heading(model, np.concatenate(att.points[i:], axis=0),
                                  REGISTER_GATE_SIGMAS * math.sqrt(var + sigma2))
        if found is None:
            return
        gain = var / (var + sigma2)
        att.heading_var_rad2, att.odom_var_seen_rad2 = (1.0 - gain) * var, odom_var
        fix = Pose2D(0.0, 0.0, gain * found)
        for lst, mark in zip(att.point_lists(), att.leg_marks, strict=True):
            lst[mark:] = [_from_frame(p, fix) for p in lst[mark:]]
        att.anchor = att.anchor.compose(fix.inverse())

    def _evaluate_attempt(self) -> bool:
        """Fit and evaluate after a leg; returns True when the attempt was decided."""
        att = self._attempt
        assert att is not None
        pts = np.concatenate(att.points, axis=0) if att.points else np.zeros((0, 2))
        t, best, model = self._measure(pts, np.zeros(2))
        if best >= att.best:
            att.best, att.best_type, att.model = best, t, model
        if att.first:
            return False  # island 0: always the full star
        if att.best > att.bound:
            if self.config.complete_star:
                return False  # acceptable: finish the star for a complete model
            self._accept()
            return True
        if len(att.legs_done) >= self.config.dismiss_min_legs and (
            att.best < self.config.dismiss_fraction * att.bound
        ):
            self._dismiss(partial=True)
            return True
        return False

    def _accept(self) -> None:
        att = self._attempt
        assert att is not None
        if att.first and att.best <= self.config.first_island_min_measure and att.bound > 0:
            self._dismiss(partial=False)
            return
        if not att.first:
            rec = self._recognize_star()
            if rec is not None:  # the star is at a known island: a revisit, not a new one
                assert self._odom is not None
                att.outcome = EventKind.ISLAND_REVISITED
                self._attempt, self._star_rel = None, None
                end = rec.pose.compose(self._odom.relative_to(att.anchor).inverse())
                self._revisit(rec, legs_m=tuple(att.legs_done), strategy_end=end)
                return
        pts = np.concatenate(att.points, axis=0) if att.points else np.zeros((0, 2))
        model = self._fit(pts) if pts.shape[0] >= 2 else LineModel()
        if self.config.verify_localization and not att.first and not self._verify(model):
            self._dismiss(partial=False, reason=DismissReason.LOCALIZATION_CHECK)
            return
        shift, r_peak = Pose2D(0.0, 0.0, 0.0), att.best  # the origin in the anchor's frame
        if self.config.origin_at_peak and not att.first and len(model) > 0:
            (shift, r_peak), (far, r_far) = self._peak_origin(model, att)
            if far != shift:  # past the driven legs: nothing was seen from there yet
                att.probe = _Probe(model, far, r_far, shift, r_peak)
                self._state = _State.PROBING
                return
        self._accept_at(model, shift, r_peak)

    def _accept_at(self, model: LineModel, shift: Pose2D, r_peak: float) -> None:
        """Accept the attempt's island with its origin at `shift` in the anchor frame, where
        its model's normalized measure is r_peak."""
        att = self._attempt
        assert att is not None
        drive: tuple[StrategyPrimitive, ...] = ()
        if shift.x != 0.0 or shift.y != 0.0:
            model = LineModel(model.segments - np.array([shift.x, shift.y] * 2))
            att.best = max(att.best, r_peak)
            drive = _drive_onto_origin(Pose2D(-shift.x, -shift.y, 0.0), min_go_m=0.0)
        origin = att.anchor.compose(shift)
        island = Island(
            id=len(self.islands),
            model=model,
            model_type=att.best_type,
            r=float(att.best),
            built_at_s=self._t,
            origin_truth=None if att.anchor_truth is None else att.anchor_truth.compose(shift),
        )
        edge = None
        if self._last_island is not None:
            length = max(self._path_m - self._island_path_start_m, 0.0) + math.hypot(
                shift.x, shift.y)
            edge = Edge(
                source=self._last_island.id,
                target=island.id,
                strategy=normalize_strategy(ControlStrategy(self._strategy.steps + drive)),
                weight=length + att.epsilon_m,
                length_m=length,
                expected_error_m=att.epsilon_m,
            )
            self.edges.append(edge)
        self.islands.append(island)
        self.island_origins_odom[island.id] = origin
        if self._last_island is not None and self._last_island.id in self._known:
            self._link(self._last_island.id, island.id, origin, att.epsilon_m)
        self._known[island.id] = (origin, att.anchor_cov)
        self._last_island = island
        if self._star_rel is not None:  # epsilon restarts from the island origin
            self._rel.p = self._star_rel.p.copy()
        att.outcome = EventKind.ISLAND_ACCEPTED
        att.anchor = origin  # the robot returns to the island origin before it is handed back
        self._emit(
            EventKind.ISLAND_ACCEPTED,
            epsilon_m=att.epsilon_m,
            anchor_odom=origin,
            measure=att.best,
            bound=att.bound,
            legs_m=tuple(att.legs_done),
            island=island,
            edge=edge,
        )
        self._state = _State.RETURNING

    def _peak_origin(
        self, model: LineModel, att: _Attempt
    ) -> tuple[tuple[Pose2D, float], tuple[Pose2D, float]]:
        """Where the model's normalized measure peaks (the origin in the anchor frame, its
        measure): along the driven star legs, and also past the ahead leg (and, with
        peak_behind, past the back leg along the straight path that led to the anchor) up to
        peak_ahead_m; each the anchor itself unless its peak beats it by peak_min_gain
        (peak_ahead_min_gain along the driven ahead leg). Where the model shows a plain
        hallway at the origin so chosen, the best driven point it shows at a junction (passing
        the attempt's bound) is the origin instead; failing that, the best such point past the
        legs (also past the back leg) is probed."""
        cfg = self.config
        anchor = (Pose2D(0.0, 0.0, 0.0), self._measure_at(model, np.zeros(2)))
        legs, far = anchor, anchor
        driven, past = [anchor], []  # candidates along the legs, and past them
        for bearing, length in att.legs_done:
            gain = cfg.peak_ahead_min_gain if bearing == 0.0 else cfg.peak_min_gain
            leg_floor = anchor[1] * (1.0 + gain)
            reach, behind = length, bearing == math.pi
            if bearing == 0.0:
                reach = max(length, min(cfg.peak_ahead_m, att.ahead_free_m - cfg.star.clearance_m))
            elif behind and (cfg.peak_behind or cfg.origin_feature_radius_m > 0.0):
                reach = max(length, min(cfg.peak_ahead_m, att.behind_free_m))  # came along it
            u = np.array([math.cos(bearing), math.sin(bearing)])
            for d, p, r in self._along(model, np.zeros(2), u, reach, length):
                if d <= length:
                    driven.append((p, r))
                    if r > leg_floor and r > legs[1]:
                        legs = (p, r)
                    continue
                past.append((p, r))
                if r > far[1] and (cfg.peak_behind or not behind):
                    far = (p, r)
        if self._plain_hallway(model, legs[0]):
            on_legs = self._best_junction(model, driven, att.bound)
            if on_legs is not None:
                legs = on_legs
            else:
                beyond = self._best_junction(model, past, att.bound)
                if beyond is not None:
                    return legs, beyond
        # The peak past the driven legs is probed only where it beats both the anchor by
        # peak_min_gain and the legs' choice; otherwise the legs' choice is the origin.
        floor = anchor[1] * (1.0 + cfg.peak_min_gain)
        return legs, (far if far[1] > floor and far[1] > legs[1] else legs)

    def _best_junction(
        self, model: LineModel, candidates: list[tuple[Pose2D, float]], bound: float
    ) -> tuple[Pose2D, float] | None:
        """The best of `candidates` (origin, measure) whose measure passes `bound` and where
        `model` does not show a plain hallway; None if there is none."""
        ok = [c for c in candidates if c[1] > bound and not self._plain_hallway(model, c[0])]
        return max(ok, key=lambda c: c[1]) if ok else None

    def _plain_hallway(self, model: LineModel, p: Pose2D) -> bool:
        """Does `model` show a plain hallway at p (anchor frame): only parallel walls within
        origin_feature_radius_m? Never with the radius 0 (the check off)."""
        return self._placement is not None and classify_place(
            model.segments, p.x, p.y, self._placement
        ) is PlaceKind.PLAIN_HALLWAY

    def _along(
        self, model: LineModel, start: FloatArray, u: FloatArray, reach_m: float, free_m: float
    ) -> Iterator[tuple[float, Pose2D, float]]:
        """(d, the point start + d u, the model's measure there) every peak_step_m up to
        reach_m, in the anchor frame; beyond free_m (driven, known free) only while the point
        is _reachable, stopping at the first that is not."""
        step = self.config.peak_step_m
        for d in np.arange(step, reach_m + 1e-9, step):
            p = start + float(d) * u
            if d > free_m and not self._reachable(model.segments, p):
                return
            yield float(d), Pose2D(float(p[0]), float(p[1]), 0.0), self._measure_at(model, p)

    def _reachable(self, segs: FloatArray, p: FloatArray) -> bool:
        """Are the straight drives anchor -> p and robot -> p clear of the model's walls?"""
        here = self._pose_in_anchor()
        return all(
            self._drive_clear(segs, a, p) for a in (np.zeros(2), np.array([here.x, here.y]))
        )

    def _probe_step(self) -> tuple[float, float]:
        """Drive to the origin past the legs, face the anchor's heading, look around (a full
        circle), then accept the island there if the look localizes in the model from offset
        guesses (the new-island check), else at the best origin along the driven legs."""
        att = self._attempt
        assert att is not None and att.probe is not None and self._odom is not None
        pr, sc = att.probe, self.config.star
        target = att.anchor.compose(pr.shift)  # the candidate origin, odometry frame
        rel = self._odom.relative_to(target)
        cmd = self._go_align(pr, rel, math.radians(sc.heading_tol_deg))
        if cmd is not None:
            return cmd
        if pr.phase is _DockPhase.ALIGN:
            self._start_look(pr)
        cmd = self._look_step(pr)
        if cmd is not None:
            return cmd
        pts = np.concatenate(pr.points, axis=0) if pr.points else np.zeros((0, 2))
        # The island's model gains what the look saw from the candidate origin itself, where
        # every later arrival localizes (the star's points alone saw its far walls from the
        # anchor, 1-3 m away, through 25 deg cones).
        robot_pts = _to_frame(pts, self._odom)
        at = self._register(pr.model, robot_pts, self._odom.relative_to(att.anchor))
        look = _from_frame(robot_pts, at)
        model = self._fit(np.concatenate([*att.points, look], axis=0))
        shifted = LineModel(model.segments - np.array([pr.shift.x, pr.shift.y] * 2))
        there = math.hypot(rel.x, rel.y) <= self.config.revisit.path_clearance_m
        ok = there and pts.shape[0] >= 3 and self._localizes_back(
            shifted, robot_pts, Pose2D(at.x - pr.shift.x, at.y - pr.shift.y, at.theta),
            math.radians(self.config.probe_turn_deg))
        self.probes["kept" if ok else "fell_back"] += 1
        att.probe = None
        if not ok:
            fallback_model = pr.model if pr.fallback_model is None else pr.fallback_model
            self._accept_at(fallback_model, pr.fallback, pr.fallback_measure)
            return 0.0, 0.0
        att.points.append(look)
        here = self._measure_at(model, np.array([pr.shift.x, pr.shift.y]))
        # One more probe, on from here, when the look's model still shows a plain hallway here
        # (the star's model ended 1-2 m short of a corner or a T) or while climbs are allowed.
        climb = pr.climbs < self.config.probe_climbs or (
            pr.climbs == 0 and self._plain_hallway(model, pr.shift))
        on = self._climb(model, pr.shift, here) if climb else None
        if on is not None:  # the completed model peaks further on: probe there too
            att.probe = _Probe(model, on[0], on[1], pr.shift, here, model, pr.climbs + 1)
            return 0.0, 0.0
        self._accept_at(model, pr.shift, here)
        return 0.0, 0.0

    def _leg_heading(
        self, model: LineModel, points: FloatArray, gate_rad: float
    ) -> float | None:
        """The turn [rad] that registers a leg's `points` (anchor frame, placed by odometry)
        onto the earlier legs' `model`: the fit's heading from the identity when its steps
        settled with enough points matched and the turn is within `gate_rad` (the innovation
        gate); else None. Only the heading is used, so a fit that slid along a hallway (its
        position free along it: degenerate, not converged) still counts; one constrained in
        both axes must stay within verify_offset_m (farther is a wrong match)."""
        cfg = self.config
        res = localize(model, points, Pose2D(0.0, 0.0, 0.0), cfg.localize)
        turned = wrap_angle(res.pose.theta)
        degenerate = res.constraint < cfg.localize.min_constraint
        if not res.settled or res.matched_fraction < cfg.localize.min_matched_fraction or (
            abs(turned) > gate_rad
        ) or (not degenerate and math.hypot(res.pose.x, res.pose.y) > cfg.verify_offset_m):
            return None
        return turned

    def _register(self, model: LineModel, points_robot: FloatArray, guess: Pose2D) -> Pose2D:
        """The robot's pose in `model`'s frame: `points_robot` localized from the odometric
        `guess`. After a star and a drive, odometry has turned a few degrees (each full circle
        adds heading noise), and those degrees would turn the walls the points add to the
        island's model. The guess itself when the fit does not converge or moves more than
        verify_offset_m / probe_turn_deg."""
        res = localize(model, points_robot, guess, self.config.localize)
        moved = math.hypot(res.pose.x - guess.x, res.pose.y - guess.y)
        turned = abs(wrap_angle(res.pose.theta - guess.theta))
        if not res.converged or moved > self.config.verify_offset_m or turned > math.radians(
            self.config.probe_turn_deg
        ):
            return guess
        return res.pose

    def _measure_at(self, model: LineModel, p: FloatArray) -> float:
        """The model's normalized measure at the point p (2,) [m] (anchor frame)."""
        _, r = normalized_measures(self.config, self._evaluate(model.segments, p))
        return r

    def _climb(self, model: LineModel, at: Pose2D, r_at: float) -> tuple[Pose2D, float] | None:
        """The model's peak further on from the anchor through `at` (ahead or back along the
        anchor's heading), up to peak_ahead_m past `at` (drives there clear of its walls), if
        it beats r_at by peak_min_gain; else None."""
        cfg = self.config
        best: tuple[Pose2D, float] | None = None
        u = np.array([1.0 if at.x >= 0.0 else -1.0, 0.0])
        for _, p, r in self._along(model, np.array([at.x, at.y]), u, cfg.peak_ahead_m, 0.0):
            if r > r_at * (1.0 + cfg.peak_min_gain) and (best is None or r > best[1]):
                best = (p, r)
        return best

    def _verify(self, model: LineModel) -> bool:
        """Do the points seen from the origin localize back onto it from offset guesses?"""
        att = self._attempt
        assert att is not None
        pts = np.concatenate(att.centre_points, axis=0) if att.centre_points else np.zeros((0, 2))
        return self._localizes_back(model, pts, Pose2D(0.0, 0.0, 0.0))

    def _localizes_back(
        self, model: LineModel, points_robot: FloatArray, at: Pose2D, turn_rad: float = 0.0
    ) -> bool:
        """The localization check: from `at` and from guesses `verify_offset_m` off it in four
        directions, do the robot-frame points converge within `verify_tol_m` of `at`? With
        turn_rad > 0 the guesses are also turned by +-turn_rad, and the fits' headings must
        agree within probe_agree_deg (a model that fits turned as well passes the position
        test alone)."""
        cfg = self.config
        d = cfg.verify_offset_m
        turns = (0.0, turn_rad, -turn_rad) if turn_rad > 0.0 else (0.0,)
        headings: list[float] = []
        for dth in turns:
            for gx, gy in ((0.0, 0.0), (d, 0.0), (-d, 0.0), (0.0, d), (0.0, -d)):
                guess = Pose2D(at.x + gx, at.y + gy, at.theta + dth)
                res = localize(model, points_robot, guess, cfg.localize)
                if not res.converged or math.hypot(res.pose.x - at.x, res.pose.y - at.y) > (
                    cfg.verify_tol_m
                ):
                    return False
                headings.append(wrap_angle(res.pose.theta - at.theta))
        spread = max(headings) - min(headings)
        return turn_rad <= 0.0 or spread <= math.radians(cfg.probe_agree_deg)

    # ----- revisits -----

    def recognize(self) -> Recognition | None:
        """Search the known islands near the odometric pose for the recent scan points.

        Candidates: islands whose origin, where it was last known in the odometry frame, could
        be within `max_dock_m` of the robot given the search radius (search_sigmas times epsilon
        plus the odometric drift since: sqrt of the largest eigenvalue of the growth of the
        odometry's xy covariance). Per candidate, guesses on a grid around the odometric
        estimate (and headings within search_sigmas heading sigmas, at most search_max_deg) are
        scored by the fraction of points within inlier_m of the model; the best few distinct
        ones are refined by localization. Accepted: converged, RMS residual <= max_residual_m,
        inlier fraction >= min_inlier_fraction, within the search radius of the estimate, the
        origin within max_dock_m over a straight path clear of the model's walls, and the
        new-island localization check from there. The smallest residual wins, unless another
        known island that may be where the robot is (rival_sigmas) fits the points too: then
        the place is a look-alike and nothing is recognised.
        """
        rc = self.config.revisit
        if not rc.enabled or not self._known or self._odom is None or not self._revisit_recent:
            return None
        pts_odom = np.concatenate([p for _, p in self._revisit_recent], axis=0)
        if pts_odom.shape[0] < rc.min_points:
            return None
        pts_odom = thin_evenly(pts_odom, rc.max_points)
        pts = _to_frame(pts_odom, self._odom)
        return self._recognize_points(pts, self._odom, star=False)

    def _recognize_points(self, pts: FloatArray, at: Pose2D, star: bool) -> Recognition | None:
        """The search of `recognize` for robot-frame points `pts` [m] seen from odometric pose
        `at`; the recognition's pose is `at` in the island frame. star=True: the points of a
        star, searched over star_search_sigmas within the star_search_max_m / _deg caps on a
        grid of at least radius / star_search_cells."""
        rc = self.config.revisit
        islands = {i.id: i for i in self.islands}
        best: Recognition | None = None
        candidates = list(self._candidates(islands))
        for _iid, island, origin, sig_m, sig_th in candidates:
            sigmas = rc.star_search_sigmas if star else rc.search_sigmas
            radius = max(sigmas * sig_m, rc.search_min_m)
            max_dth = sigmas * sig_th
            max_m, max_deg = (
                (rc.star_search_max_m, rc.star_search_max_deg)
                if star
                else (rc.search_max_m, rc.search_max_deg)
            )
            step = max(rc.search_step_m, radius / rc.star_search_cells) if star else (
                rc.search_step_m)
            est = at.relative_to(origin)  # the robot in the island frame, by odometry
            if math.hypot(est.x, est.y) > radius + rc.max_dock_m:
                continue
            if radius > max_m or max_dth > math.radians(max_deg):
                # The search could not cover where the island may be: a match inside it
                # could be a look-alike place (doors repeat along corridors; a star that
                # clipped its search to 6 m took the T at (9, 22) for the one at (9, 9)).
                self._refuse("drift_too_large")
                continue
            max_res = rc.star_max_residual_m if star else rc.max_residual_m
            found = self._search_island(island, pts, est, radius, max_dth, step, max_res)
            if found is not None and (best is None or found.residual_m < best.residual_m):
                best = found
        if best is not None and self._rival_fits(candidates, pts, at, best.island_id, star):
            self._refuse("look_alike")
            return None
        return best

    def _candidates(
        self, islands: Mapping[int, Island]
    ) -> Iterator[tuple[int, Island, Pose2D, float, float]]:
        """Known islands a recognition may match, with their best odometric origin estimate
        and its (position [m], heading [rad]) sigmas: not the island just left."""
        rc = self.config.revisit
        last = self._last_island
        just_left = self._path_m - self._island_path_start_m < rc.min_loop_m
        for iid in sorted(self._known):
            island = islands.get(iid)
            if island is None or len(island.model) == 0:
                continue
            if last is not None and iid == last.id and just_left:
                continue
            origin, sig_m, sig_th = min(self._estimates(iid), key=lambda e: e[1])
            yield iid, island, origin, sig_m, sig_th

    def _rival_fits(
        self, candidates: list[tuple[int, Island, Pose2D, float, float]], pts: FloatArray,
        at: Pose2D, chosen: int, star: bool,
    ) -> bool:
        """Does another known island that may be here (rival_sigmas) fit the points too?

        Offline paper_fig4 seed 3: after a loop the odometry was 7.4 m and 26 deg off (2
        sigmas); the one-sigma window around the door island held the south-west corner the
        robot stood at, which fitted it (0.13 m, 83 % inliers), while the corner's own island
        was outside its window. Its wide search finds it."""
        rc = self.config.revisit
        k = rc.rival_sigmas
        if k <= 0:
            return False
        max_res = rc.star_max_residual_m if star else rc.max_residual_m
        for iid, island, origin, sig_m, sig_th in candidates:
            est = at.relative_to(origin)
            if iid == chosen or math.hypot(est.x, est.y) > k * sig_m + rc.max_dock_m:
                continue
            radius = min(max(k * sig_m, rc.search_min_m), rc.rival_max_m)
            max_dth = min(k * sig_th, math.radians(rc.star_search_max_deg))
            step = min(max(rc.search_step_m, radius / rc.star_search_cells), rc.rival_step_m)
            # A rival's failed fits are not refusals of this recognition.
            if self._search_island(island, pts, est, radius, max_dth, step, max_res,
                                   count_refusals=False) is not None:
                return True
        return False

    def _search_island(
        self,
        island: Island,
        pts: FloatArray,
        est: Pose2D,
        radius_m: float,
        max_dth_rad: float,
        step_m: float,
        max_residual_m: float,
        count_refusals: bool = True,
    ) -> Recognition | None:
        """The recognition of `island` in `pts` searched around `est` (see `recognize`), or
        None; each refusal is counted in revisit_refusals unless count_refusals is False."""
        rc = self.config.revisit
        refuse = self._refuse if count_refusals else (lambda _reason: None)
        segs = island.model.segments
        n = math.floor(radius_m / step_m + 1e-9)
        ticks = np.arange(-n, n + 1) * step_m
        gx, gy = np.meshgrid(ticks, ticks)
        inside = np.hypot(gx, gy) <= radius_m + 1e-9
        offs = np.stack([gx[inside], gy[inside]], axis=1)
        heading_step = math.radians(rc.heading_step_deg)
        m = math.floor(max_dth_rad / heading_step + 1e-9)
        dths = np.arange(-m, m + 1) * heading_step
        guesses: list[tuple[float, Pose2D]] = []
        for dth in dths:
            th = est.theta + float(dth)
            c, s_ = math.cos(th), math.sin(th)
            rot = np.stack([c * pts[:, 0] - s_ * pts[:, 1], s_ * pts[:, 0] + c * pts[:, 1]], 1)
            base = rot + np.array([est.x, est.y])
            for chunk in np.array_split(offs, max(1, len(offs) // 40)):
                world = (base[None, :, :] + chunk[:, None, :]).reshape(-1, 2)
                d = point_segment_distance(world, segs).min(axis=1).reshape(len(chunk), -1)
                score = np.mean(d <= rc.inlier_m, axis=1)
                for k in range(len(chunk)):
                    guesses.append(
                        (float(score[k]), Pose2D(est.x + chunk[k, 0], est.y + chunk[k, 1], th))
                    )
        guesses.sort(key=lambda g: -g[0])
        chosen: list[Pose2D] = []
        for _, g in guesses:  # the best distinct guesses
            if all(math.hypot(g.x - c.x, g.y - c.y) > 2 * step_m for c in chosen):
                chosen.append(g)
            if len(chosen) >= rc.refine_guesses:
                break
        fits: list[Recognition] = []  # every hypothesis that fits the model well
        for g in chosen:
            res = localize(island.model, pts, g, self.config.localize)
            p = res.pose
            if not res.converged:
                refuse("not_converged")
                continue
            if res.residual_m > max_residual_m:
                refuse("residual")
                continue
            if res.constraint < rc.min_constraint:
                refuse("weak_constraint")  # slides along a hallway: aliases along it
                continue
            if math.hypot(p.x - est.x, p.y - est.y) > radius_m:
                refuse("outside_search_radius")
                continue
            if abs(wrap_angle(p.theta - est.theta)) > max_dth_rad + 2.0 * heading_step:
                # The refinement turned the points far out of the heading window: a + junction
                # fits itself turned by 90 deg (paper_fig4: 0.09 m residual, 92 % inliers).
                refuse("outside_heading_window")
                continue
            world = _from_frame(pts, p)
            inl = float(np.mean(point_segment_distance(world, segs).min(axis=1) <= rc.inlier_m))
            if inl < rc.min_inlier_fraction:
                refuse("inliers")
                continue
            fits.append(Recognition(island.id, p, float(res.residual_m), inl))
        if not fits:
            return None
        best = min(fits, key=lambda f: f.residual_m)
        p = best.pose
        if any(math.hypot(f.pose.x - p.x, f.pose.y - p.y) > rc.ambiguity_m for f in fits):
            refuse("ambiguous")  # the model fits at distinct places (e.g. along doors)
            return None
        if math.hypot(p.x, p.y) > rc.max_dock_m:
            refuse("origin_too_far")
            return None
        if not self._path_clear(segs, p):
            refuse("path_blocked")
            return None
        if not self._localizes_back(island.model, pts, p):
            refuse("localization_check")
            return None
        return best

    def _link(self, a: int, b: int, origin_b_odom: Pose2D, sigma_m: float) -> None:
        """Remember where b's origin lies in a's frame (the odometry since a's origin)."""
        t_ab = origin_b_odom.relative_to(self._known[a][0])
        sig_th = math.sqrt(max(float(self._rel.p[2, 2]), 0.0))
        old = self._links.get((a, b))
        if old is None or sigma_m < old[1]:
            self._links[a, b] = (t_ab, sigma_m, sig_th)

    def _estimates(self, iid: int) -> list[tuple[Pose2D, float, float]]:
        """Where island iid's origin may be in the odometry frame: (pose, position sigma [m],
        heading sigma [rad]), from its last known odometric pose (the odometry's drift since)
        and, when the links measured on edges join it to the last island, through the chain of
        links with the smallest summed sigma (epsilon plus the chain's error)."""
        assert self._odom is not None
        origin, cov0 = self._known[iid]
        grow = self._cov - cov0
        w_xy = np.linalg.eigvalsh(0.5 * (grow[:2, :2] + grow[:2, :2].T))
        out = [
            (
                origin,
                max(self.epsilon_m, math.sqrt(max(float(w_xy[-1]), 0.0))),
                math.sqrt(max(float(grow[2, 2]), 0.0)),
            )
        ]
        last = self._last_island
        if last is not None and last.id in self._known and last.id != iid:
            chain = self._chain(last.id, iid)
            if chain is not None:
                t, sig_m, sig_th = chain
                base = self._known[last.id][0]
                sig_rel_th = math.sqrt(max(float(self._rel.p[2, 2]), 0.0))
                # The robot's own heading error since the last island turns the whole chain.
                reach = math.hypot(t.x, t.y)
                out.append((base.compose(t), self.epsilon_m + sig_m + sig_rel_th * reach,
                            sig_rel_th + sig_th))
        return out

    def _chain(self, src: int, dst: int) -> tuple[Pose2D, float, float] | None:
        """Island dst's origin in island src's frame through the links (either direction),
        the chain with the smallest position sigma: (pose, sigma [m], heading sigma [rad]).
        A link's heading error turns every later link: sigma grows by the heading sigma so far
        times each later link's length (first order)."""
        best = {src: 0.0}
        heap: list[tuple[float, int, int, Pose2D, float]] = [(0.0, 0, src, Pose2D(0, 0, 0), 0.0)]
        tie = 1
        while heap:
            sig, _, node, pose, sig_th = heapq.heappop(heap)
            if node == dst:
                return pose, sig, sig_th
            if sig > best.get(node, math.inf):
                continue
            for (a, b), (t_ab, s_m, s_th) in self._links.items():
                if node not in (a, b):
                    continue
                nxt, step = (b, t_ab) if a == node else (a, t_ab.inverse())
                ns = sig + s_m + sig_th * math.hypot(step.x, step.y)
                if ns < best.get(nxt, math.inf):
                    best[nxt] = ns
                    heapq.heappush(heap, (ns, tie, nxt, pose.compose(step), sig_th + s_th))
                    tie += 1
        return None

    def _refuse(self, reason: str) -> None:
        self.revisit_refusals[reason] = self.revisit_refusals.get(reason, 0) + 1

    def _path_clear(self, segs: FloatArray, p: Pose2D) -> bool:
        """Is the straight path from p to the island origin clear of the model's walls?"""
        return self._drive_clear(segs, np.array([p.x, p.y]), np.zeros(2))

    def _drive_clear(self, segs: FloatArray, a: FloatArray, b: FloatArray) -> bool:
        """Does the straight drive a -> b [m] keep path_clearance_m from the walls `segs`?"""
        k = max(2, math.ceil(float(np.hypot(*(b - a))) / 0.05) + 1)
        line = np.stack([np.linspace(a[0], b[0], k), np.linspace(a[1], b[1], k)], axis=1)
        clear = self.config.revisit.path_clearance_m
        return bool(point_segment_distance(line, segs).min() >= clear)

    def _try_revisit(self) -> bool:
        """Recognise a known island here; on success the robot docks onto its origin."""
        rec = self.recognize()
        if rec is None:
            return False
        self._revisit(rec)
        return True

    def _recognize_star(self) -> Recognition | None:
        """Match the points of the current star against the known islands near its anchor;
        the recognition's pose is the robot's (now) in the island frame."""
        att, rc = self._attempt, self.config.revisit
        assert att is not None and self._odom is not None
        if not (rc.enabled and rc.at_star) or not self._known or not att.near_points:
            return None
        pts = np.concatenate(att.near_points, axis=0)  # the anchor's frame
        if pts.shape[0] < rc.min_points:
            return None
        pts = thin_evenly(pts, rc.star_max_points)
        rec = self._recognize_points(pts, att.anchor, star=True)
        if rec is None:
            return None
        now = rec.pose.compose(self._odom.relative_to(att.anchor))
        return Recognition(rec.island_id, now, rec.residual_m, rec.inlier_fraction)

    def _revisit(
        self,
        rec: Recognition,
        legs_m: tuple[tuple[float, float], ...] = (),
        strategy_end: Pose2D | None = None,
    ) -> None:
        """Link the previous island to the recognised one and dock onto its origin.

        strategy_end: where the follower's strategy ended, in the island frame (default: the
        robot now); the edge's last steps drive from there to the origin. After a star the
        robot is back at the anchor but faces its last leg, so that must be the anchor pose.
        """
        assert self._odom is not None
        island = next(i for i in self.islands if i.id == rec.island_id)
        p = rec.pose if strategy_end is None else strategy_end
        dist = math.hypot(p.x, p.y)
        steps = _drive_onto_origin(p, self.config.revisit.strategy_min_go_m)
        edge = None
        prev = self._last_island
        if prev is not None and prev.id != island.id:
            length = max(self._path_m - self._island_path_start_m, 0.0) + dist
            eps = self.epsilon_m
            new = Edge(
                source=prev.id,
                target=island.id,
                strategy=normalize_strategy(ControlStrategy(self._strategy.steps + steps)),
                weight=length + eps,
                length_m=length,
                expected_error_m=eps,
            )
            pair = (prev.id, island.id)
            old = next((k for k, e in enumerate(self.edges) if (e.source, e.target) == pair), None)
            if old is None:
                self.edges.append(new)
                edge = new
            elif new.weight < self.edges[old].weight:
                self.edges[old] = new
                edge = new
        origin_odom = self._odom.compose(rec.pose.inverse())  # the island origin, odometry
        self._emit(
            EventKind.ISLAND_REVISITED,
            anchor_odom=origin_odom,
            revisited_island_id=island.id,
            island_pose=rec.pose,
            residual_m=rec.residual_m,
            edge=edge,
            legs_m=legs_m,
        )
        if prev is not None and prev.id != island.id and prev.id in self._known:
            self._link(prev.id, island.id, origin_odom, self.epsilon_m)
        self._dock = _Dock(
            island=island,
            target=origin_odom,
            looks_left=self.config.revisit.dock_looks,
        )
        self._state = _State.DOCKING

    def _dock_step(self) -> tuple[float, float]:
        """Drive onto the recognised origin, face its heading, look around and re-localize."""
        dock = self._dock
        assert dock is not None and self._odom is not None
        sc, rc = self.config.star, self.config.revisit
        rel = self._odom.relative_to(dock.target)  # the robot in the island frame
        cmd = self._go_align(dock, rel, math.radians(min(sc.heading_tol_deg, rc.dock_tol_deg)))
        if cmd is not None:
            return cmd
        if dock.phase is _DockPhase.ALIGN:
            if dock.looks_left <= 0:
                return self._finish_dock()
            self._start_look(dock)
        cmd = self._look_step(dock)  # a full circle, then localize from the odometric estimate
        if cmd is not None:
            return cmd
        dock.looks_left -= 1
        pts = np.concatenate(dock.points, axis=0) if dock.points else np.zeros((0, 2))
        res = localize(dock.island.model, _to_frame(pts, self._odom), rel, self.config.localize)
        moved = math.hypot(res.pose.x - rel.x, res.pose.y - rel.y)
        if res.converged and res.residual_m <= rc.max_residual_m and moved <= rc.max_dock_m:
            dock.target = self._odom.compose(res.pose.inverse())
            if math.hypot(res.pose.x, res.pose.y) <= rc.dock_tol_m and abs(
                res.pose.theta
            ) <= math.radians(rc.dock_tol_deg):
                dock.looks_left = 0
        else:
            dock.looks_left = 0  # cannot do better than odometry
        dock.phase = _DockPhase.GO
        return 0.0, 0.0

    def _go_align(self, look: _Look, rel: Pose2D, tol_rad: float
                  ) -> tuple[float, float] | None:
        """GO onto the origin (`rel`: the robot in its frame), then ALIGN with its heading
        within tol_rad: the command, or None once aligned (phase ALIGN) or looking (LOOK)."""
        if look.phase is _DockPhase.GO:
            cmd = self._drive_to_origin(rel)
            if cmd is not None:
                return cmd
            look.phase = _DockPhase.ALIGN
        if look.phase is _DockPhase.ALIGN:
            err = wrap_angle(-rel.theta)
            if abs(err) > tol_rad:
                return 0.0, self._turn_rate(err)
        return None

    def _look(self) -> _Look | None:
        """The dock or probe under way, if the state is one of theirs."""
        if self._state is _State.DOCKING:
            return self._dock
        if self._state is _State.PROBING and self._attempt is not None:
            return self._attempt.probe
        return None

    def _start_look(self, look: _Look) -> None:
        assert self._odom is not None
        look.phase, look.turned_rad, look.prev_theta, look.points = (
            _DockPhase.LOOK, 0.0, self._odom.theta, [])

    def _look_step(self, look: _Look) -> tuple[float, float] | None:
        """LOOK: turn a full circle in place (scans collect in look.points); None once done."""
        assert self._odom is not None
        look.turned_rad += abs(wrap_angle(self._odom.theta - look.prev_theta))
        look.prev_theta = self._odom.theta
        if look.turned_rad < 2.0 * math.pi:
            return 0.0, self.config.star.turn_rate_radps
        return None

    def _turn_rate(self, err_rad: float) -> float:
        sc = self.config.star
        return float(
            np.clip(sc.heading_gain_per_s * err_rad, -sc.turn_rate_radps, sc.turn_rate_radps)
        )

    def _drive_to_origin(self, rel: Pose2D) -> tuple[float, float] | None:
        """(v, w) toward the island origin (forward, or reversing when it is just behind),
        or None when there (or when the way ahead is blocked)."""
        sc = self.config.star
        dist = math.hypot(rel.x, rel.y)
        if dist <= sc.position_tol_m:
            return None
        to_c = math.atan2(-rel.y, -rel.x)
        err = wrap_angle(to_c - rel.theta)
        if abs(err) > 0.5 * math.pi and dist < 0.3:  # overshot a little: reverse onto it
            err_b = wrap_angle(to_c + math.pi - rel.theta)
            return -min(sc.speed_mps, 2.0 * dist), self._turn_rate(err_b)
        if abs(err) > math.radians(10.0):
            return 0.0, self._turn_rate(err)
        if self._ahead_free_m() < min(sc.clearance_m, 0.5):
            return None  # something in the way: dock where it stands
        return min(sc.speed_mps, 2.0 * dist), self._turn_rate(err)

    def _finish_dock(self) -> tuple[float, float]:
        dock = self._dock
        assert dock is not None and self._odom is not None
        iid = dock.island.id
        self._last_island = dock.island
        self._island_path_start_m = self._path_m
        self._strategy = ControlStrategy(())
        self._rel.reset()  # the robot knows where it is: at the island's origin
        self._known[iid] = (dock.target, self._cov.copy())
        self._retry_at_path_m = self._path_m
        self._emit(EventKind.HANDED_BACK, anchor_odom=dock.target, accepted_island_id=iid)
        self._dock = None
        self._recent.clear()
        self._revisit_recent.clear()
        self._state = _State.FOLLOWING
        return 0.0, 0.0

    def _dismiss(self, partial: bool, reason: DismissReason | None = None) -> None:
        att = self._attempt
        assert att is not None
        att.outcome = EventKind.ATTEMPT_DISMISSED
        self._retry_at_path_m = self._path_m + self.config.retry_distance_m
        self._emit(
            EventKind.ATTEMPT_DISMISSED,
            epsilon_m=att.epsilon_m,
            anchor_odom=att.anchor,
            measure=att.best,
            bound=att.bound,
            legs_m=tuple(att.legs_done),
            partial=partial,
            reason=reason if reason is not None else DismissReason.MEASURE,
        )
        self._state = _State.RETURNING

    def _return_step(self) -> tuple[float, float]:
        att = self._attempt
        assert att is not None
        sc = self.config.star
        pose = self._pose_in_anchor()
        dist = math.hypot(pose.x, pose.y)
        if dist > sc.position_tol_m:
            # Reverse or drive straight back to the centre along the current heading's line.
            to_c = math.atan2(-pose.y, -pose.x)
            err = wrap_angle(to_c - pose.theta)
            if abs(err) < 0.5 * math.pi:
                if abs(err) > math.radians(10.0):
                    return self._turn_to(to_c) or (0.0, 0.0)
                return self._drive_line(to_c, 0.0, min(sc.speed_mps, 2.0 * dist))
            back = wrap_angle(to_c + math.pi)
            if abs(wrap_angle(back - pose.theta)) > math.radians(10.0):
                return self._turn_to(back) or (0.0, 0.0)
            return self._drive_line(back, 0.0, -min(sc.speed_mps, 2.0 * dist))
        cmd = self._turn_to(0.0)
        if cmd is not None:
            return cmd
        accepted = att.outcome is EventKind.ISLAND_ACCEPTED
        if accepted:
            self._island_path_start_m = self._path_m
            self._strategy = ControlStrategy(())
        self._emit(
            EventKind.HANDED_BACK,
            anchor_odom=att.anchor,
            accepted_island_id=self._last_island.id if accepted and self._last_island else None,
        )
        self._attempt = None
        self._star_rel = None
        self._recent.clear()
        self._state = _State.FOLLOWING
        return 0.0, 0.0


class StampSync:
    """Feeds an `IslandBuilder` so each scan meets the odometry (and ground truth) of its stamp.

    Live, DDS may deliver the odometry of the next sensor period before the scan of this one;
    feeding odometry at arrival would make a scan's decision use a later pose, so a run would
    depend on arrival order. Here odometry and ground truth wait in stamp-ordered buffers and a
    scan is processed (in stamp order) once odometry of its stamp or later has arrived: the
    builder is first fed every odometry stamped at or before the scan (so it holds the pose of
    the same stamp, or the newest older one), then the scan, then asked for its command. Never
    blocks; buffers are bounded by `max_buffer`: surplus odometry (no scan is waiting for it)
    is fed to the builder oldest first, surplus scans (no odometry is arriving) are dropped
    oldest first and counted in `dropped_scans`. Odometry stamped at or before what the
    builder was already fed cannot be applied in order and is counted in `stale_odometry`.
    """

    def __init__(self, builder: IslandBuilder, max_buffer: int = 200) -> None:
        if max_buffer < 1:
            raise BuilderError(f"StampSync.max_buffer: expected >= 1, got {max_buffer}")
        self.builder = builder
        self.max_buffer = max_buffer
        self._odom: list[tuple[int, Pose2D, FloatArray]] = []  # sorted by stamp [ns]
        self._truth: list[tuple[int, Pose2D]] = []  # sorted by stamp [ns]
        self._scans: deque[tuple[int, FloatArray, FloatArray]] = deque()
        self._fed_ns: int | None = None  # stamp of the newest odometry fed to the builder
        self.dropped_scans = 0
        self.stale_odometry = 0

    @property
    def scans_waiting(self) -> int:
        """Scans taken but not processed yet (their odometry has not come)."""
        return len(self._scans)

    def odometry(
        self, t_ns: int, pose: Pose2D, cov3x3: npt.ArrayLike
    ) -> list[tuple[int, BuilderCommand]]:
        """An odometry message; returns (stamp [ns], command) of every scan it released."""
        cov = np.asarray(cov3x3, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
            raise BuilderError(
                f"odometry: covariance must be a finite 3x3 matrix, got shape {cov.shape}"
            )
        if self._fed_ns is not None and t_ns <= self._fed_ns:
            self.stale_odometry += 1
            return []
        i = bisect.bisect_left(self._odom, t_ns, key=lambda o: o[0])
        if i < len(self._odom) and self._odom[i][0] == t_ns:
            self._odom[i] = (t_ns, pose, cov)
        else:
            self._odom.insert(i, (t_ns, pose, cov))
        return self._drain()

    def ground_truth(self, t_ns: int, pose: Pose2D) -> list[tuple[int, BuilderCommand]]:
        """A true pose (evaluation only); it reaches the builder with the scans of its stamp."""
        bisect.insort(self._truth, (t_ns, pose), key=lambda o: o[0])
        if len(self._truth) > self.max_buffer:
            self.builder.on_ground_truth(self._truth.pop(0)[1])
        return []

    def scan(
        self, t_ns: int, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike
    ) -> list[tuple[int, BuilderCommand]]:
        """A scan; returns (stamp [ns], command) of every scan processed now (this and older)."""
        r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
        a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
        if r.shape != a.shape:
            raise BuilderError(f"scan: {r.shape[0]} ranges but {a.shape[0]} angles")
        i = len(self._scans)
        while i > 0 and self._scans[i - 1][0] > t_ns:
            i -= 1
        self._scans.insert(i, (t_ns, r, a))
        if len(self._scans) > self.max_buffer:
            self._scans.popleft()
            self.dropped_scans += 1
        return self._drain()

    def _feed_odometry_until(self, t_ns: int) -> None:
        n = bisect.bisect_right(self._odom, t_ns, key=lambda o: o[0])
        for stamp, pose, cov in self._odom[:n]:
            self.builder.on_odometry(stamp * 1e-9, pose, cov)
            self._fed_ns = stamp
        del self._odom[:n]
        m = bisect.bisect_right(self._truth, t_ns, key=lambda o: o[0])
        if m:
            self.builder.on_ground_truth(self._truth[m - 1][1])
            del self._truth[:m]

    def _drain(self) -> list[tuple[int, BuilderCommand]]:
        out: list[tuple[int, BuilderCommand]] = []
        while self._scans:
            newest = self._odom[-1][0] if self._odom else self._fed_ns
            t_ns, r, a = self._scans[0]
            if newest is None or newest < t_ns:
                break  # its odometry may still come
            self._scans.popleft()
            self._feed_odometry_until(t_ns)
            t = t_ns * 1e-9
            self.builder.on_scan(t, r, a)
            out.append((t_ns, self.builder.command(t)))
        while len(self._odom) > self.max_buffer:  # no scan is waiting for these
            self._feed_odometry_until(self._odom[0][0])
        return out


def _scan_points(r: FloatArray, a: FloatArray, pose: Pose2D) -> FloatArray:
    """(K, 2) points [m] of the finite ranges in the pose's parent frame."""
    ok = np.isfinite(r) & np.isfinite(a)
    ang = a[ok] + pose.theta
    return np.stack([pose.x + r[ok] * np.cos(ang), pose.y + r[ok] * np.sin(ang)], axis=1)


def _drive_onto_origin(p: Pose2D, min_go_m: float) -> tuple[StrategyPrimitive, ...]:
    """The steps from pose `p` in an island's frame onto its origin, facing theta 0, as the hall
    follower would record them: turn to the origin, go, turn; only the final turn when the origin
    is `min_go_m` [m] or nearer."""
    dist = math.hypot(p.x, p.y)
    steps: tuple[StrategyPrimitive, ...]
    if dist > min_go_m:
        to_c = wrap_angle(math.atan2(-p.y, -p.x) - p.theta)
        steps = (_rot(to_c), StrategyPrimitive(PrimitiveKind.GO, round(100 * dist)),
                 _rot(-(p.theta + to_c)))
    else:
        steps = (_rot(-p.theta),)
    return tuple(s for s in steps if s.value != 0)


def _rot(angle_rad: float) -> StrategyPrimitive:
    """A Rot step of the strategy (degrees CCW in [0, 360))."""
    return StrategyPrimitive(PrimitiveKind.ROT, round(math.degrees(angle_rad)) % 360)


def _from_frame(points: FloatArray, frame: Pose2D) -> FloatArray:
    """(K, 2) points [m] of `frame` expressed in its parent frame."""
    c, s = math.cos(frame.theta), math.sin(frame.theta)
    x = frame.x + c * points[:, 0] - s * points[:, 1]
    return np.stack([x, frame.y + s * points[:, 0] + c * points[:, 1]], axis=1)


def _to_frame(points: FloatArray, frame: Pose2D) -> FloatArray:
    """(K, 2) points [m] of the parent frame expressed in `frame`."""
    c, s = math.cos(frame.theta), math.sin(frame.theta)
    d = points - np.array([frame.x, frame.y])
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)


def event_to_dict(e: BuilderEvent) -> dict[str, object]:
    """The JSON form of a builder event (poses as {x, y, theta}, m and rad)."""
    d: dict[str, object] = {
        "kind": e.kind.value,
        "t_s": e.t_s,
        "odom_pose": json_io.pose_to_dict(e.odom_pose),
        "epsilon_m": e.epsilon_m,
        "measure": e.measure,
        "bound": e.bound,
        "legs_m": [list(leg) for leg in e.legs_m],
        "partial": e.partial,
        "anchor_odom": json_io.pose_to_dict(e.anchor_odom) if e.anchor_odom else None,
    }
    if e.island is not None:
        d["island"] = json_io.island_to_dict(e.island)
    if e.edge is not None:
        d["edge"] = json_io.edge_to_dict(e.edge)
    if e.accepted_island_id is not None:
        d["accepted_island_id"] = e.accepted_island_id
    if e.reason is not None:
        d["reason"] = e.reason.value
    if e.revisited_island_id is not None:
        d["revisited_island_id"] = e.revisited_island_id
    if e.island_pose is not None:
        d["island_pose"] = json_io.pose_to_dict(e.island_pose)
    if e.residual_m is not None:
        d["residual_m"] = e.residual_m
    return d
