"""Offline islands on real data (the builder's passive mode, fed by logs.islands): scoring by
hand, eq. 3 decisions, and the first scans of the Intel Research Lab log end to end (laser and
sonar-like mode)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from island_mapping.core import relations as rd
from island_mapping.core.builder import passive
from island_mapping.core.builder.epsilon import propagate_covariances
from island_mapping.core.builder.places import PlaceSearch
from island_mapping.core.lines import fit_lines
from island_mapping.logs import carmen
from island_mapping.logs import islands as offline
from island_mapping.logs.relations import read_relations
from island_msgs_py.geometry import compose_poses, from_frame, relative_poses, wrap_angles
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

N_SCANS = 50  # ~3 min of the Intel log; keeps the end-to-end test to a few seconds


def _run(scan_island: list[int], scan_pose: list[list[float]]) -> passive.IslandRun:
    model = LineModel(np.array([[0.0, -1.0, 0.0, 1.0]]))
    isl = passive.PassiveIsland(Island(0, model, ModelType.LINE, 1.0, 0.0), 0, np.zeros(3))
    return passive.IslandRun(
        (isl, isl), (), np.asarray(scan_island, dtype=np.int64), np.asarray(scan_pose, float),
        np.zeros(len(scan_island)), passive.PassiveConfig(),
    )


def test_score_relations_uses_island_frame_poses_of_the_same_island() -> None:
    nan = [math.nan] * 3
    run = _run([0, 0, 1, -1], [[0, 0, 0], [1.0, 0.0, math.radians(90)], [0, 0, 0], nan])
    scan_t = np.array([10.0, 20.0, 30.0, 40.0])
    u = rd.INTEL_LOG_TO_UNIX_S
    rel = rd.Relations(
        t1_s=np.array([10.0, 10.0, 10.0, 10.004]) + u,
        t2_s=np.array([20.0, 30.0, 40.0, 20.5]) + u,  # same island; other island; none; no scan
        rel=np.array([[1.05, 0.0, math.radians(88.0)], [0, 0, 0], [0, 0, 0], [1.0, 0, 0]]),
    )
    score = rd.score_relations(run, scan_t, rel)
    assert score.covered.tolist() == [True, False, False, False]
    assert score.trans_err_m[0] == pytest.approx(0.05)
    assert score.rot_err_deg[0] == pytest.approx(2.0)
    assert score.islands.count == 1 and score.ends_at_scans == 3
    assert np.isnan(score.trans_err_m[1:]).all()
    # Two times 8 ms apart that both fall on scan 1: the log cannot resolve them.
    pair = rd.Relations(np.array([19.996 + u]), np.array([20.004 + u]), np.array([[0.3, 0, 0]]))
    same = rd.score_relations(run, scan_t, pair)
    assert same.unresolvable == 1 and not same.covered.any()


def test_bridging_adds_raw_odometry_from_the_nearer_localized_scan() -> None:
    # Scans at 0 s and 4 s in island 0; an ODOM line at 1 s, raw odometry 0.3 m ahead of scan 0.
    lines = [
        "FLASER 2 1 1 0 0 0 0 0 0 0.0 h 0.0\n",
        "ODOM 0.3 0 0 0 0 0 1.0 h 1.0\n",
        "ODOM 0.6 0 0 0 0 0 2.9 h 2.9\n",
        "ODOM 0.8 0 0 0 0 0 3.5 h 3.5\n",
        "FLASER 2 1 1 1.0 0 0 0 0 0 4.0 h 4.0\n",
    ]
    track = carmen.pose_track(carmen.parse_carmen(lines))
    run = _run([0, 0], [[0.0, 0.0, 0.0], [1.1, 0.0, 0.0]])
    u = rd.INTEL_LOG_TO_UNIX_S
    rel = rd.Relations(np.array([0.0 + u]), np.array([1.0 + u]), np.array([[0.32, 0.0, 0.0]]))
    strict = rd.score_relations(run, np.array([0.0, 4.0]), rel, track)
    assert not strict.covered.any()
    bridged = rd.score_relations(run, np.array([0.0, 4.0]), rel, track, bridge_s=1.5)
    assert bridged.covered.tolist() == [True]
    assert bridged.trans_err_m[0] == pytest.approx(0.02)  # 0.3 m by odometry vs 0.32 m true
    # The ODOM line at 2.9 s is nearer to scan 1: its fix 1.1 m minus the 0.2 m that raw
    # odometry still moved before scan 1 = 0.9 m.
    i, p, _, _ = rd.island_poses_at(run, np.array([0.0, 4.0]), np.array([2.9 + u]), track=track,
                                 bridge_s=1.5)
    assert i.tolist() == [0] and p[0, 0] == pytest.approx(0.9)
    # Too far from any scan for a 0.5 s bridge: no pose.
    i2, _, _, _ = rd.island_poses_at(run, np.array([0.0, 4.0]), np.array([1.0 + u]), track=track,
                                  bridge_s=0.5)
    assert i2.tolist() == [-1]


@pytest.fixture(scope="module")
def intel(shared_data: Path) -> tuple[rd.PoseTrack, np.ndarray, rd.Relations]:
    records = carmen.read_carmen_records(shared_data / "intel" / "intel.gfs.log")
    log, track = carmen.carmen_log(records), carmen.pose_track(records)
    rel = read_relations(shared_data / "intel" / "intel.relations")
    return track, log.ranges_m, rel


@pytest.fixture(scope="module")
def laser_run(intel: tuple[rd.PoseTrack, np.ndarray, rd.Relations]) -> passive.IslandRun:
    track, ranges, _ = intel
    rows = track.scan_rows[:N_SCANS]
    return offline.build_islands_offline(ranges[:N_SCANS], track.raw[rows], track.times_s[rows])


def test_islands_on_the_first_intel_scans_follow_eq3(laser_run: passive.IslandRun) -> None:
    run = laser_run
    cfg = run.config
    assert len(run.islands) >= 1
    for a in run.attempts:
        assert a.epsilon_m > cfg.builder.e_min_m  # attempts only when lost
        assert a.accepted == (a.best_normalized > a.bound)  # eq. 3
        assert a.bound == pytest.approx(max(cfg.builder.e_min_m / a.epsilon_m,
                                            cfg.builder.bound_floor))
    accepted = [a for a in run.attempts if a.accepted]
    assert [a.scan for a in accepted] == [i.anchor_scan for i in run.islands]
    for isl in run.islands:
        assert len(isl.island.model) >= 3
        assert run.scan_island[isl.anchor_scan] == isl.island.id
        # The anchor is the island's origin: its fix stays close to (0, 0, 0).
        p = run.scan_pose[isl.anchor_scan]
        assert math.hypot(p[0], p[1]) < 0.2 and abs(p[2]) < math.radians(5)
    inside = run.scan_island >= 0
    assert inside.sum() >= 10
    dist = np.hypot(run.scan_pose[inside, 0], run.scan_pose[inside, 1])
    assert np.all(dist <= cfg.coverage_radius_m + 1e-9)
    assert np.all(run.epsilon_m[inside] < 1.0)


def test_island_localization_beats_a_loose_bound_on_covered_relations(
    laser_run: passive.IslandRun, intel: tuple[rd.PoseTrack, np.ndarray, rd.Relations]
) -> None:
    track, _, rel = intel
    scan_t = track.times_s[track.scan_rows[:N_SCANS]]
    score = rd.score_relations(laser_run, scan_t, rel, track, bridge_s=1.7)
    assert score.islands.count >= 20
    assert score.islands.mean_trans_err_m < 0.08
    assert score.islands.mean_rot_err_deg < 3.0
    # Errors are per relation and finite exactly where covered.
    assert np.isfinite(score.trans_err_m[score.covered]).all()
    assert score.gmapping_covered.count == score.islands.count


def test_sonar_like_mode_keeps_few_beams_and_still_builds_islands(
    intel: tuple[rd.PoseTrack, np.ndarray, rd.Relations],
) -> None:
    track, ranges, _ = intel
    n = 40
    rows = track.scan_rows[:n]
    cfg = offline.sonar_like_config(24)
    assert cfg.beams == 24 and cfg.max_range_m == offline.SONAR_LIKE_RANGE_M
    seen: list[int] = []

    def fitter(points: np.ndarray) -> LineModel:
        seen.append(points.shape[0])
        return fit_lines(points, cfg.islands.builder.line_fit)

    run = offline.build_islands_offline(ranges[:n], track.raw[rows], track.times_s[rows], cfg,
                                        fitter=fitter)
    window = 2 * cfg.islands.half_window_scans + 1
    assert seen and max(seen) <= 24 * window
    assert len(run.attempts) >= 1
    assert len(run.islands) >= 1


def test_bad_inputs_are_clear_errors() -> None:
    with pytest.raises(offline.OfflineError, match="beams"):
        offline.OfflineConfig(beams=32)
    with pytest.raises(offline.OfflineError, match="ranges"):
        offline.build_islands_offline(np.zeros((3, 180)), np.zeros((2, 3)), np.zeros(3))


def test_sonar_like_scans_localize_in_laser_built_islands(
    intel: tuple[rd.PoseTrack, np.ndarray, rd.Relations],
) -> None:
    track, ranges, _ = intel
    n = 30
    rows = track.scan_rows[:n]
    cfg = offline.OfflineConfig(localize_beams=16)
    fit_sizes: list[int] = []
    fix_sizes: list[int] = []
    loc = passive.core_localizer(cfg.islands.builder.localize)

    def fitter(points: np.ndarray) -> LineModel:
        fit_sizes.append(points.shape[0])
        return fit_lines(points, cfg.islands.builder.line_fit)

    def localizer(model: LineModel, points: np.ndarray, guess: np.ndarray) -> passive.ScanFix:
        fix_sizes.append(points.shape[0])
        return loc(model, points, guess)

    run = offline.build_islands_offline(ranges[:n], track.raw[rows], track.times_s[rows], cfg,
                                        localizer=localizer, fitter=fitter)
    assert len(run.islands) >= 1
    assert max(fit_sizes) > 100  # island models come from the full laser scans
    assert fix_sizes and max(fix_sizes) > 16  # window alignment uses laser scans ...
    # ... while every scan localized in an island was localized from at most 16 beams.
    localized = int((run.scan_island >= 0).sum())
    assert localized >= 1
    assert sum(1 for k in fix_sizes if k <= 16) >= localized
    with pytest.raises(offline.OfflineError, match="localize_beams"):
        offline.OfflineConfig(localize_beams=7)


def _points_seen_from(segments: np.ndarray, pose: np.ndarray, step_m: float = 0.1) -> np.ndarray:
    """Points along the segments, in the robot frame of `pose` (no occlusion: enough here)."""
    pts = []
    for x1, y1, x2, y2 in segments:
        k = max(2, int(math.hypot(x2 - x1, y2 - y1) / step_m))
        pts.append(np.stack([np.linspace(x1, x2, k), np.linspace(y1, y2, k)], axis=1))
    world = np.concatenate(pts)
    inv = relative_poses(pose, np.zeros(3))[0]  # pose^-1
    local = from_frame(world, inv)
    return local[np.hypot(local[:, 0], local[:, 1]) <= 6.0]  # the sensor's range


def test_place_search_finds_a_pose_in_an_asymmetric_room_and_flags_a_corridor() -> None:
    room = np.array([[-3, -2, 4, -2], [4, -2, 4, 3], [4, 3, 0, 3], [0, 3, 0, 1], [0, 1, -3, 1],
                     [-3, 1, -3, -2], [1.5, 0.0, 2.5, 0.0]], dtype=float)  # L-shape + a box edge
    search = PlaceSearch(LineModel(room), half_extent_m=8.0, coverage_m=3.0)
    true_pose = np.array([1.0, -0.6, math.radians(70.0)])
    pose, score, second = search.search(_points_seen_from(room, true_pose))
    assert math.hypot(pose[0] - true_pose[0], pose[1] - true_pose[1]) <= 0.15
    assert abs(math.degrees(wrap_angles(pose[2] - true_pose[2]))) <= 5.0
    assert score > 0.9 and score - second > 0.2
    corridor = np.array([[-20, -1, 20, -1], [-20, 1, 20, 1]], dtype=float)
    search_c = PlaceSearch(LineModel(corridor), half_extent_m=8.0, coverage_m=3.0)
    _, score_c, second_c = search_c.search(_points_seen_from(corridor, np.array([0.5, 0, 0])))
    assert score_c > 0.9 and score_c - second_c < 0.05  # every position along it fits


def _synthetic_revisit_log() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A laser robot in room A, down a corridor to room B and back to room A; its raw odometry
    gains a 60 deg heading error in room B (so odometry cannot lead it back into A's island).
    Returns (ranges (S, 180), raw poses (S, 3), true poses (S, 3), times (S,))."""
    from island_sim.core.world import World

    walls = np.array([
        [0, 0, 6, 0], [6, 0, 6, 2], [6, 3, 6, 5], [6, 5, 0, 5], [0, 5, 0, 0],  # room A
        [1, 1, 2, 1], [2, 1, 2, 1.6],  # a box edge in A
        [6, 2, 14, 2], [6, 3, 14, 3],  # corridor
        [14, 2, 14, -2], [14, -2, 19, -2], [19, -2, 19, 6], [19, 6, 14, 6], [14, 6, 14, 3],  # B
        [16, 0, 17, 1],  # a diagonal wall in B
    ], dtype=float)
    world = World(walls)
    out = [(2.0 + 0.4 * k, 2.5, 0.0) for k in range(4)]
    out += [(4.0 + 1.0 * k, 2.5, 0.0) for k in range(1, 13)]  # through the corridor into B
    back = [(16.0, 2.5, math.pi)] + [(16.0 - 1.0 * k, 2.5, math.pi) for k in range(1, 13)]
    back += [(3.6 - 0.4 * k, 2.5, math.pi) for k in range(4)]
    back += [(2.4, 2.5, 0.0), (2.8, 2.5, 0.0)]  # turn round: face the part seen on the way out
    true = np.array(out + back)
    angles = carmen.flaser_angles(180)
    ranges = []
    for x, y, th in true:
        hits = world.raycast(np.tile([x, y], (180, 1)), th + angles, 20.0)
        ranges.append(np.where(np.isfinite(hits.distance_m), hits.distance_m, 81.83))
    inc = relative_poses(true[:-1], true[1:])
    inc[len(out) - 1, 2] += math.radians(60.0)  # the odometry's heading error in room B
    raw = [np.zeros(3)]
    for d in inc:
        raw.append(compose_poses(raw[-1], d)[0])
    return np.array(ranges), np.array(raw), true, np.arange(true.shape[0], dtype=float) * 3.0


def test_place_recognition_re_enters_the_first_island_after_odometry_fails() -> None:
    ranges, raw, true, times = _synthetic_revisit_log()
    isl = passive.replace_builder(passive.PassiveConfig(), e_min_m=0.05)
    base = offline.OfflineConfig(islands=isl)
    plain = offline.build_islands_offline(ranges, raw, times, base)
    found = offline.build_islands_offline(
        ranges, raw, times,
        dataclasses.replace(base, islands=dataclasses.replace(isl, place_recognition=True)))
    for run in (plain, found):
        assert run.islands and run.islands[0].anchor_scan < 4  # island 0 is in room A

    def room_a_ids(run: passive.IslandRun) -> set[int]:
        return {i.island.id for i in run.islands if i.anchor_scan < 4}

    tail = slice(true.shape[0] - 2, true.shape[0])  # the last scans, back in room A
    assert not set(plain.scan_island[tail].tolist()) & room_a_ids(plain)
    back_in_a = [j for j in range(true.shape[0])[tail] if found.scan_island[j] in room_a_ids(found)]
    assert back_in_a
    for j in back_in_a:  # the island-frame pose agrees with the truth
        isl = found.islands[int(found.scan_island[j])]
        truth = relative_poses(true[isl.anchor_scan], true[j])[0]
        got = found.scan_pose[j]
        assert math.hypot(*(got[:2] - truth[:2])) < 0.1
        assert abs(math.degrees(wrap_angles(got[2] - truth[2]))) < 3.0


def test_a_fix_restarts_epsilon_and_the_scans_are_decided_online() -> None:
    """On the synthetic log, every scan localized in an island when it was decided (at or after
    the island's anchor; scans before it join it when it is built) restarts epsilon: the next
    scan's epsilon is that of its own odometry increment from zero (a fresh builder fed the
    two poses). Fed scan by scan, a scan is decided once half_window_scans more have come."""
    ranges, raw, _, times = _synthetic_revisit_log()
    isl = passive.replace_builder(passive.PassiveConfig(), e_min_m=0.05)
    run = offline.build_islands_offline(ranges, raw, times, offline.OfflineConfig(islands=isl))
    after_fix = [j for j in range(1, raw.shape[0]) if run.scan_island[j - 1] >= 0
                 and j - 1 >= run.islands[run.scan_island[j - 1]].anchor_scan]
    assert len(after_fix) >= 5
    covs = propagate_covariances(raw, offline.OfflineConfig().odometry)
    for j in after_fix:
        fresh = passive.PassiveBuilder(isl)
        for k in (j - 1, j):
            fresh.on_odometry(times[k], Pose2D(*raw[k]), covs[k])
            fresh.on_scan(times[k], np.zeros((0, 2)))
        assert run.epsilon_m[j] > 0.0
        assert run.epsilon_m[j] == pytest.approx(fresh.finish().epsilon_m[1], rel=1e-9)
    b = passive.PassiveBuilder(isl)
    build, _ = offline.beam_points(ranges, offline.OfflineConfig(islands=isl))
    for k in range(4):
        b.on_odometry(times[k], Pose2D(*raw[k]), covs[k])
        b.on_scan(times[k], build[k])
        assert b.run().scan_island.size == max(0, k + 1 - isl.half_window_scans)
