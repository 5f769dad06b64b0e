"""Validation of the measures against simulated localization (paper 8.1), on a small world."""

from __future__ import annotations

import math

import numpy as np
import pytest
from island_mapping.core.measure import MeasureConfig, cast_rays, inside_outline
from island_mapping.evaluation.validation import (
    ConfidenceMap,
    ValidationConfig,
    ValidationError,
    compare,
    confidence_map,
    fit_line_parameters,
    free_points,
    line_values,
    normalize,
    roc_auc,
    run_validation,
)
from island_sim.core.world import World

# A 8 x 6 m room opening into a 2 m wide corridor 32 m long (closed outline, counter-clockwise).
OUTLINE = [(0, 0), (8, 0), (8, 2), (40, 2), (40, 4), (8, 4), (8, 6), (0, 6)]
ROOM_CORRIDOR = World(
    np.array([[*OUTLINE[i], *OUTLINE[(i + 1) % len(OUTLINE)]] for i in range(len(OUTLINE))],
             dtype=float),
    name="room_corridor",
)
ROOM_PTS = np.array([[4.0, 3.0], [2.0, 2.0], [6.0, 4.5]])
CORRIDOR_PTS = np.array([[22.0, 3.0], [24.0, 2.8], [26.0, 3.2]])  # > 6.5 m from both ends
FAST = ValidationConfig(resolution_m=1.0, trials=2, scans_per_trial=2, seed=3)


def test_roc_auc_on_known_rankings() -> None:
    assert roc_auc([0.1, 0.2, 0.8, 0.9], [False, False, True, True]) == 1.0
    assert roc_auc([0.9, 0.8, 0.2, 0.1], [False, False, True, True]) == 0.0
    assert roc_auc([0.5, 0.5, 0.5, 0.5], [False, True, False, True]) == 0.5
    assert math.isnan(roc_auc([0.1, 0.2], [True, True]))


def test_normalize_divides_by_the_maximum() -> None:
    assert np.allclose(normalize([0.0, 0.2, 0.4]), [0.0, 0.5, 1.0])
    assert np.allclose(normalize([0.0, 0.0]), [0.0, 0.0])


def _conf(values: list[float], success: list[bool]) -> ConfidenceMap:
    n = len(values)
    return ConfidenceMap(np.zeros((n, 2)), np.zeros((n, 1)), np.ones((n, 1), bool),
                         np.array(values), np.array(success))


def test_compare_perfect_and_poor_agreement() -> None:
    conf = _conf([0.0, 0.25, 0.5, 1.0], [False, False, True, True])
    good = compare([0.0, 0.5, 1.0, 2.0], conf)  # normalized: 0, .25, .5, 1
    assert good.frac_residual_gt == 0.0 and good.spearman == pytest.approx(1.0)
    assert good.auc == 1.0 and good.n_points == 4
    bad = compare([2.0, 1.0, 0.5, 0.0], conf)
    assert bad.frac_residual_gt == 0.5 and bad.spearman == pytest.approx(-1.0) and bad.auc == 0.0
    with pytest.raises(ValidationError, match="measure values"):
        compare([1.0, 2.0], conf)


def test_free_points_are_inside_and_clear_of_walls() -> None:
    _, _, pts, mask = free_points(ROOM_CORRIDOR, 0.5, ValidationConfig(clearance_m=0.3))
    assert pts.shape[0] == int(mask.sum()) > 100
    assert np.all(inside_outline(ROOM_CORRIDOR, pts))
    in_room = (pts[:, 0] < 8.0) & (pts[:, 0] > 0.0)
    in_corr = (pts[:, 0] >= 8.0) & (pts[:, 1] > 2.0) & (pts[:, 1] < 4.0)
    assert np.all(in_room | in_corr)
    assert not np.any((pts[:, 0] > 9.0) & ((pts[:, 1] < 2.3) | (pts[:, 1] > 3.7)))


def test_confidence_is_high_in_the_room_and_low_mid_corridor() -> None:
    pts = np.concatenate([ROOM_PTS, CORRIDOR_PTS])
    cm = confidence_map(ROOM_CORRIDOR, pts, ValidationConfig(trials=3, seed=1))
    assert np.all(cm.confidence[:3] > 0.9) and np.all(cm.success[:3])
    assert np.all(cm.confidence[3:] < 0.2) and not np.any(cm.success[3:])
    assert not np.any(cm.converged[3:])  # the localizer itself says so
    again = confidence_map(ROOM_CORRIDOR, pts, ValidationConfig(trials=3, seed=1))
    assert np.array_equal(cm.errors, again.errors)


def test_cone_aware_localization_beats_axis_points_in_the_room() -> None:
    aware = confidence_map(ROOM_CORRIDOR, ROOM_PTS, ValidationConfig(trials=3, seed=2))
    axis = confidence_map(ROOM_CORRIDOR, ROOM_PTS,
                          ValidationConfig(trials=3, seed=2, sonar_aware=False))
    assert aware.errors.mean() < 0.01
    assert axis.errors.mean() > 2 * aware.errors.mean()


def test_run_validation_end_to_end_agrees_on_this_world() -> None:
    rep = run_validation(ROOM_CORRIDOR, FAST)
    m = rep.metrics
    assert m["n_points"] == rep.confidence.points.shape[0] == int(rep.mask.sum())
    assert rep.r_map.shape == rep.mask.shape == rep.confidence_map.shape
    assert np.all(np.isnan(rep.r_map[~rep.mask]))
    for model in ("line", "fisher"):
        assert set(m[model]) >= {"frac_residual_gt_0_4", "spearman", "auc", "params", "fitted"}
        assert 0.0 <= m[model]["frac_residual_gt_0_4"] <= 1.0
    # R and the Fisher score both separate the room (and corridor ends) from the mid-corridor.
    assert m["line"]["auc"] > 0.8 and m["fisher"]["auc"] > 0.8
    fitted = m["line"]["fitted"]["frac_residual_gt_0_4"]
    assert fitted <= m["line"]["frac_residual_gt_0_4"]


def test_fit_reduces_the_residual_statistic_in_sample() -> None:
    _, _, pts, _ = free_points(ROOM_CORRIDOR, 1.0, FAST)
    conf = confidence_map(ROOM_CORRIDOR, pts, FAST)
    start = MeasureConfig(k=2.0, c=3.0, m=1.0)  # a poor start
    bundle = cast_rays(ROOM_CORRIDOR, pts, start.angular_res_deg, start.max_range_m,
                       start.reflect_deg)
    before = compare(line_values(bundle, start), conf).frac_residual_gt
    fitted = fit_line_parameters(bundle, conf, start)
    after = compare(line_values(bundle, fitted), conf).frac_residual_gt
    assert after < before
    assert (fitted.k, fitted.c, fitted.m) != (start.k, start.c, start.m)


def test_bad_config_is_named() -> None:
    with pytest.raises(ValidationError, match="offset_max_m"):
        ValidationConfig(offset_min_m=0.2, offset_max_m=0.1)
    with pytest.raises(ValidationError, match="trials"):
        ValidationConfig(trials=0)
    with pytest.raises(ValidationError, match="grid points"):
        run_validation(ROOM_CORRIDOR, ValidationConfig(resolution_m=60.0))


def test_spearman_ceiling_of_a_two_valued_confidence() -> None:
    from island_mapping.evaluation.validation import spearman_ceiling

    p = 0.8
    conf = np.r_[np.ones(80), np.zeros(20)]
    assert spearman_ceiling(conf) == pytest.approx(math.sqrt(3 * p * (1 - p)), abs=0.01)
    assert spearman_ceiling(np.linspace(0, 1, 50)) == pytest.approx(1.0)
    assert math.isnan(spearman_ceiling(np.ones(5)))


def test_split_half_reliability_is_high_for_a_repeatable_confidence() -> None:
    from island_mapping.evaluation.validation import split_half_reliability

    cfg = ValidationConfig(trials=4)
    good = np.repeat(np.linspace(0.0, 0.15, 30)[:, None], 4, axis=1)  # same error every trial
    rel = split_half_reliability(ConfidenceMap(np.zeros((30, 2)), good, np.ones((30, 4), bool),
                                               np.zeros(30), np.zeros(30, bool)), cfg)
    assert rel["split_half_spearman"] == pytest.approx(1.0)
    noise = np.random.default_rng(0).uniform(0.0, 0.15, (30, 4))  # nothing repeatable
    rel = split_half_reliability(ConfidenceMap(np.zeros((30, 2)), noise, np.ones((30, 4), bool),
                                               np.zeros(30), np.zeros(30, bool)), cfg)
    assert rel["spearman_ceiling_est"] < 0.6
