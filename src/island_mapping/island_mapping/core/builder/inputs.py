"""What the builder takes in: checked scans and odometry, and what the stamp pairer released.

The node pairs scans with odometry by stamp with the project's one pairer
(`island_msgs_py.stamps.ScanOdomPairer` with `every_odometry=True` and a ground-truth stream):
each scan is decided with the odometry of its own stamp, after every odometry increment up to
it (eq. 3 integrates them all). `feed` applies what the pairer released, in order; `checked_scan`
and `checked_cov` refuse bad input before it is buffered, so a bad message never reaches the
pairer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np
import numpy.typing as npt
from island_msgs_py.stamps import OdometrySample, Paired, Released, StreamSample
from island_msgs_py.types import FloatArray, Pose2D

from island_mapping.core.builder.config import BuilderError
from island_mapping.core.builder.events import BuilderCommand

GROUND_TRUTH = "ground_truth"
"""The pairer's stream of true poses (evaluation only: islands' origin_truth)."""

ScanArrays = tuple[FloatArray, FloatArray]
"""(ranges [m], angles [rad]) of one scan."""


class BuilderInputs(Protocol):
    """What `feed` drives (an IslandBuilder)."""

    def on_odometry(self, t_s: float, odom_pose: Pose2D, cov3x3: npt.ArrayLike) -> None: ...

    def on_ground_truth(self, pose: Pose2D) -> None: ...

    def on_scan(self, t_s: float, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike) -> None: ...

    def command(self, t_s: float) -> BuilderCommand: ...


def checked_cov(t_s: float, cov3x3: npt.ArrayLike) -> FloatArray:
    """An odometry covariance as a finite 3x3 array, or BuilderError."""
    cov = np.asarray(cov3x3, dtype=np.float64)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise BuilderError(
            f"on_odometry: covariance must be a finite 3x3 matrix, got shape {cov.shape}"
        )
    if not math.isfinite(t_s):
        raise BuilderError(f"on_odometry: time must be finite, got {t_s}")
    return cov


def checked_scan(t_s: float, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike
                 ) -> ScanArrays:
    """A scan as two flat float arrays of one length, or BuilderError."""
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if r.shape != a.shape:
        raise BuilderError(f"on_scan: {r.shape[0]} ranges but {a.shape[0]} angles")
    if not math.isfinite(t_s):
        raise BuilderError(f"on_scan: time must be finite, got {t_s}")
    return r, a


def feed(builder: BuilderInputs, released: Sequence[Released[ScanArrays]]
         ) -> list[tuple[int, BuilderCommand]]:
    """Apply what the pairer released, in order: odometry, true poses, and scans (each followed
    by the builder's command); returns (scan stamp [ns], command) per scan."""
    out: list[tuple[int, BuilderCommand]] = []
    for item in released:
        if isinstance(item, OdometrySample):
            if item.cov is None:
                raise BuilderError("odometry: the builder needs its covariance (got none)")
            builder.on_odometry(item.stamp_ns * 1e-9, item.pose, item.cov)
        elif isinstance(item, StreamSample):
            if item.stream == GROUND_TRUTH:
                builder.on_ground_truth(item.pose)
        elif isinstance(item, Paired):
            t_s = item.stamp_ns * 1e-9
            builder.on_scan(t_s, *item.payload)
            out.append((item.stamp_ns, builder.command(t_s)))
    return out
