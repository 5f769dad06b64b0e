"""Configuration of exploration by the map: exits, the explorer's mission, loop closure.

Frozen dataclasses, the single source of defaults; every field's help says what it does.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from island_mapping.core.builder import RevisitConfig
from island_mapping.core.builder.opening_config import OpeningConfig


class ExploreError(ValueError):
    """Bad input to exploration (the message names what was wrong)."""


def _check_ints(owner: object, names: tuple[str, ...], minimum: int = 0) -> None:
    """Named fields must be ints (not bools) >= minimum."""
    for name in names:
        v = getattr(owner, name)
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            raise ExploreError(f"{type(owner).__name__}.{name}: expected an int >= {minimum}, "
                               f"got {v!r}")


def _check_numbers(owner: object, strict: tuple[str, ...], loose: tuple[str, ...]) -> None:
    """Named fields must be finite numbers, > 0 (strict) or >= 0 (loose)."""
    name = type(owner).__name__
    for f in strict + loose:
        v = getattr(owner, f)
        ok = isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
        if not ok or v < 0 or (f in strict and v == 0):
            bound = "> 0" if f in strict else ">= 0"
            raise ExploreError(f"{name}.{f}: expected a finite number {bound}, got {v!r}")


@dataclass(frozen=True)
class ExitConfig:
    """Where free space leads away from an island (`core.explore.exits`)."""

    heading_step_deg: float = field(
        default=15.0,
        metadata={"help": "lanes are tried along the island's axes and every this many degrees "
                          "[deg]"},
    )
    lane_offset_m: float = field(
        default=1.5,
        metadata={"help": "a lane may leave the origin's line this far to either side (a side "
                          "corridor or a door beside the origin) [m]"},
    )
    clearance_m: float = field(
        default=0.32,
        metadata={"help": "a lane is free while it keeps this far from the model's walls and "
                          "from echo points (the robot's radius plus a margin) [m]"},
    )
    reach_m: float = field(
        default=3.0,
        metadata={"help": "free space leads away along a lane that stays free this far [m]"},
    )
    entry_m: float = field(
        default=1.2,
        metadata={"help": "an exit's heading points from the origin to this far along its "
                          "lane (into the opening) [m]"},
    )
    evidence_range_m: float = field(
        default=5.0,
        metadata={"help": "echo points farther than this from the origin are not used (wide "
                          "sonar cones) [m]"},
    )
    min_points: int = field(
        default=2,
        metadata={"help": "echo points within clearance_m of a lane point that block it [-]"},
    )
    driven_clearance_m: float = field(
        default=0.3,
        metadata={"help": "echo points this close to a path the robot drove are noise (it drove "
                          "there) and are ignored, and lane points this close are free [m]"},
    )
    merge_deg: float = field(
        default=30.0,
        metadata={"help": "lanes whose headings lie within this of a kept exit's are that exit "
                          "[deg]"},
    )
    arrival_match_deg: float = field(
        default=45.0,
        metadata={"help": "the exit within this of the direction the robot came from is the "
                          "arrival exit (explored by the edge that arrived) [deg]"},
    )
    min_width_m: float = field(
        default=0.6, metadata={"help": "narrowest opening reported as an exit [m]"}
    )
    closed_reach_m: float = field(
        default=1.8,
        metadata={"help": "an island none of whose lanes stays free reach_m (a small room "
                          "whose doorway opens on a narrow hallway) takes the lanes free this "
                          "far as its exits (0: none) [m]"},
    )
    open_width_m: float = field(
        default=3.0,
        metadata={"help": "where the model's free width across the origin is at least this "
                          "along both island axes the island stands in open space (a room, a "
                          "hall): its exits are the gaps in the walls (gates) [m]"},
    )
    gap_line_m: float = field(
        default=0.3,
        metadata={"help": "two wall segments within this of one line make a wall with a gap "
                          "(a doorway) [m]"},
    )
    gap_line_deg: float = field(
        default=15.0,
        metadata={"help": "... and within this of one direction [deg]"},
    )
    opening_ahead_deg: float = field(
        default=100.0,
        metadata={"help": "an island inside a side opening keeps the exits within this of its "
                          "theta 0 (into the opening); the hallway it stands off is its arrival "
                          "and a side exit [deg]"},
    )
    look_through: bool = field(
        default=True,
        metadata={"help": "a lane straight out along an island axis is free, whatever the model "
                          "and echoes say, when the star's readings along it see past reach_m "
                          "(look_* below) [bool]"},
    )
    look_from_m: float = field(
        default=0.75,
        metadata={"help": "readings taken within this of the origin are looked through [m]"},
    )
    look_deg: float = field(
        default=8.0,
        metadata={"help": "readings whose bearing lies within this of the axis look along it "
                          "[deg]"},
    )
    look_min_readings: int = field(
        default=3,
        metadata={"help": "readings along the axis with no echo, or one beyond reach_m plus "
                          "clearance_m, that make it free [-]"},
    )
    look_min_fraction: float = field(
        default=0.25,
        metadata={"help": "... and their least share of the readings along it [-]"},
    )

    def __post_init__(self) -> None:
        _check_numbers(self, ("heading_step_deg", "clearance_m", "reach_m", "evidence_range_m",
                              "look_from_m", "look_deg", "look_min_fraction",
                              "merge_deg", "min_width_m", "entry_m", "opening_ahead_deg",
                              "open_width_m", "gap_line_m", "gap_line_deg"),
                       ("driven_clearance_m", "arrival_match_deg", "lane_offset_m",
                        "closed_reach_m"))
        for name in ("min_points", "look_min_readings"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ExploreError(f"ExitConfig.{name}: expected an int >= 1, got {v!r}")
        if self.look_min_fraction > 1.0:
            raise ExploreError(f"ExitConfig.look_min_fraction: expected at most 1, got "
                               f"{self.look_min_fraction!r}")


@dataclass(frozen=True)
class NoveltyConfig:
    """Exits into space the map already knows go last (`core.explore.novelty`)."""

    enabled: bool = field(
        default=False,
        metadata={"help": "rank exits whose look point the map already knows after the others "
                          "(false: nearest first only) [bool]"},
    )
    lookahead_m: float = field(
        default=4.0,
        metadata={"help": "an exit's look point lies this far ahead of it (a side exit's: of "
                          "its opening, after the turn) [m]"},
    )
    radius_m: float = field(
        default=2.0,
        metadata={"help": "a look point within this of an island origin, an edge's driven path "
                          "or a side exit's opening is known space [m]"},
    )
    penalty_m: float = field(
        default=200.0,
        metadata={"help": "extra route length the planner charges an exit into known space [m]"},
    )
    chain_m: float = field(
        default=200.0,
        metadata={"help": "islands up to this route length away are placed (their frames "
                          "dead-reckoned along the edges' strategies); exits of islands farther "
                          "away cost nothing extra [m]"},
    )
    spacing_m: float = field(
        default=0.5,
        metadata={"help": "an edge's driven path is sampled every this far [m]"},
    )

    def __post_init__(self) -> None:
        _check_numbers(self, ("lookahead_m", "radius_m", "chain_m", "spacing_m"), ("penalty_m",))
        if not isinstance(self.enabled, bool):
            raise ExploreError(f"NoveltyConfig.enabled: expected a bool, got {self.enabled!r}")


@dataclass(frozen=True)
class DoorwayConfig:
    """How the robot finds and passes a doorway its departure has no lane through
    (`core.explore.doorway`)."""

    enabled: bool = field(
        default=True,
        metadata={"help": "with no lane seen, the robot looks for a doorway in the wall the exit "
                          "meets and passes its middle (false: it drives along the exit, "
                          "centred by the sonar) [bool]"},
    )
    approach_m: float = field(
        default=1.0,
        metadata={"help": "where a look from the departure's start shows no doorway, the "
                          "robot drives along the exit until an echo within 30 deg of its "
                          "heading is this near (or 70 deg and 0.6 of it), then looks again "
                          "[m]"},
    )
    sweep_deg: float = field(
        default=45.0,
        metadata={"help": "the look turns this far either side of the exit's heading [deg]"},
    )
    standoff_m: float = field(
        default=0.7,
        metadata={"help": "the robot stands this far before the doorway's middle, on its wall's "
                          "normal, looks again and drives through from there [m]"},
    )
    refines: int = field(
        default=3,
        metadata={"help": "looks from the stand-off point at most, each moving it to the "
                          "middle found [-]"},
    )
    settle_m: float = field(
        default=0.08,
        metadata={"help": "the looks stop once the middle found moves less than this [m]"},
    )
    see_through_m: float = field(
        default=0.5,
        metadata={"help": "a reading this much beyond the fitted wall sees through it [m]"},
    )
    half_width_m: float = field(
        default=0.38,
        metadata={"help": "a doorway whose one jamb only is seen has its middle this far "
                          "from it along the wall [m]"},
    )
    min_inliers: int = field(
        default=10,
        metadata={"help": "bearing bins a wall must explain to be fitted [-]"},
    )
    cone_half_deg: float = field(
        default=12.5,
        metadata={"help": "half the sonar's cone (island_sim SonarConfig.beam_width_deg / 2) "
                          "[deg]"},
    )
    cone_rays: int = field(
        default=5,
        metadata={"help": "rays across a cone the wall model takes (SonarConfig.rays_per_beam) "
                          "[-]"},
    )
    echo_deg: float = field(
        default=30.0,
        metadata={"help": "largest incidence that still echoes (SonarConfig.reflect_deg) [deg]"},
    )

    def __post_init__(self) -> None:
        _check_numbers(self, ("approach_m", "sweep_deg", "standoff_m", "settle_m",
                              "see_through_m", "half_width_m", "echo_deg"),
                       ("cone_half_deg",))
        if not isinstance(self.enabled, bool):
            raise ExploreError(f"DoorwayConfig.enabled: expected a bool, got {self.enabled!r}")
        _check_ints(self, ("refines", "min_inliers"))
        _check_ints(self, ("cone_rays",), 1)


@dataclass(frozen=True)
class ExplorerConfig:
    """The explorer's mission (`core.explore.mission`)."""

    stuck_s: float = field(
        default=45.0,
        metadata={"help": "the builder's exploration of an exit is stopped as past exit_cap_s "
                          "when the robot's odometric position has stayed within stuck_m for "
                          "this long [s]"},
    )
    stuck_m: float = field(
        default=0.5,
        metadata={"help": "see stuck_s: moving less than this far is no progress [m]"},
    )
    return_max_shift_m: float = field(
        default=1.0,
        metadata={"help": "back at the island left, a localization farther than this from "
                          "where odometry says the robot is counts as not converged (the robot "
                          "is then lost, not docked) [m]"},
    )
    relocalize_max_shift_m: float = field(
        default=3.0,
        metadata={"help": "when that fails, a second look may find the island up to this far "
                          "from odometry's estimate; the robot drives to the origin it shows "
                          "and is docked only when a look there localizes within "
                          "return_max_shift_m (<= return_max_shift_m: no second look) [m]"},
    )
    relocalize_max_turn_deg: float = field(
        default=40.0,
        metadata={"help": "the second look's hypothesis may turn the heading this far from "
                          "odometry's (NavigateConfig.max_turn_deg for every look that docks); "
                          "a quarter turn would be a junction's alias [deg]"},
    )
    relocalize_max_residual_m: float = field(
        default=0.2,
        metadata={"help": "and may leave this RMS residual (NavigateConfig.max_residual_m "
                          "for every look that docks) [m]"},
    )
    return_shortcut_m: float = field(
        default=0.4,
        metadata={"help": "driving back to the island left, the way out is taken without its "
                          "loops: where it came back within this of a point passed "
                          "return_loop_m earlier, the lap is skipped (0: the whole way) [m]"},
    )
    return_loop_m: float = field(
        default=3.0,
        metadata={"help": "see return_shortcut_m: the shortest stretch of the way that counts "
                          "as a loop [m]"},
    )
    way_tolerance_m: float = field(
        default=0.5,
        metadata={"help": "the way back to the island left, and a lost robot's next prefix, "
                          "are the odometric way driven since the last dock, as a polyline "
                          "within this of it, without its loops (return_shortcut_m); 0: the "
                          "explorer's own moves and the follower's record [m]"},
    )
    exit_cap_s: float = field(
        default=300.0,
        metadata={"help": "sim time the builder may spend exploring one exit before the explorer "
                          "takes the robot back to the island it left and marks the exit "
                          "blocked [s]"},
    )
    open_space_cap_s: float = field(
        default=90.0,
        metadata={"help": "the builder's exploration of an exit is stopped as past exit_cap_s "
                          "once the robot has gone this long without walls on both sides: the "
                          "hall follower runs round a room, where no place of its own is left "
                          "(the room's island stands at its door) [s]"},
    )
    depart_min_free_m: float = field(
        default=1.2,
        metadata={"help": "an exit whose way ahead (the sonar, facing it) is free less than "
                          "this is blocked without driving it [m]"},
    )
    lane_snap_m: float = field(
        default=0.2,
        metadata={"help": "a departure lane that leaves the origin's line less than this to the "
                          "side is driven from the origin itself [m]"},
    )
    look_buffer_s: float = field(
        default=30.0,
        metadata={"help": "the explorer keeps the echoes of this last stretch of time to plan "
                          "a departure [s]"},
    )
    door_max_width_m: float = field(
        default=1.6,
        metadata={"help": "exits narrower than this are doorways: the robot drives through "
                          "before the hall follower takes over [m]"},
    )
    door_through_m: float = field(
        default=1.5,
        metadata={"help": "how far along a doorway's lane the robot drives before the hall "
                          "follower takes over; with no lane seen, how far past the opening's "
                          "entry (exit.entry_m) it drives along the exit [m]"},
    )
    map_wait_s: float = field(
        default=5.0,
        metadata={"help": "at an island, the explorer waits at most this for the map to show "
                          "it and the exits its arrival explored [s]"},
    )
    retries_per_exit: int = field(
        default=1,
        metadata={"help": "times an exit is tried again, once no other exit is left, after "
                          "its exploration was stopped (stuck, or round a room) and the robot "
                          "driven back, before it is marked blocked [-]"},
    )
    revisit_near_m: float = field(
        default=2.5,
        metadata={"help": "a recognised island is docked onto only when the robot is this "
                          "close to its origin (at its place, not seeing it from the next "
                          "one) [m]"},
    )
    revisit_max_mahalanobis2: float = field(
        default=11.34,
        metadata={"help": "a recognised island is docked onto only when the recognised pose "
                          "lies within this squared Mahalanobis distance of where odometry "
                          "propagated from the last island puts it (11.34: 99 % of 3 degrees "
                          "of freedom) [-]"},
    )
    rehearse_hypotheses: int = field(
        default=2,
        metadata={"help": "a star that fits a known island and a look-alike is not decided on "
                          "the spot: up to this many of the islands it fits (best fit first, "
                          "each within the loop-closure gate) are tested by driving the "
                          "island's shortest edges and localizing at their neighbours; the "
                          "first found so is docked onto, else a new island is built (0: build "
                          "at once) [-]"},
    )
    rehearse_edges: int = field(
        default=3,
        metadata={"help": "a rehearsal tries at most this many of the island's edges, shortest "
                          "first, docking at the island again between them (an edge replay "
                          "that ends off its neighbour says little of where the robot was) [-]"},
    )
    rehearse_neighbours: int = field(
        default=2,
        metadata={"help": "a rehearsal confirms once this many of the island's neighbours were "
                          "found at the ends of its edges (all of them where it has fewer) [-]"},
    )
    rehearse_onward: bool = field(
        default=False,
        metadata={"help": "the last neighbour a rehearsal needs is looked for beyond the one "
                          "just found (its shortest edge to another island), not by driving "
                          "back to the island and along its next edge [-]"},
    )
    rehearse_max_shift_m: float = field(
        default=1.0,
        metadata={"help": "a rehearsal's look at the neighbour confirms only within this of "
                          "its origin (no search along the hallway) [m]"},
    )
    rehearse_through: float = field(
        default=0.25,
        metadata={"help": "and only when at most this fraction of the beams the neighbour's "
                          "model says must echo (a wall within 3 m, met near head-on) heard "
                          "through it in a look there [-]"},
    )
    side_exits: bool = field(
        default=True,
        metadata={"help": "a side opening the robot passes while the hall follower drives an "
                          "edge becomes an exit of the island the edge left, reached by the "
                          "edge's strategy up to it and a turn (no island is placed there) "
                          "[-]"},
    )
    side_min_width_m: float = field(
        default=0.5,
        metadata={"help": "a side must stay open over this much straight driving to be a side "
                          "exit [m]"},
    )
    side_max_turn_deg: float = field(
        default=20.0,
        metadata={"help": "an opening passed while the heading changed more than this (the "
                          "follower turned there) is not a side exit [deg]"},
    )
    side_near_island_m: float = field(
        default=3.0,
        metadata={"help": "an opening this close to a known island's origin (dead-reckoned "
                          "along edges) is that island's, whose own exits cover it [m]"},
    )
    side_merge_m: float = field(
        default=2.0,
        metadata={"help": "an opening this close to a known side exit (dead-reckoned along "
                          "edges) whose turn leads the same way is that exit [m]"},
    )
    side_merge_deg: float = field(
        default=45.0,
        metadata={"help": "two side exits lead the same way when their headings after the "
                          "turn differ by less than this [deg]"},
    )
    side_chain_m: float = field(
        default=60.0,
        metadata={"help": "islands up to this route length away are compared for duplicates "
                          "(their frames dead-reckoned along the edges' strategies) [m]"},
    )
    failed_edge_penalty_m: float = field(
        default=100.0,
        metadata={"help": "an edge whose arrival did not localize counts this much longer in "
                          "later routes (the robot turned back to the island it left) [m]"},
    )
    side_direct_m: float = field(
        default=3.0,
        metadata={"help": "a side exit whose prefix drives no farther than this is reached by "
                          "its prefix alone, without seeking the opening [m]"},
    )
    side_search_m: float = field(
        default=1.5,
        metadata={"help": "driving to a side exit, the robot looks for the opening from this "
                          "far before the end of its prefix to this far past it [m]"},
    )
    exit: ExitConfig = field(
        default_factory=ExitConfig, metadata={"help": "how exits are found at an island"}
    )
    doorway: DoorwayConfig = field(
        default_factory=DoorwayConfig,
        metadata={"help": "a doorway the departure has no lane through: found by a look and "
                          "passed at its middle"},
    )
    novelty: NoveltyConfig = field(
        default_factory=NoveltyConfig,
        metadata={"help": "which exits the planner takes last: those into known space"},
    )
    opening: OpeningConfig = field(
        default_factory=lambda: OpeningConfig(enabled=True),
        metadata={"help": "the builder's side openings while exploring by exits: a doorway or "
                          "a side hallway passed is a place to attempt an island at, inside it"},
    )
    accept_on_legs: bool = field(
        default=True,
        metadata={"help": "the builder checks eq. 3 over the region its star surveyed while "
                          "exploring by exits (BuilderConfig.accept_on_legs) [bool]"},
    )
    revisit: RevisitConfig = field(
        default_factory=lambda: RevisitConfig(
            unique_island=True, clip_search=True, star_search_max_m=10.0,
            star_search_cells=14, ambiguity_inlier_margin=0.15, turned_alias=True,
            accept_inlier_fraction=0.85, clipped_rivals=True),
        metadata={"help": "the builder's revisit search while exploring by exits: the star "
                          "searches every island odometry allows (within its caps) and a "
                          "recognition must fit one island only, 85 % of its points; the gate "
                          "adds the topology"},
    )

    def __post_init__(self) -> None:
        _check_numbers(self, ("exit_cap_s", "open_space_cap_s", "stuck_s", "stuck_m",
                              "return_max_shift_m", "door_max_width_m", "return_loop_m",
                              "door_through_m", "map_wait_s", "look_buffer_s", "revisit_near_m",
                              "revisit_max_mahalanobis2", "rehearse_max_shift_m"),
                       ("depart_min_free_m", "lane_snap_m", "return_shortcut_m",
                        "relocalize_max_shift_m", "relocalize_max_turn_deg",
                        "relocalize_max_residual_m", "way_tolerance_m", "rehearse_through"))
        _check_numbers(self, ("side_min_width_m", "side_near_island_m", "side_merge_m",
                              "side_merge_deg", "side_chain_m", "side_search_m"),
                       ("side_max_turn_deg", "side_direct_m", "failed_edge_penalty_m"))
        _check_ints(self, ("retries_per_exit", "rehearse_hypotheses", "rehearse_edges",
                           "rehearse_neighbours"))


def help_of(cls: type, name: str) -> str:
    """The help text of field `name` of a config dataclass (for docs and CLI help)."""
    for f in fields(cls):
        if f.name == name:
            return str(f.metadata.get("help", ""))
    raise ExploreError(f"{cls.__name__} has no field {name!r}")
