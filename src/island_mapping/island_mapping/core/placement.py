"""Where did the islands land? An independent geometric check against the world's walls.

Evaluation runs it on the simulator's walls (ground truth the builder never sees); the
builder runs the same rule on its own sonar line model (BuilderConfig.origin_feature_radius_m).
A place is classified by the walls *visible* from it within `radius_m` (rays every
`angular_res_deg`, first hit only, so walls behind walls do not count):

- PLAIN_HALLWAY: every visible wall is parallel to the others — the robot sees straight walls
  and nothing that fixes its position along them;
- FEATURE: visible walls in two or more directions — intersections, door jambs, room openings
  and corners, corridor ends;
- OPEN_SPACE: no wall visible within the radius (the middle of a big room).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from island_msgs_py.raycast import raycast
from island_msgs_py.types import FloatArray, Pose2D

PARALLEL_TOL_DEG = 10.0
"""Walls within this angle of each other count as parallel (the worlds are drawn axis-aligned)."""


class PlaceKind(StrEnum):
    PLAIN_HALLWAY = "plain_hallway"
    FEATURE = "feature"
    OPEN_SPACE = "open_space"


@dataclass(frozen=True)
class PlacementConfig:
    radius_m: float = field(
        default=3.0,
        metadata={"help": "walls visible within this distance describe a place: the star legs' "
                          "reach (1.2 m) plus the range of dense sonar echoes for line fits [m]"},
    )
    angular_res_deg: float = field(default=1.0, metadata={"help": "ray spacing [deg]"})


def classify_place(
    segments: FloatArray, x_m: float, y_m: float, cfg: PlacementConfig | None = None
) -> PlaceKind:
    """The kind of place at (x, y) [m] among world wall `segments` (N, 4) [m]."""
    c = cfg or PlacementConfig()
    angles = np.radians(np.arange(0.0, 360.0, c.angular_res_deg))
    hits = raycast(segments, np.array([[x_m, y_m]]), angles, c.radius_m)
    seen = np.unique(hits.segment[hits.segment >= 0])
    if seen.size == 0:
        return PlaceKind.OPEN_SPACE
    near = segments[seen]
    direction = np.arctan2(near[:, 3] - near[:, 1], near[:, 2] - near[:, 0]) % np.pi
    diff = np.abs(direction[:, None] - direction[None, :])
    diff = np.minimum(diff, np.pi - diff)
    if np.all(diff <= np.radians(PARALLEL_TOL_DEG)):
        return PlaceKind.PLAIN_HALLWAY
    return PlaceKind.FEATURE


def feature_distance_m(
    segments: FloatArray, x_m: float, y_m: float, max_m: float = 6.5, step_m: float = 0.25
) -> float:
    """Smallest visibility radius [m] (in steps of `step_m`) at which the place at (x, y) is a
    FEATURE (walls in two directions visible); `inf` if none is up to `max_m`."""
    n = round(max_m / step_m)
    for k in range(1, n + 1):
        r = k * step_m
        if classify_place(segments, x_m, y_m, PlacementConfig(radius_m=r)) is PlaceKind.FEATURE:
            return r
    return float("inf")


def placement_counts(
    segments: FloatArray, places: Iterable[Pose2D], cfg: PlacementConfig | None = None
) -> dict[str, int]:
    """How many of `places` fall in each PlaceKind (every kind listed, zeros included)."""
    counts = Counter(classify_place(segments, p.x, p.y, cfg) for p in places)
    return {k.value: int(counts.get(k, 0)) for k in PlaceKind}
