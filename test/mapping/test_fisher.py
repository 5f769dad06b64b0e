"""Fisher-information model type (Censi 2007): Jacobian rows, degeneracy and the score."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.fisher import (
    FisherConfig,
    FisherError,
    fisher_measure,
    information_matrices,
)
from island_mapping.core.rays import ray_angles
from island_msgs_py.raycast import raycast

SQUARE = np.array([[-2, -2, 2, -2], [2, -2, 2, 2], [2, 2, -2, 2], [-2, 2, -2, -2]], float)
CORRIDOR = np.array([[-60, -1.5, 60, -1.5], [-60, 1.5, 60, 1.5]], float)
ROOM_WITH_BOX = np.concatenate([SQUARE, [[0.5, 0.8, 1.2, 0.8], [1.2, 0.8, 1.2, 1.4]]])


def numeric_information(walls: np.ndarray, p: np.ndarray, cfg: FisherConfig) -> np.ndarray:
    """sum J^T J / sigma^2 with J from central differences of ray-cast ranges."""
    angles = ray_angles(cfg.angular_res_deg)
    cos_min = math.cos(math.radians(cfg.reflect_deg)) - 1e-12  # same tie rule as the model
    base = raycast(walls, np.array([p]), angles, cfg.max_range_m)
    info = np.zeros((3, 3))
    h = 1e-6
    for j, a in enumerate(angles):
        if base.segment[j] < 0 or base.cos_incidence[j] < cos_min:
            continue

        def rng_at(dx: float, dy: float, dth: float, a: float = a) -> float:
            hit = raycast(walls, np.array([[p[0] + dx, p[1] + dy]]), np.array([a + dth]))
            return float(hit.distance_m[0])

        jac = np.array([
            (rng_at(h, 0, 0) - rng_at(-h, 0, 0)) / (2 * h),
            (rng_at(0, h, 0) - rng_at(0, -h, 0)) / (2 * h),
            (rng_at(0, 0, h) - rng_at(0, 0, -h)) / (2 * h),
        ])
        sigma = cfg.sigma_m + cfg.sigma_per_m * base.distance_m[j]
        info += np.outer(jac, jac) / sigma**2
    return info


@pytest.mark.parametrize("p", [(0.3, -0.4), (-1.1, 0.9)])
def test_information_equals_finite_difference_jacobians(p: tuple[float, float]) -> None:
    cfg = FisherConfig(angular_res_deg=7.0)
    analytic = information_matrices(ROOM_WITH_BOX, [p], cfg)[0]
    numeric = numeric_information(ROOM_WITH_BOX, np.array(p), cfg)
    assert np.allclose(analytic, numeric, rtol=1e-4, atol=1e-2 * np.abs(numeric).max() * 1e-3)


def test_corridor_is_degenerate_and_room_is_well_conditioned() -> None:
    corridor = fisher_measure(CORRIDOR, [[0.0, 0.0], [5.0, 0.9]])
    assert np.all(corridor.min_eig == 0.0) and np.all(np.isinf(corridor.cond))
    assert np.all(corridor.score == 0.0)
    room = fisher_measure(SQUARE, [[0.0, 0.0]])
    assert room.cond[0] == pytest.approx(1.0, abs=1e-6)
    assert room.score[0] > 0.5
    assert room.min_eig[0] > 1.0 / FisherConfig().std_ref_m**2


def test_score_falls_as_the_walls_recede() -> None:
    near = fisher_measure(SQUARE, [[0.0, 0.0]])
    far = fisher_measure(SQUARE * 3.0, [[0.0, 0.0]], FisherConfig(max_range_m=20.0))
    assert far.min_eig[0] < near.min_eig[0] and far.score[0] < near.score[0]


def test_score_is_rotation_invariant_for_ray_aligned_turns() -> None:
    cfg = FisherConfig(angular_res_deg=1.0)
    base = fisher_measure(ROOM_WITH_BOX, [[0.2, -0.3]], cfg)
    rot = ROOM_WITH_BOX[:, [1, 0, 3, 2]] * np.array([-1, 1, -1, 1])  # +90 deg about the origin
    turned = fisher_measure(rot, [[0.3, 0.2]], cfg)
    assert turned.min_eig[0] == pytest.approx(base.min_eig[0], rel=1e-6)
    assert turned.score[0] == pytest.approx(base.score[0], rel=1e-6)


def test_bad_config_is_named() -> None:
    with pytest.raises(FisherError, match="sigma"):
        FisherConfig(sigma_m=0.0)
    with pytest.raises(FisherError, match="reflect_deg"):
        FisherConfig(reflect_deg=95.0)
