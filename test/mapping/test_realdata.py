"""Real data: relation files and CARMEN logs (island_mapping.logs), time matching, relative pose
errors and the GMapping baseline (core.relations), the odometry error model and epsilon, beams,
and the UCI sonar ring (parsing, errors, R on hand-made rings)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from island_mapping.core import relations as rel_core
from island_mapping.core import sonar_ring as ring
from island_mapping.core.builder.epsilon import (
    OdometryErrorModel,
    RelativeCovariance,
    fit_odometry_error_model,
    propagate_covariances,
)
from island_mapping.core.builder.passive import PassiveBuilder, PassiveConfig, voxel_thin
from island_mapping.logs import carmen, uci_sonar
from island_mapping.logs import relations as rel_files
from island_mapping.logs.errors import LogFormatError
from island_mapping.logs.islands import scan_points
from island_msgs_py.types import Pose2D

from island_msgs_py import geometry as poses

RELATION_LINES = [
    "976052905.167303 976052911.885496 -0.056990 -0.128430 0.000000 0.000000 0.000000 -1.682210\n",
    "\n",
    "# a comment\n",
    "976052911.885496 976052913.712702 0.332780 -0.005920 0.000000 0.000000 0.000000 -0.019150\n",
]


def test_parse_relations_reads_times_and_planar_pose() -> None:
    rel = rel_files.parse_relations(RELATION_LINES)
    assert len(rel) == 2
    assert rel.t1_s[0] == pytest.approx(976052905.167303)
    assert rel.t2_s[1] == pytest.approx(976052913.712702)
    np.testing.assert_allclose(rel.rel[0], [-0.056990, -0.128430, -1.682210])
    np.testing.assert_allclose(rel.rel[1], [0.332780, -0.005920, -0.019150])


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("1 2 3 4 5 6 7\n", "expected 8 fields"),
        ("1 2 3 4 5 6 7 x\n", "not a number"),
        ("1 2 3 nan 5 6 7 8\n", "NaN or infinite"),
    ],
)
def test_parse_relations_names_the_bad_line(line: str, message: str) -> None:
    with pytest.raises(LogFormatError, match=rf"rel\.txt:3: .*{message}"):
        rel_files.parse_relations([RELATION_LINES[0], "\n", line], "rel.txt")


def test_read_relations_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="cannot read relations file"):
        rel_files.read_relations(tmp_path / "nope.relations")


def test_match_times_nearest_within_tolerance_first_of_equal_times() -> None:
    ref = np.array([5.0, 1.0, 3.0, 3.0, 7.0])  # unsorted, with a repeated time
    q = np.array([1.004, 2.0, 3.009, 6.99, 100.0, 3.0])
    idx = rel_core.match_times(q, ref, tolerance_s=0.01)
    assert idx.tolist() == [1, -1, 2, 4, -1, 2]  # index 2 is the first of the two 3.0 s
    assert rel_core.match_times(q, np.array([]), 0.01).tolist() == [-1] * 6


def test_relative_pose_error_hand_cases() -> None:
    truth = np.array([[1.0, 0.0, math.pi / 2], [2.0, 1.0, 0.0], [0.5, -0.5, 0.1]])
    est = np.array([[1.0, 0.1, math.pi / 2], [2.0, 1.0, math.radians(2.0)], [0.5, -0.5, 0.1]])
    trans, rot = rel_core.relative_pose_errors(est, truth)
    np.testing.assert_allclose(trans, [0.1, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(rot, [0.0, 2.0, 0.0], atol=1e-9)
    # Rotation errors wrap: 359 deg off is 1 deg off.
    _, rot2 = rel_core.relative_pose_errors([[0, 0, math.radians(179.5)]],
                                            [[0, 0, math.radians(-179.5)]])
    assert rot2[0] == pytest.approx(1.0)


def test_compose_and_relative_are_inverse() -> None:
    rng = np.random.default_rng(7)
    a = rng.uniform(-5, 5, (20, 3))
    b = rng.uniform(-5, 5, (20, 3))
    back = poses.compose_poses(a, poses.relative_poses(a, b))
    np.testing.assert_allclose(back[:, :2], b[:, :2], atol=1e-12)
    np.testing.assert_allclose(poses.wrap_angles(back[:, 2] - b[:, 2]), 0.0, atol=1e-12)


@pytest.fixture(scope="module")
def intel_track(shared_data: Path) -> rel_core.PoseTrack:
    return carmen.pose_track(carmen.read_carmen_records(shared_data / "intel" / "intel.gfs.log"))


def test_gmapping_baseline_reproduces_the_published_figures(
    shared_data: Path, intel_track: rel_core.PoseTrack
) -> None:
    track = intel_track
    rel = rel_files.read_relations(shared_data / "intel" / "intel.relations")
    assert len(rel) == 2984
    stats = rel_core.ErrorStats.of(*rel_core.gmapping_relation_errors(track, rel))
    assert stats.count == 2984
    assert round(stats.mean_trans_err_m, 3) == 0.065
    assert round(stats.median_trans_err_m, 3) == 0.048
    assert round(stats.mean_rot_err_deg, 1) == 2.1
    assert round(stats.median_rot_err_deg, 1) == 1.5


def test_relation_times_match_log_lines_and_some_scans(
    shared_data: Path, intel_track: rel_core.PoseTrack
) -> None:
    track = intel_track
    rel = rel_files.read_relations(shared_data / "intel" / "intel.relations")
    times = np.unique(np.concatenate([rel.t1_s, rel.t2_s])) - rel_core.INTEL_LOG_TO_UNIX_S
    assert times.size == 1791
    assert np.all(rel_core.match_times(times, track.times_s, 0.006) >= 0)
    scan_t = track.times_s[track.scan_rows]
    assert scan_t.size == 910
    at_scan = rel_core.match_times(times, scan_t) >= 0
    assert 300 < int(np.sum(at_scan)) < 500  # the relations were taken at raw laser times


def test_pose_track_agrees_with_the_carmen_reader(
    shared_data: Path, intel_track: rel_core.PoseTrack
) -> None:
    from island_mapping.bag.carmen import read_carmen

    path = shared_data / "intel" / "intel.gfs.log"
    track = intel_track
    log = read_carmen(path)
    rows = track.scan_rows
    np.testing.assert_array_equal(track.times_s[rows], log.times_s)
    np.testing.assert_allclose(track.gmapping[rows], log.corrected)
    inc_a = poses.relative_poses(track.raw[rows[:-1]], track.raw[rows[1:]])
    inc_b = poses.relative_poses(log.raw_odometry[:-1], log.raw_odometry[1:])
    np.testing.assert_allclose(inc_a, inc_b, atol=1e-9)


def test_parse_pose_track_reconstructs_raw_odometry() -> None:
    # Scan 0 corrected at the origin; odometry says +1 m; GMapping corrects scan 1 to (1.1, 0, 0);
    # then odometry +1 m again from there: raw odometry must show 2 m, GMapping 2.1 m.
    lines = [
        "ODOM 0 0 0 0 0 0 0.5 h 0.5\n",
        "FLASER 2 1 1 0 0 0 0 0 0 1.0 h 1.0\n",
        "ODOM 0 0 0 0 0 0 0 h 0\n",
        "ODOM 1.0 0 0 0 0 0 2.0 h 2.0\n",
        "FLASER 2 1 1 1.1 0 0 0 0 0 3.0 h 3.0\n",
        "ODOM 2.1 0 0 0 0 0 4.0 h 4.0\n",
    ]
    tr = carmen.pose_track(carmen.parse_carmen(lines))
    assert tr.is_scan.tolist() == [True, False, True, False]
    np.testing.assert_allclose(tr.times_s, [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_allclose(tr.raw[:, 0], [0.0, 1.0, 1.0, 2.0])
    np.testing.assert_allclose(tr.gmapping[:, 0], [0.0, 1.0, 1.1, 2.1])
    assert tr.scan_index.tolist() == [0, 0, 1, 1]
    with pytest.raises(LogFormatError, match="log:2: FLASER with 2 beams needs 13 fields"):
        carmen.pose_track(carmen.parse_carmen(["ODOM 0 0 0 0 0 0 1 h 1\n", "FLASER 2 1\n"], "log"))
    with pytest.raises(LogFormatError, match="log: no FLASER"):
        carmen.pose_track(carmen.parse_carmen(["ODOM 0 0 0 0 0 0 1 h 1\n", "NEFF 3\n"], "log"))


def passive_epsilons(steps: list[tuple[float, float, float]]) -> list[float]:
    """Epsilon of the passive builder at each of the odometry poses `steps`, their covariance
    propagated by the default error model (one empty scan each: no island, no attempt)."""
    b = PassiveBuilder(PassiveConfig())
    poses_ = np.array(steps, dtype=float)
    covs = propagate_covariances(poses_, OdometryErrorModel())
    for k, (x, y, th) in enumerate(steps):
        b.on_odometry(float(k), Pose2D(x, y, th), covs[k])
        b.on_scan(float(k), np.zeros((0, 2)))
    return b.finish().epsilon_m.tolist()


def test_epsilon_grows_with_travel_and_resets() -> None:
    """Epsilon from the covariance the error model propagates (as an odometry would publish
    it) through the live builder's relative-covariance tracker: 1 m straight adds half the
    model's x-plus-y variance per axis; the next metre also swings the first metre's heading
    variance sideways (var_y = b + a), faster than sqrt of the distance; turning adds too."""
    model = OdometryErrorModel()
    e0, e1, e2, e3 = passive_epsilons([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (2.0, 0.0, 0.0),
                                        (2.0, 0.0, math.pi / 2)])
    b, a = model.var_xy_per_m_m2, model.var_theta_per_m_rad2
    assert e0 == 0.0
    assert e1 == pytest.approx(math.sqrt(b / 2))
    assert e2 == pytest.approx(math.sqrt(b + a))
    assert e2 > e1 * math.sqrt(2)  # heading uncertainty makes the error grow faster than sqrt
    assert e3 > e2  # turning in place adds error too
    tracker = RelativeCovariance()
    for pose, cov in zip([Pose2D(*p) for p in ((0, 0, 0), (1, 0, 0), (2, 0, 0))],
                         propagate_covariances(np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0.0]]),
                                               model), strict=True):
        tracker.update(pose, cov)
    assert tracker.epsilon_m == pytest.approx(e2)  # the live builder's tracker, the same
    tracker.reset()
    assert tracker.epsilon_m == 0.0


def test_fit_odometry_error_model_recovers_known_variances() -> None:
    rng = np.random.default_rng(3)
    n = 4000
    d = rng.uniform(0.2, 1.0, n)
    turn = rng.uniform(-1.0, 1.0, n)
    true_inc = np.stack([d, np.zeros(n), turn], axis=1)
    sd_xy = np.sqrt((0.004 * d + 0.006 * np.abs(turn)) / 2)  # per axis
    sd_th = np.sqrt(0.005 * d + 0.002 * np.abs(turn))
    raw = true_inc + np.stack(
        [rng.normal(0, sd_xy), rng.normal(0, sd_xy), rng.normal(0, sd_th)], axis=1
    )
    m = fit_odometry_error_model(raw, true_inc)
    assert m.var_xy_per_m_m2 == pytest.approx(0.004, rel=0.25)
    assert m.var_xy_per_rad_m2 == pytest.approx(0.006, rel=0.25)
    assert m.var_theta_per_m_rad2 == pytest.approx(0.005, rel=0.25)
    assert m.var_theta_per_rad_rad2 == pytest.approx(0.002, rel=0.25)


def test_default_odometry_model_fits_the_intel_log(intel_track: rel_core.PoseTrack) -> None:
    track = intel_track
    rows = track.scan_rows
    raw_inc = poses.relative_poses(track.raw[rows[:-1]], track.raw[rows[1:]])
    cor_inc = poses.relative_poses(track.gmapping[rows[:-1]], track.gmapping[rows[1:]])
    fitted = fit_odometry_error_model(raw_inc, cor_inc)
    default = OdometryErrorModel()
    for name in ("var_xy_per_m_m2", "var_xy_per_rad_m2", "var_theta_per_m_rad2",
                 "var_theta_per_rad_rad2"):
        assert getattr(fitted, name) == pytest.approx(getattr(default, name), rel=0.05), name


def test_sonar_like_beams_are_centred_in_their_sectors_and_points_drop_no_returns() -> None:
    np.testing.assert_array_equal(carmen.sonar_like_indices(180, 16),
                                  np.floor(5.625 + 11.25 * np.arange(16)).astype(int))
    assert carmen.sonar_like_indices(180, 24).tolist()[:3] == [3, 11, 18]
    assert carmen.sonar_like_indices(180, 180).tolist() == list(range(180))
    with pytest.raises(LogFormatError, match="beams"):
        carmen.sonar_like_indices(180, 0)
    ranges = np.array([1.0, 81.83, np.nan, 2.0])
    pts = scan_points(ranges, np.radians([0.0, 10.0, 20.0, 90.0]), max_range_m=10.0)
    np.testing.assert_allclose(pts, [[1.0, 0.0], [0.0, 2.0]], atol=1e-12)


def test_voxel_thin_keeps_one_point_per_cell() -> None:
    pts = np.array([[0.01, 0.01], [0.03, 0.02], [0.51, 0.0], [0.52, 0.01]])
    thin = voxel_thin(pts, 0.1)
    assert thin.shape == (2, 2)
    np.testing.assert_allclose(sorted(thin[:, 0]), [0.02, 0.515])


# ---------------------------------------------------------------------------------------------
# UCI sonar ring


def _ring_line(ranges: list[float], label: str = "Move-Forward") -> str:
    return ",".join(f"{r:.3f}" for r in ranges) + f",{label}\n"


def test_sonar_ring_file_first_readings(shared_data: Path) -> None:
    readings = uci_sonar.read_sonar_ring(shared_data / "sonar" / "sensor_readings_24.data",
                                         limit=300)
    assert readings.ranges_m.shape == (300, 24)
    assert readings.labels[0] == "Slight-Right-Turn"
    assert set(readings.labels) <= {"Move-Forward", "Sharp-Right-Turn", "Slight-Left-Turn",
                                    "Slight-Right-Turn"}
    assert 4.9 < float(readings.ranges_m.max()) < 5.1  # 5.0 m is the no-echo value
    # The robot follows the wall on its left: left-side transducers (16-21) read short ranges.
    left = np.median(readings.ranges_m[:, 15:21])
    right = np.median(readings.ranges_m[:, 3:9])
    assert left < 1.0 < right


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("1,2,3,Move-Forward\n", "expected 24 ranges and a label, got 4 fields"),
        (_ring_line([1.0] * 23 + [-1.0]), "a range is negative"),
        (",".join(["1.0"] * 23 + ["x", "Move-Forward"]) + "\n", "not a range"),
        (",".join(["1.0"] * 25) + "\n", "missing motion label"),
    ],
)
def test_sonar_ring_bad_line_names_its_number(line: str, message: str) -> None:
    header = "S1,S2,S3,S4,S5,S6,S7,S8,S9,S10,S11,S12,S13,S14,S15,S16,S17,S18,S19,S20,S21,S22," \
             "S23,S24,OUTPUT\n"
    lines = [header, _ring_line([1.0] * 24), line]
    with pytest.raises(LogFormatError, match=rf"ring\.data:3: {message}"):
        uci_sonar.parse_sonar_ring(lines, "ring.data")


def _ring_in(walls: list[tuple[float, float, float]]) -> list[float]:
    """Ranges of the 24 transducers to straight walls n . p = c (n unit, c > 0), max 5 m."""
    cfg = ring.SonarRingConfig()
    out = []
    for a in ring.ring_angles():
        u = np.array([math.cos(a), math.sin(a)])
        best = cfg.max_range_m
        for nx, ny, c in walls:
            denom = nx * u[0] + ny * u[1]
            if denom > 1e-9:
                best = min(best, c / denom - cfg.ring_radius_m)
        out.append(min(best, cfg.max_range_m))
    return out


def test_ring_geometry_sensor_one_ahead_clockwise() -> None:
    cfg = ring.SonarRingConfig()
    ranges = [5.0] * 24
    ranges[0] = 1.0  # ahead
    ranges[6] = 2.0  # sensor 7: 90 deg clockwise = the right side
    pts = ring.ring_points(ranges, cfg)
    np.testing.assert_allclose(pts, [[1.0 + cfg.ring_radius_m, 0.0],
                                     [0.0, -(2.0 + cfg.ring_radius_m)]], atol=1e-12)


def test_ring_r_is_high_in_a_corner_and_low_in_a_corridor() -> None:
    corner = _ring_in([(1.0, 0.0, 1.2), (0.0, 1.0, 0.9), (0.0, -1.0, 1.5)])  # front, left, right
    corridor = _ring_in([(0.0, 1.0, 0.9), (0.0, -1.0, 0.9)])  # two long parallel walls
    readings = ring.SonarReadings(np.array([corner, corridor]),
                                  ("Sharp-Right-Turn", "Move-Forward"))
    scores = ring.score_ring_readings(readings)
    assert scores.segments.tolist()[1] >= 2
    assert scores.r[0] > 0.3
    assert scores.r[1] < 0.05
    assert scores.fisher[0] > scores.fisher[1]
    metrics = ring.ring_metrics(readings, scores)
    assert metrics["readings"] == 2
    per = metrics["per_label"]
    assert isinstance(per, dict) and per["Move-Forward"]["count"] == 1


def test_real_data_modules_do_not_load_rclpy_or_matplotlib() -> None:
    code = (
        "import sys, island_mapping.core.relations, island_mapping.core.sonar_ring\n"
        "import island_mapping.core.builder.passive, island_mapping.logs.carmen\n"
        "import island_mapping.logs.islands, island_mapping.logs.relations\n"
        "import island_mapping.logs.uci_sonar\n"
        "bad = [m for m in ('rclpy', 'matplotlib') if m in sys.modules]\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
