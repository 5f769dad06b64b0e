"""Side openings as places to attempt islands at: their configuration (`OpeningConfig`), part
of `BuilderConfig` (core.builder.config); what it drives is core.builder.opening."""

from __future__ import annotations

from dataclasses import dataclass, field

from island_mapping.core.builder.errors import check_numbers as _check


@dataclass(frozen=True)
class OpeningConfig:
    """Side openings (a doorway, a side hallway) the follower passes as places to attempt an
    island at: entered first, the star inside (core.builder.opening)."""

    enabled: bool = field(
        default=False,
        metadata={
            "help": "while following, a side opening (open over min_m of path, in a hallway) "
            "is a place: once epsilon > E_min the builder drives back to its middle, into it, "
            "and attempts there, whatever the quick check at the robot says [bool]"
        },
    )
    min_m: float = field(
        default=0.3, metadata={"help": "a side open over this much path is an opening [m]"}
    )
    hall_m: float = field(
        default=1.0,
        metadata={"help": "an opening counts only in a hallway: both sides walls over this "
                          "much path before it [m]"},
    )
    long_m: float = field(
        default=2.5,
        metadata={"help": "a side open over this much path is a wide opening, entered half "
                          "this far along [m]"},
    )
    stale_m: float = field(
        default=3.0,
        metadata={"help": "an opening not entered within this much path after its middle is "
                          "dropped (the robot was near the last island) [m]"},
    )
    hallway_recent_m: float = field(
        default=2.0,
        metadata={"help": "with openings on, the quick check may start an attempt only where "
                          "both sides were walls within this much path (a hallway, its corner "
                          "or end), not along a room's wall [m]"},
    )
    room_after_m: float = field(
        default=0.0,
        metadata={"help": "with openings on, after this much path along a room's walls with "
                          "no hallway (both sides walls) the quick check may start an attempt "
                          "there too: the room's own island (0: rooms only at their doors) [m]"},
    )
    behind_walls: bool = field(
        default=False,
        metadata={"help": "with openings on, the last island's vicinity (vicinity_m) ends "
                          "where a wall of its own model stands between its origin and the "
                          "robot: the room behind is another place [bool]"},
    )
    narrow_m: float = field(
        default=0.7,
        metadata={"help": "both side walls nearer than this (robot centre): a doorway's "
                          "passage [m]"},
    )
    past_m: float = field(
        default=0.6, metadata={"help": "the star starts this far past a passage's end [m]"}
    )
    room_in_m: float = field(
        default=2.0,
        metadata={"help": "through a doorway the star starts at least this far from the "
                          "hallway's middle: between the junction and the room behind it [m]"},
    )
    branch_m: float = field(
        default=1.2,
        metadata={"help": "into an opening that is no doorway (a side hallway) the star "
                          "starts this far in [m]"},
    )
    max_in_m: float = field(
        default=2.5, metadata={"help": "the longest drive into an opening [m]"}
    )
    clearance_m: float = field(
        default=0.5,
        metadata={"help": "the drive in stops this far (robot centre) before an obstacle in "
                          "its path [m]"},
    )

    def __post_init__(self) -> None:
        _check("OpeningConfig", self, ("min_m", "hall_m", "long_m", "stale_m", "hallway_recent_m",
                                       "room_after_m",
                                       "narrow_m", "past_m",
                                       "room_in_m", "branch_m", "max_in_m", "clearance_m"),
               strict=False)
