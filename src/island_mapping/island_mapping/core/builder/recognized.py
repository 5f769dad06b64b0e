"""What a recognition reasons from and finds (`core.builder.recognition`): the robot's
snapshot and a known island found in the scan points."""

from __future__ import annotations

from dataclasses import dataclass

from island_msgs_py.types import FloatArray, Pose2D


@dataclass(frozen=True)
class Recognition:
    """A known island found in the scan points: the robot's pose in its frame."""

    island_id: int
    pose: Pose2D  # the robot in the island frame [m, rad]
    residual_m: float
    inlier_fraction: float
    # How far the recognised pose lies from the odometric estimates, in their sigmas: the
    # largest squared Mahalanobis distance over (x, y, theta) under each estimate's full
    # covariance (`Recognizer.spreads`) [-]; None when not computed.
    mahalanobis2: float | None = None
    # The direction the robot came from, in the island frame (set by the builder before its
    # revisit gate; None: unknown) [rad].
    arrival_rad: float | None = None


@dataclass(frozen=True)
class PoseSnapshot:
    """The robot's state a recognition reasons from.

    odom: odometric pose [m, rad]; odom_cov: the odometry's 3x3 covariance (the drift since
    an island's origin was last known grows from it); epsilon_m and heading_sigma_rad: the
    error since the last island's origin (eq. 3); last_island_id: the island left last (None:
    none yet); path_since_island_m: odometric path followed since leaving it [m].
    """

    odom: Pose2D
    odom_cov: FloatArray
    epsilon_m: float
    heading_sigma_rad: float
    last_island_id: int | None
    path_since_island_m: float
