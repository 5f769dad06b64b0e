"""Pose algebra on (N, 3) arrays of poses (x [m], y [m], theta [rad]) (pure: numpy only).

The builder works on single `Pose2D`s; logs, relations and the passive builder work on arrays of
poses, row by row.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


class PoseError(ValueError):
    """Pose arrays of the wrong shape; the message names the argument."""


def wrap_angles(theta_rad: npt.ArrayLike) -> FloatArray:
    """Wrap angles [rad] to [-pi, pi)."""
    a = np.asarray(theta_rad, dtype=np.float64)
    return np.asarray((a + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


def _as_poses(a: npt.ArrayLike, name: str) -> FloatArray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise PoseError(f"{name}: expected (N, 3) poses (x, y, theta), got {arr.shape}")
    return arr


def relative_poses(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """Poses b expressed in the frames of poses a (a^-1 (+) b), row by row; (N, 3)."""
    pa, pb = _as_poses(a, "a"), _as_poses(b, "b")
    c, s = np.cos(pa[:, 2]), np.sin(pa[:, 2])
    dx, dy = pb[:, 0] - pa[:, 0], pb[:, 1] - pa[:, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angles(pb[:, 2] - pa[:, 2])], axis=1)


def compose_poses(a: npt.ArrayLike, b: npt.ArrayLike) -> FloatArray:
    """a (+) b row by row: b given in the frame of a, returned in a's parent frame; (N, 3)."""
    pa, pb = _as_poses(a, "a"), _as_poses(b, "b")
    c, s = np.cos(pa[:, 2]), np.sin(pa[:, 2])
    return np.stack(
        [
            pa[:, 0] + c * pb[:, 0] - s * pb[:, 1],
            pa[:, 1] + s * pb[:, 0] + c * pb[:, 1],
            wrap_angles(pa[:, 2] + pb[:, 2]),
        ],
        axis=1,
    )


def transform_points(pose: npt.ArrayLike, points: npt.ArrayLike) -> FloatArray:
    """(N, 2) points [m] given in the frame of `pose` (x, y, theta), returned in its parent."""
    p = np.asarray(pose, dtype=np.float64).reshape(3)
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    c, s = math.cos(p[2]), math.sin(p[2])
    return np.stack([p[0] + c * pts[:, 0] - s * pts[:, 1], p[1] + s * pts[:, 0] + c * pts[:, 1]], 1)
