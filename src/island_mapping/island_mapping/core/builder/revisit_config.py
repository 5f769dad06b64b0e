"""Recognising an island the robot already built: its configuration (`RevisitConfig`), part of
`BuilderConfig` (core.builder.config) and of the explorer's."""

from __future__ import annotations

from dataclasses import dataclass, field

from island_mapping.core.builder.errors import BuilderError
from island_mapping.core.builder.errors import check_numbers as _check


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
    accept_inlier_fraction: float = field(
        default=0.0,
        metadata={"help": "the recognition kept must have at least this inlier fraction; fits "
                          "from min_inlier_fraction up still count as rivals (0: "
                          "min_inlier_fraction alone) [-]"},
    )
    clip_search: bool = field(
        default=False,
        metadata={"help": "a candidate whose window would exceed the search caps is searched "
                          "within the caps instead of refused (needs unique_island and a "
                          "revisit gate with topological evidence) [bool]"},
    )
    turned_alias: bool = field(
        default=False,
        metadata={"help": "refuse a recognition when the island fits the points as well turned "
                          "by a quarter or half turn, once its heading uncertainty (rival_sigmas "
                          "heading sigmas) exceeds 45 deg [bool]"},
    )
    clipped_rivals: bool = field(
        default=False,
        metadata={"help": "when the recognised island's window was cut to the search caps "
                          "(clip_search), every other island is searched around its own "
                          "origin (within max_dock_m, any heading): one that fits as well "
                          "makes the place a look-alike and the recognition is refused [bool]"},
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
            "accept_inlier_fraction",
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
