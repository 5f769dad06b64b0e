"""The distinctiveness measure R (eqs. 4-12): hand-checkable cases and invariances."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from island_mapping.core.measure import (
    MeasureConfig,
    MeasureError,
    cast_rays,
    eps_offsets,
    evaluate_models,
    line_measure,
    measure_from_bundle,
    measure_map,
    sigmoid_filter,
)
from island_msgs_py.types import ModelType

CORRIDOR = np.array([[-60, -1.5, 60, -1.5], [-60, 1.5, 60, 1.5]], float)
SQUARE = np.array([[-2, -2, 2, -2], [2, -2, 2, 2], [2, 2, -2, 2], [-2, 2, -2, -2]], float)


def rotate(segments: np.ndarray, angle: float, centre: np.ndarray) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    pts = segments.reshape(-1, 2) - centre
    return (pts @ rot.T + centre).reshape(-1, 4)


def test_long_corridor_has_no_perpendicular_constraint_and_r_zero() -> None:
    res = line_measure(CORRIDOR, [[0.0, 0.0], [10.0, 0.7], [-20.0, -1.0]])
    assert np.all(res.c_par > 1.0)
    assert np.allclose(res.c_perp, 0.0, atol=1e-9)
    assert np.allclose(res.r, 0.0) and np.allclose(res.q, 0.0) and np.allclose(res.f, 0.0)


def test_centre_of_a_square_room_has_equal_constraints() -> None:
    res = line_measure(SQUARE, [[0.0, 0.0]])
    assert res.c_par[0] == pytest.approx(res.c_perp[0], rel=1e-9)
    assert res.q[0] == pytest.approx(1.0)
    assert res.r[0] == pytest.approx(res.f[0]) and res.r[0] > 0.9


def test_single_wall_sum_matches_an_independent_quadrature() -> None:
    cfg = MeasureConfig(k=0.4, reflect_deg=30.0, angular_res_deg=1.0, max_range_m=6.5)
    wall = np.array([[-100.0, 2.0, 100.0, 2.0]])
    res = line_measure(wall, [[0.0, 0.0]], cfg)
    # Ray j at j deg; it hits y=2 at d = 2/sin(a) with |N.u| = sin(a); counted if the incidence
    # angle 90 - a <= 30 deg.
    a = np.radians(np.arange(360.0))
    s = np.sin(a)
    ok = (s > 0) & (np.degrees(np.abs(np.pi / 2 - a)) <= 30.0 + 1e-9)
    expected = np.sum(np.exp(-0.4 * 2.0 / s[ok]) * s[ok]) * math.radians(1.0)
    assert res.c_par[0] == pytest.approx(expected, rel=1e-9)
    assert res.c_perp[0] == pytest.approx(0.0, abs=1e-12)


def test_walls_beyond_range_and_behind_other_walls_do_not_count() -> None:
    cfg = MeasureConfig(max_range_m=3.0)
    near = np.array([[-50.0, 1.0, 50.0, 1.0]])
    both = np.concatenate([near, [[-50.0, 2.0, 50.0, 2.0]]])  # hidden behind `near`
    far = np.array([[-50.0, 3.5, 50.0, 3.5]])
    assert line_measure(both, [[0, 0]], cfg).c_par[0] == pytest.approx(
        line_measure(near, [[0, 0]], cfg).c_par[0]
    )
    assert line_measure(far, [[0, 0]], cfg).c_par[0] == 0.0


def test_smaller_reflectance_threshold_counts_fewer_rays() -> None:
    wide = line_measure(SQUARE, [[0.5, 0.3]], MeasureConfig(reflect_deg=45.0))
    narrow = line_measure(SQUARE, [[0.5, 0.3]], MeasureConfig(reflect_deg=10.0))
    assert narrow.c_par[0] < wide.c_par[0] and narrow.c_perp[0] < wide.c_perp[0]


def test_symmetric_points_of_a_symmetric_room_have_equal_measures() -> None:
    pts = np.array([[0.7, 0.4], [-0.7, 0.4], [0.7, -0.4], [-0.7, -0.4], [0.4, 0.7]])
    res = line_measure(SQUARE, pts, MeasureConfig(angular_res_deg=1.0))
    assert np.allclose(res.r, res.r[0], atol=2e-3)
    assert np.allclose(res.c_par + res.c_perp, (res.c_par + res.c_perp)[0], rtol=5e-3)


@pytest.mark.parametrize("angle_deg", [90.0, 30.0, 137.0])
def test_rotating_world_and_point_together_leaves_the_measure_unchanged(angle_deg: float) -> None:
    world = np.concatenate([SQUARE, [[-2.0, 0.5, -0.5, 0.5]]])  # a partition wall
    p = np.array([0.6, -0.9])
    cfg = MeasureConfig(angular_res_deg=0.5)
    base = line_measure(world, [p], cfg)
    centre = np.array([0.3, 0.1])
    rot = rotate(world, math.radians(angle_deg), centre)
    p_rot = rotate(np.r_[p, p][None, :], math.radians(angle_deg), centre)[0, 0:2]
    turned = line_measure(rot, [p_rot], cfg)
    # A rotation by a multiple of the ray spacing is exact; other angles shift the ray sampling.
    tol = 1e-9 if (angle_deg / 0.5).is_integer() else 0.02
    assert turned.c_par[0] == pytest.approx(base.c_par[0], rel=tol, abs=tol)
    assert turned.c_perp[0] == pytest.approx(base.c_perp[0], rel=tol, abs=tol)
    assert turned.r[0] == pytest.approx(base.r[0], abs=max(tol, 1e-9))


def test_sigmoid_filter_and_quality_follow_eqs_11_and_12() -> None:
    c = np.array([0.0, 0.5, 1.0, 2.0])
    assert np.allclose(sigmoid_filter(c, 1.0, 2.0), [0.0, 0.25 / 1.25, 0.5, 4.0 / 5.0])
    # Q = min/max of the filtered pair; r = F(1+Q)/2 with F = min.
    cfg = MeasureConfig(c=1.0, m=2.0)
    bundle = cast_rays(SQUARE, [[0.9, 0.0]], cfg.angular_res_deg, cfg.max_range_m,
                       cfg.reflect_deg)
    res = measure_from_bundle(bundle, cfg)
    fp, fq = sigmoid_filter(res.c_par, 1.0, 2.0)[0], sigmoid_filter(res.c_perp, 1.0, 2.0)[0]
    lo, hi = min(fp, fq), max(fp, fq)
    assert res.f[0] == pytest.approx(lo)
    assert res.q[0] == pytest.approx(lo / hi)
    assert res.r[0] == pytest.approx(lo * (1 + lo / hi) / 2)


def test_no_visible_wall_gives_q_zero_not_nan() -> None:
    res = line_measure(np.array([[100.0, 0.0, 100.0, 5.0]]), [[0.0, 0.0]])
    assert res.c_par[0] == 0.0 and res.q[0] == 0.0 and res.r[0] == 0.0


def test_eps_averages_r_over_the_square_grid() -> None:
    cfg = MeasureConfig(eps_m=0.2, eps_step_m=0.1)
    offs = eps_offsets(0.2, 0.1)
    assert offs.shape == (25, 2) and np.isclose(offs.max(), 0.2)
    p = np.array([0.8, 1.1])
    res = line_measure(SQUARE, [p], cfg)
    direct = line_measure(SQUARE, p + offs, MeasureConfig()).r.mean()
    assert res.r_eps[0] == pytest.approx(direct)
    assert res.r_eps[0] != pytest.approx(res.r[0])


def test_measure_map_agrees_with_pointwise_values_and_has_grid_shape() -> None:
    xs, ys, grid = measure_map(SQUARE, (-2.0, -2.0, 2.0, 1.0), 0.5)
    assert xs.shape == (8,) and ys.shape == (6,) and grid.shape == (6, 8)
    assert xs[0] == pytest.approx(-1.75) and ys[-1] == pytest.approx(0.75)
    one = line_measure(SQUARE, [[xs[3], ys[2]]]).r[0]
    assert grid[2, 3] == pytest.approx(one)


def test_chunked_and_single_calls_agree() -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1.9, 1.9, (300, 2))
    all_at_once = line_measure(SQUARE, pts).r
    one_by_one = np.array([line_measure(SQUARE, [p]).r[0] for p in pts[:20]])
    assert np.allclose(all_at_once[:20], one_by_one)


def test_bad_input_is_named() -> None:
    with pytest.raises(MeasureError, match=r"MeasureConfig\.c"):
        MeasureConfig(c=0.0)
    with pytest.raises(MeasureError, match="reflect_deg"):
        MeasureConfig(reflect_deg=120.0)
    with pytest.raises(MeasureError, match="points"):
        line_measure(SQUARE, [[0.0, np.nan]])
    with pytest.raises(ValueError, match="segments"):
        line_measure(np.zeros((2, 3)), [[0.0, 0.0]])


def test_evaluate_models_gives_both_model_types() -> None:
    vals = evaluate_models(SQUARE, np.array([0.0, 0.0]))
    assert set(vals) == {ModelType.LINE, ModelType.FISHER}
    assert vals[ModelType.LINE] > 0.9 and vals[ModelType.FISHER] > 0.5
    corridor = evaluate_models(CORRIDOR, np.array([0.0, 0.0]))
    assert corridor[ModelType.LINE] == 0.0 and corridor[ModelType.FISHER] < 0.01


def test_island_cores_do_not_import_rclpy() -> None:
    code = (
        "import sys\n"
        "import island_mapping.core.lines, island_mapping.core.localize\n"
        "import island_mapping.core.measure, island_mapping.core.fisher\n"
        "import island_mapping.evaluation.validation\n"
        "bad = [m for m in sys.modules if m.startswith(('rclpy', 'matplotlib'))]\n"
        "assert not bad, bad\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_map_with_eps_on_its_own_grid_equals_pointwise_averages() -> None:
    cfg = MeasureConfig(eps_m=0.5, eps_step_m=0.25)
    xs, ys, grid = measure_map(SQUARE, (-2.0, -2.0, 2.0, 2.0), 0.25, cfg)
    assert grid.shape == (16, 16)
    pts = np.array([[xs[i], ys[j]] for j, i in [(0, 0), (3, 7), (8, 8), (15, 2)]])
    direct = line_measure(SQUARE, pts, cfg).r_eps
    got = np.array([grid[j, i] for j, i in [(0, 0), (3, 7), (8, 8), (15, 2)]])
    assert np.allclose(got, direct, atol=1e-12)


def test_tiled_casting_gives_exactly_the_untiled_result(monkeypatch) -> None:
    import island_mapping.core.rays as rays_mod
    from island_mapping.core.fisher import fisher_measure

    rng = np.random.default_rng(8)
    a = rng.uniform(0.0, 25.0, (60, 2))
    ang = rng.uniform(0.0, math.pi, 60)
    length = rng.uniform(0.5, 4.0, 60)
    walls = np.c_[a, a + length[:, None] * np.c_[np.cos(ang), np.sin(ang)]]
    pts = rng.uniform(0.0, 25.0, (400, 2))
    tiled = line_measure(walls, pts)
    tiled_f = fisher_measure(walls, pts)
    monkeypatch.setattr(rays_mod, "_TILE_MIN_SEGMENTS", 10**9)
    whole = line_measure(walls, pts)
    whole_f = fisher_measure(walls, pts)
    assert np.array_equal(tiled.c_par, whole.c_par) and np.array_equal(tiled.r, whole.r)
    assert np.array_equal(tiled_f.info, whole_f.info)
    assert np.count_nonzero(whole.c_par) > 300  # the world is not trivially empty
