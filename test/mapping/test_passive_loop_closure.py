"""The passive mode closes loops as live exploration does (issue 19): the same Recognizer search
and loop-closure gate, under the odometry's full covariance since an island's origin was last
known; islands per place from a reference trajectory."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from island_mapping.core.builder.passive import IslandRun, PassiveBuilder
from island_mapping.core.explore import ExplorerConfig, loop_closure_hooks
from island_mapping.logs import reference as refs
from island_mapping.logs import report
from island_mapping.logs.geometry import ScanGeometry
from island_mapping.logs.islands import OfflineConfig
from island_msgs_py.raycast import raycast
from island_msgs_py.types import Pose2D

# A closed room with a notch (constrained along every axis, not symmetric), walls [m].
ROOM = np.array([
    [0.0, 0.0, 4.0, 0.0], [4.0, 0.0, 4.0, 1.2], [4.0, 1.2, 3.0, 1.2], [3.0, 1.2, 3.0, 2.0],
    [3.0, 2.0, 4.0, 2.0], [4.0, 2.0, 4.0, 5.0], [4.0, 5.0, 0.0, 5.0], [0.0, 5.0, 0.0, 3.0],
    [0.0, 3.0, 1.0, 3.0], [1.0, 3.0, 1.0, 2.6], [1.0, 2.6, 0.0, 2.6], [0.0, 2.6, 0.0, 0.0],
])
A = np.array([2.0, 1.5, 0.3])  # where the robot looks around in the room (true pose)
BEAMS = np.radians(np.arange(-90.0, 90.5, 1.0))  # a 181-beam, 1 deg laser


def _world(shift_x_m: float) -> np.ndarray:
    """The room, and the same room again shift_x_m further along x (a look-alike place)."""
    twin = ROOM + np.array([shift_x_m, 0.0, shift_x_m, 0.0])
    return np.concatenate([ROOM, twin])


def _scan(walls: np.ndarray, pose: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Robot-frame laser points (N, 2) [m] seen from the true pose (1 cm range noise)."""
    hits = raycast(walls, np.tile(pose[:2], (BEAMS.size, 1)), BEAMS + pose[2], 10.0)
    r = hits.distance_m + rng.normal(0.0, 0.01, BEAMS.size)
    ok = np.isfinite(r)
    return np.stack([r[ok] * np.cos(BEAMS[ok]), r[ok] * np.sin(BEAMS[ok])], axis=1)


def _run(walls: np.ndarray, stops: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
         closure: bool, seed: int = 3) -> tuple[IslandRun, list[np.ndarray]]:
    """Feed the passive mode: per stop (true pose, odometric pose, 3x3 odometry covariance),
    the odometry along a detour of 24 m out and back before it (path, no scans: the robot is
    out of sight), then three scans there. Returns the run and the true pose of every scan."""
    rng = np.random.default_rng(seed)
    builder = PassiveBuilder(hooks=loop_closure_hooks(ExplorerConfig()) if closure else None)
    t, truth = 0.0, []
    builder.on_odometry(t, Pose2D(*stops[0][1]), np.zeros((3, 3)))
    prev_odom, prev_cov = stops[0][1], np.zeros((3, 3))
    for true_pose, odom, cov in stops:
        if not np.allclose(odom, prev_odom):  # the detour: 12 m out along x and back
            for f in np.linspace(0.0, 1.0, 25):
                out = 12.0 * math.sin(math.pi * f)
                mid = prev_odom + f * (odom - prev_odom) + np.array([out, 0.0, 0.0])
                t += 1.0
                builder.on_odometry(t, Pose2D(*mid), prev_cov + f * (cov - prev_cov))
        t += 1.0
        builder.on_odometry(t, Pose2D(*odom), cov)
        prev_odom, prev_cov = odom, cov
        for _ in range(3):
            t += 1.0
            builder.on_scan(t, _scan(walls, true_pose, rng))
            truth.append(true_pose)
    return builder.finish(), truth


def _places(run: IslandRun, truth: list[np.ndarray]) -> dict[str, object]:
    """Islands per place, the island origins placed by the true poses (the reference)."""
    return refs.places([i.island.id for i in run.islands],
                       np.array([truth[i.anchor_scan] for i in run.islands]))


START_COV = np.diag([0.2, 0.2, 0.002])  # the robot is lost at the start: eq. 3 builds island 0


@pytest.mark.parametrize("closure", [True, False])
def test_a_revisit_after_a_loop_docks_onto_the_island_of_the_place(closure: bool) -> None:
    """Back at the room after a 24 m detour, raw odometry is 0.9 m and 3 deg off: too far for
    the island tracker's small correction (0.6 m), well inside the odometry's uncertainty (1 m
    sigma). With the loop closure the scans are localized in island 0, no island is built
    again (one island per place); without it the place is stored twice."""
    off = np.array([0.8, 0.4, math.radians(3.0)])
    cov = np.diag([1.0, 1.0, 0.01])
    run, truth = _run(ROOM, [(A, A, START_COV), (A, A + off, START_COV + cov)], closure)
    assert run.islands[0].anchor_scan == 0
    places = _places(run, truth)
    back = run.scan_island[3:]
    if closure:
        assert len(run.islands) == 1 and places["islands_per_place"] == 1.0
        assert np.all(back == 0)
        assert [r.island_id for r in run.revisits] == [0]
        # where the scans are in island 0: their true pose (the island's origin is A)
        assert np.allclose(run.scan_pose[3:, :2], 0.0, atol=0.05)
        assert run.loop_closure is not None and run.loop_closure["accepted"] == 1
    else:
        assert len(run.islands) == 2 and places["islands_per_place"] == 2.0
        assert places["duplicates"][0]["island"] == 1 and places["duplicates"][0]["place_of"] == 0
        assert run.revisits == () and run.loop_closure is None


def test_a_look_alike_outside_the_uncertainty_is_not_docked_onto() -> None:
    """The same room 6 m further along x: odometry knows the robot moved 6 m along x to within
    0.2 m (but not across: 3 m). The recognizer's circular window (of the largest sigma)
    reaches the first room's island and its model fits, but 6 m along x is 30 sigmas under the
    full covariance: the gate refuses it (counted), and the look-alike gets its own island."""
    walls = _world(6.0)
    twin = A + np.array([6.0, 0.0, 0.0])
    cov = np.diag([0.04, 9.0, 0.0004])
    run, truth = _run(walls, [(A, A, START_COV), (twin, twin, START_COV + cov)], True)
    assert len(run.islands) == 2 and run.revisits == ()
    assert run.loop_closure is not None and run.loop_closure["accepted"] == 0
    assert run.loop_closure["refused"].get("outside_uncertainty", 0) >= 1
    places = _places(run, truth)
    assert places["places"] == 2 and places["islands_per_place"] == 1.0
    assert places["duplicates"] == []


def test_the_same_look_alike_within_a_loose_uncertainty_is_taken() -> None:
    """Control of the test above: the same twin, with odometry that does not know where along
    x the robot went (2 m sigma both ways). Nothing but the covariance changed, and the
    recognition passes the gate: what refuses a look-alike is the covariance."""
    walls = _world(6.0)
    twin = A + np.array([6.0, 0.0, 0.0])
    cov = np.diag([16.0, 16.0, 0.0004])
    run, _ = _run(walls, [(A, A, START_COV), (twin, twin, START_COV + cov)], True)
    assert [r.island_id for r in run.revisits] == [0]
    assert len(run.islands) == 1


def test_places_merge_origins_within_two_metres_of_a_places_first_island() -> None:
    """Places as issue 16's yardstick merges them: an island within 2 m of a place's first
    island duplicates it (a missed loop closure); a chain of islands 1.5 m apart is not one
    place (no single linkage along a corridor)."""
    origins = np.array([[0.0, 0.0, 0.0], [1.5, 0.0, 0.0], [3.0, 0.0, 0.0], [0.5, 0.5, 1.0]])
    got = refs.places([4, 7, 9, 12], origins)
    assert got["places"] == 2 and got["islands_per_place"] == 2.0
    assert got["places_with_several"] == [[4, 7, 12]]
    assert [d["island"] for d in got["duplicates"]] == [7, 12]
    assert all(d["place_of"] == 4 for d in got["duplicates"])


def test_islands_per_place_needs_a_reference_and_says_so_without_one() -> None:
    """A recording with no reference: islands per place cannot be computed, and metrics.json
    and the console say so (no guess from raw odometry); with the truth as the reference the
    places are counted and the loop closures scored against it."""
    rng = np.random.default_rng(4)
    poses = np.array([A + np.array([0.1 * k, 0.05 * k, 0.02 * k]) for k in range(8)])
    ranges = []
    for p in poses:
        hits = raycast(ROOM, np.tile(p[:2], (BEAMS.size, 1)), BEAMS + p[2], 10.0)
        ranges.append(hits.distance_m + rng.normal(0.0, 0.01, BEAMS.size))
    log = report.RecordedLog(
        name="room.log", times_s=np.arange(8.0), ranges_m=np.array(ranges),
        geometry=ScanGeometry(BEAMS.size, float(BEAMS[0]), math.radians(1.0), "test"),
        raw_odometry=poses + np.array([0.0, 0.0, 0.0]))
    lost = OfflineConfig(odometry=dataclasses.replace(OfflineConfig().odometry,
                                                      var_xy_per_m_m2=2.0))
    metrics, run = report.evaluate_log(log, lost, report.Scoring())
    assert len(run.islands) >= 1
    assert metrics["places"]["computable"] is False and "reference" in metrics["places"]["why"]
    assert metrics["loop_closure"]["tried"] >= 0
    text = "\n".join(report.headline(metrics))
    assert "islands per place: cannot be computed" in text
    truth = refs.Reference(np.arange(8.0), poses, "truth")
    metrics, _ = report.evaluate_log(log, lost, report.Scoring(reference=truth,
                                                               reference_offset_s=0.0))
    assert metrics["places"]["computable"] is True
    assert metrics["places"]["islands"] == len(run.islands)
    assert "islands per place: " in "\n".join(report.headline(metrics))
