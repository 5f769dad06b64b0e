"""Localization in the island the robot is near, scan after scan (island_localizer_node's core).

Pure (numpy; no simulator, no ROS). Each island's origin is known in the odometry frame when it
is added (where it was built); the points of the last `window_scans` scans, placed by odometry,
are localized against the nearest island's line model every `every_n_scans` scans, and every
trusted fix re-places that origin so the estimate follows the odometry's drift.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import ranges_to_points, to_frame
from island_msgs_py.types import FloatArray, Island, Pose2D

from island_mapping.core.localize import LocalizeConfig, localize, point_to_line_config


class TrackerError(InputError):
    """A TrackerConfig value is invalid (the message names it)."""


@dataclass(frozen=True)
class TrackerConfig:
    """Continuous localization in the nearest island while the robot is within its model."""

    window_scans: int = field(
        default=20, metadata={"help": "scans whose points (by odometry) are localized together [-]"}
    )
    every_n_scans: int = field(
        default=5, metadata={"help": "localize on every n-th scan (CPU budget) [-]"}
    )
    max_extent_m: float = field(
        default=8.0,
        metadata={
            "help": "an island counts as near within its model's extent (farthest "
            "endpoint from its origin), capped at this [m]"
        },
    )
    max_residual_m: float = field(
        default=0.15, metadata={"help": "a localization with a larger RMS residual is ignored [m]"}
    )
    localize: LocalizeConfig = field(
        default_factory=point_to_line_config,
        metadata={"help": "line-model localization (point-to-line Gauss-Newton)"},
    )

    def __post_init__(self) -> None:
        if self.window_scans < 1 or self.every_n_scans < 1:
            raise TrackerError("TrackerConfig: window_scans and every_n_scans must be >= 1")
        if not (math.isfinite(self.max_extent_m) and self.max_extent_m > 0):
            raise TrackerError(f"TrackerConfig.max_extent_m: must be > 0, got {self.max_extent_m}")


@dataclass(frozen=True)
class IslandFix:
    """A localization in an island's frame: pose [m, rad], 3x3 covariance, the island."""

    island_id: int
    frame_id: str
    pose: Pose2D
    covariance: FloatArray
    residual_m: float


class IslandTracker:
    """Localizes the robot in the island it is near, scan after scan, from odometry.

    Each island's origin is known in the odometry frame when it is added (where it was built);
    every trusted localization refines that placement, so the estimate follows the drift.
    """

    def __init__(self, config: TrackerConfig | None = None) -> None:
        self.config = config if config is not None else TrackerConfig()
        self._islands: dict[
            int, tuple[Island, Pose2D, float]
        ] = {}  # id -> (island, origin, extent)
        self._window: list[FloatArray] = []  # recent scan points in the odometry frame [m]
        self._count = 0
        self.fixes = 0

    def add_island(self, island: Island, origin_odom: Pose2D) -> None:
        """An island and the odometry pose of its origin."""
        seg = island.model.segments
        ext = float(np.max(np.hypot(seg[:, [0, 2]], seg[:, [1, 3]]))) if len(seg) else 0.0
        self._islands[island.id] = (island, origin_odom, min(ext, self.config.max_extent_m))

    def origin_odom(self, island_id: int) -> Pose2D:
        return self._islands[island_id][1]

    def nearest(self, odom_pose: Pose2D) -> int | None:
        """The island whose origin is nearest, if the robot is within that island's extent."""
        best, best_d = None, math.inf
        for i, (_, origin, ext) in self._islands.items():
            d = math.hypot(odom_pose.x - origin.x, odom_pose.y - origin.y)
            if d <= ext and d < best_d:
                best, best_d = i, d
        return best

    def on_scan(
        self, odom_pose: Pose2D, ranges_m: FloatArray, angles_rad: FloatArray
    ) -> IslandFix | None:
        """Add a scan (robot frame) at an odometry pose; a fix when one is due and trusted."""
        self._window.append(ranges_to_points(ranges_m, angles_rad, odom_pose))
        del self._window[: -self.config.window_scans]
        self._count += 1
        if self._count % self.config.every_n_scans:
            return None
        near = self.nearest(odom_pose)
        if near is None:
            return None
        island, origin, ext = self._islands[near]
        robot_pts = to_frame(np.concatenate(self._window, axis=0), odom_pose)
        res = localize(island.model, robot_pts, odom_pose.relative_to(origin), self.config.localize)
        if not res.converged or res.residual_m > self.config.max_residual_m:
            return None
        # Re-place the island origin in the odometry frame so the two agree now.
        self._islands[near] = (island, odom_pose.compose(res.pose.inverse()), ext)
        self.fixes += 1
        var = max(res.residual_m, 0.01) ** 2 / max(res.constraint, 1e-3)
        cov = np.diag([var, var, var / 4.0])  # heading var: residual over a ~2 m lever [rad^2]
        return IslandFix(island.id, island.frame_id, res.pose, cov, res.residual_m)
