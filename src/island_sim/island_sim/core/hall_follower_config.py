"""The hall follower's configuration: turn policies, turn choices and `HallFollowerConfig`.

`HallFollowerConfig` is the single source of the follower's defaults (each field's help says
what it does and its unit; `"live"` fields may be changed while the follower runs, see
`HallFollower.reconfigure`). `parse_script` reads the scripted policy's turns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum

from island_msgs_py.errors import InputError
from island_msgs_py.hall_perception import HallPerceptionConfig

# Parameter range of the config's distances, speeds, gains and times (all must be >= 0).
_NON_NEGATIVE = (0.0, math.inf)


class HallFollowerError(InputError):
    """Bad configuration or bad `update` input; the message names the field."""


class TurnPolicy(StrEnum):
    """How the follower chooses at intersections and dead ends."""

    LEFT_HAND = "left_hand"  # prefer left, then straight, then right, then back
    RIGHT_HAND = "right_hand"  # prefer right, then straight, then left, then back
    SCRIPTED = "scripted"  # the next choice of `script`; left-hand order when unavailable/used up
    RANDOM = "random"  # uniformly among the available choices (seeded Generator)


class TurnChoice(StrEnum):
    LEFT = "left"
    STRAIGHT = "straight"
    RIGHT = "right"
    BACK = "back"


def parse_script(text: str) -> tuple[TurnChoice, ...]:
    """`"left, straight, right, back"` (or l/s/r/b) -> turn choices; empty text -> ()."""
    short = {"l": "left", "s": "straight", "r": "right", "b": "back"}
    out = []
    for part in text.replace(";", ",").split(","):
        p = part.strip().lower()
        if not p:
            continue
        try:
            out.append(TurnChoice(short.get(p, p)))
        except ValueError:
            raise HallFollowerError(
                f"HallFollowerConfig.script: unknown turn {part.strip()!r} "
                "(use left, straight, right, back)"
            ) from None
    return tuple(out)


@dataclass(frozen=True)
class HallFollowerConfig:
    """Parameters of the hall follower (distances from the robot centre)."""

    cruise_speed_mps: float = field(
        default=0.5,
        metadata={"help": "speed along halls [m/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    max_turn_rate_radps: float = field(
        default=1.0,
        metadata={"help": "largest commanded turn rate [rad/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    robot_radius_m: float = field(
        default=0.25,
        metadata={"help": "radius of the robot's body, for clearance checks [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    stop_distance_m: float = field(
        default=0.75,
        metadata={"help": "an obstacle ahead this close (from the robot centre) stops the "
                  "robot and forces a decision [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    slow_distance_m: float = field(
        default=2.0,
        metadata={"help": "the robot slows down linearly below this front range [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    path_margin_m: float = field(
        default=0.2,
        metadata={"help": "echoes ahead within robot_radius_m + this of the robot's path "
                  "count as obstacles in the way [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    narrow_margin_m: float = field(
        default=0.03,
        metadata={"help": "where a side wall stands closer than robot_radius_m + path_margin_m "
                  "(plus fit_tolerance_m), the path narrows to keep that wall's echoes out of "
                  "it, down to robot_radius_m + this [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    side_half_angle_deg: float = field(
        default=35.0,
        metadata={"help": "echoes within this of a side's perpendicular bearing are fitted as "
                  "that side's wall [deg]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    fit_tolerance_m: float = field(
        default=0.08,
        metadata={"help": "largest residual of a side wall fit still taken as one straight "
                  "wall; otherwise only the perpendicular distance is used [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    open_side_m: float = field(
        default=2.5,
        metadata={"help": "a side whose perpendicular range exceeds this is open [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    rearm_distance_m: float = field(
        default=1.0,
        metadata={"help": "travel with a side closed before an opening on it counts again [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    confirm_distance_m: float = field(
        default=0.1,
        metadata={"help": "travel with a side open before the opening counts (debounce) [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    default_hall_width_m: float = field(
        default=2.0,
        metadata={"help": "hallway width assumed before one has been measured [m]",
                  "range": _NON_NEGATIVE},
    )
    side_lag_m: float = field(
        default=0.2,
        metadata={"help": "travel past a corner before the side transducer's cone clears it; "
                  "subtracted from the advance to a side hallway's middle [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    min_advance_m: float = field(
        default=0.4,
        metadata={"help": "shortest drive from an opening to the turn [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    enter_distance_m: float = field(
        default=1.2,
        metadata={"help": "drive after a turn before following again [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    straight_free_m: float = field(
        default=3.0,
        metadata={"help": "at an opening, straight is a choice when the way ahead is free this "
                  "far [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    k_lateral: float = field(
        default=1.2,
        metadata={"help": "approach angle per metre off the hallway middle [rad/m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    max_approach_deg: float = field(
        default=20.0,
        metadata={"help": "largest angle to the hallway when re-centring [deg]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    k_heading: float = field(
        default=2.0,
        metadata={"help": "turn rate per radian of heading error [1/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    turn_tolerance_deg: float = field(
        default=1.5,
        metadata={"help": "a rotation in place ends within this of its target [deg]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    stall_time_s: float = field(
        default=1.0,
        metadata={"help": "driving forward while odometry shows (almost) no progress for this "
                  "long counts as blocked (a wall the sonar cannot see) [s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    backoff_m: float = field(
        default=0.3,
        metadata={"help": "after a stall the robot backs straight away this far before it "
                  "decides as at a wall (0: it decides where it stands) [m]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    backoff_speed_mps: float = field(
        default=0.15,
        metadata={"help": "backing speed [m/s]", "live": True, "range": _NON_NEGATIVE},
    )
    min_turn_rate_radps: float = field(
        default=0.15,
        metadata={"help": "smallest turn rate while rotating in place [rad/s]",
                  "live": True, "range": _NON_NEGATIVE},
    )
    policy: TurnPolicy = field(
        default=TurnPolicy.LEFT_HAND,
        metadata={"help": "turn policy: left_hand, right_hand, scripted, random",
                  "live": True},
    )
    script: str = field(
        default="",
        metadata={"help": "scripted policy: comma-separated turns (left, straight, right, back) "
                  "used one per decision",
                  "live": True},
    )

    def __post_init__(self) -> None:
        for f_name in (
            "cruise_speed_mps", "max_turn_rate_radps", "robot_radius_m", "stop_distance_m",
            "slow_distance_m", "path_margin_m", "narrow_margin_m", "side_half_angle_deg",
            "fit_tolerance_m", "open_side_m",
            "rearm_distance_m", "confirm_distance_m", "default_hall_width_m", "side_lag_m",
            "min_advance_m", "enter_distance_m", "straight_free_m", "k_lateral",
            "max_approach_deg", "k_heading", "turn_tolerance_deg", "min_turn_rate_radps",
            "stall_time_s", "backoff_m", "backoff_speed_mps",
        ):
            v = getattr(self, f_name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise HallFollowerError(f"HallFollowerConfig.{f_name}: expected a finite number, "
                                        f"got {v!r}")
            if v < 0:
                raise HallFollowerError(f"HallFollowerConfig.{f_name}: must be >= 0, got {v}")
        if self.stop_distance_m <= self.robot_radius_m:
            raise HallFollowerError(
                f"HallFollowerConfig.stop_distance_m ({self.stop_distance_m}) must exceed "
                f"robot_radius_m ({self.robot_radius_m})"
            )
        if self.slow_distance_m <= self.stop_distance_m:
            raise HallFollowerError(
                f"HallFollowerConfig.slow_distance_m ({self.slow_distance_m}) must exceed "
                f"stop_distance_m ({self.stop_distance_m})"
            )
        if not isinstance(self.policy, TurnPolicy):
            try:
                object.__setattr__(self, "policy", TurnPolicy(self.policy))
            except ValueError:
                raise HallFollowerError(
                    f"HallFollowerConfig.policy: unknown policy {self.policy!r} "
                    f"(use {', '.join(p.value for p in TurnPolicy)})"
                ) from None
        parse_script(self.script)

    @property
    def perception(self) -> HallPerceptionConfig:
        """The hallway perception these fields configure (shared with route following)."""
        return HallPerceptionConfig(self.robot_radius_m, self.path_margin_m,
                                    self.side_half_angle_deg, self.fit_tolerance_m,
                                    self.open_side_m, self.narrow_margin_m)

    @property
    def script_choices(self) -> tuple[TurnChoice, ...]:
        return parse_script(self.script)
