"""An arrival whose estimate is known well (odometry since the island) refuses a fit that
left it farther than max_shift_m: it is not trusted, and no search along the hallway follows."""

from __future__ import annotations

import math

import numpy as np
from island_mapping.core.route import NavigateConfig, localize_multi
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

# A 6 m x 4 m room around the origin: every fit is well constrained.
WALLS = np.array([[-3.0, -2.0, 3.0, -2.0], [3.0, -2.0, 3.0, 2.0],
                  [3.0, 2.0, -3.0, 2.0], [-3.0, 2.0, -3.0, -2.0]])


def _points(rng: np.random.Generator) -> np.ndarray:
    """Echoes along every wall seen from the origin facing theta 0, 2 cm noise."""
    t = rng.uniform(0.05, 0.95, size=(40, 1))
    w = WALLS[rng.integers(len(WALLS), size=40)]
    pts = w[:, :2] + t * (w[:, 2:] - w[:, :2])
    return pts + rng.normal(0.0, 0.02, size=pts.shape)


def test_a_fit_far_from_a_well_known_estimate_is_not_trusted() -> None:
    island = Island(0, LineModel(WALLS), ModelType.LINE, 1.0, 0.0)
    pts = _points(np.random.default_rng(3))
    estimate = Pose2D(1.3, 0.0, math.radians(3.0))  # the robot is truly at the origin
    res, trusted = localize_multi(island, pts, estimate, NavigateConfig())
    assert trusted and math.hypot(res.pose.x, res.pose.y) < 0.1
    _, trusted_near = localize_multi(island, pts, estimate, NavigateConfig(), max_shift_m=1.0)
    assert not trusted_near
    _, trusted_wide = localize_multi(island, pts, estimate, NavigateConfig(), max_shift_m=2.0)
    assert trusted_wide
