"""Any robot's log (issue 19): every sensor a CARMEN log can hold read where it points and where
it sits (a laser off the robot's centre, a rear laser facing backwards, a sonar ring), sonar
rings built as such, recordings' references taken by stamp, and the console, figure and
metrics of a log named and honest. Small synthetic logs of a HouseExpo room, seeded."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from island_mapping.cli import main
from island_mapping.core.lines import point_segment_distance
from island_mapping.evaluation import synthetic_log as syn
from island_mapping.logs import carmen, islands
from island_mapping.logs.errors import LogFormatError
from island_msgs_py.geometry import from_frame
from island_sim.core.world_loader import load_world
from PIL import Image

ROOM = "house_expo_room_0000.json"


@pytest.fixture(scope="module")
def room(shared_data: Path) -> str:
    return str(shared_data / "floorplans" / ROOM)


def _wall_distance_m(world_spec: str, log: carmen.CarmenLog, truth: np.ndarray) -> float:
    """Median distance [m] to the walls of the scans' points, read with the log's geometry and
    mount and placed at the true poses."""
    world = load_world(world_spec)
    g = log.geometry
    assert g is not None
    d = []
    for r, pose in zip(log.ranges_m, truth, strict=True):
        pts = islands.scan_points(r, g.angles(), 20.0, g.origins())
        pts = from_frame(pts, np.asarray(log.mount))
        d.append(point_segment_distance(from_frame(pts, pose), world.segments).min(axis=1))
    return float(np.median(np.concatenate(d)))


@pytest.mark.parametrize(("kind", "beams", "mount", "sensor"), [
    ("FLASER", 361, (0.3, 0.05, 0.1), "laser"),
    ("RLASER", 181, (0.2, 0.0, 0.0), "laser"),
    ("SONAR", 16, (0.0, 0.0, 0.0), "sonar ring"),
])
def test_each_sensor_is_read_where_it_sits_so_its_points_lie_on_the_walls(
        tmp_path: Path, room: str, kind: str, beams: int, mount: tuple[float, float, float],
        sensor: str) -> None:
    sim = syn.simulate_log(room, beams=beams, goals=1, seed=3, kind=kind, mount=mount)
    log = carmen.carmen_log(carmen.parse_carmen(syn.carmen_lines(sim), f"{kind}.log"))
    assert log.geometry is not None and log.geometry.sensor.value == sensor
    np.testing.assert_allclose(log.mount, sim.mount, atol=1e-9)
    assert log.has_corrected == (kind != "SONAR")
    if kind != "SONAR":  # the robot's corrected pose, not the laser's, whatever the mount
        np.testing.assert_allclose(log.corrected[:, :2], sim.corrected[:, :2], atol=1e-5)
    assert _wall_distance_m(room, log, sim.truth) < 0.03
    # Read as a forward laser at the robot's centre (what an unread mount amounts to), the
    # same ranges miss the walls by far more than the 1 cm noise.
    if kind != "SONAR":
        naive = carmen.CarmenLog(log.path, log.times_s, log.scan_log_times_s, log.ranges_m,
                                 log.corrected, log.raw_odometry, log.odom_times_s, log.odom_raw,
                                 log.odom_scan_index, log.geometry)
        assert _wall_distance_m(room, naive, sim.truth) > 0.08


def test_a_sonar_ring_builds_islands_as_sonar_and_says_what_it_scores_against(
        tmp_path: Path, room: str, capsys: pytest.CaptureFixture[str]) -> None:
    sim = syn.simulate_log(room, beams=16, goals=2, seed=5, kind="SONAR")
    paths = syn.write_all(sim, tmp_path / "ring")
    out = tmp_path / "o"
    assert main(["eval-relations", "--log", str(paths["log"]), "--relations",
                 str(paths["relations"]), "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["geometry"]["sensor"] == "sonar ring" and m["geometry"]["beams"] == 16
    assert m["mode"].startswith("sonar ring") and m["config"]["max_range_m"] == 6.5
    assert m["island_count"] >= 1 and m["localized_scans"] > 0
    # A SONAR log holds no corrected poses: relations are scored beside raw odometry, named
    # so, and islands per place cannot be computed without a reference.
    assert m["relations_reference"].startswith("raw odometry")
    assert m["places"]["computable"] is False
    text = capsys.readouterr().out
    assert "raw odometry (the log has no corrected poses) on the same" in text
    assert main(["eval-relations", "--log", str(paths["log"]), "--reference",
                 str(paths["reference"]), "--out", str(tmp_path / "r")]) == 0
    r = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert r["places"]["computable"] is True and r["island_count"] == m["island_count"]
    assert r["reference"]["inside_islands"]["mean_trans_err_m"] < 0.1


def test_an_imported_sonar_ring_replays_as_a_ring(tmp_path: Path, room: str) -> None:
    sim = syn.simulate_log(room, beams=16, goals=2, seed=5, kind="SONAR")
    paths = syn.write_all(sim, tmp_path / "ring")
    bag = tmp_path / "bag"
    assert main(["bag", "import-carmen", str(paths["log"]), "--out", str(bag)]) == 0
    from island_mapping.bag.scanlog import read_scan_log

    log, counts = read_scan_log(bag)
    assert counts["scans_before_odometry"] == 0  # a raw log's ODOM line precedes its scans
    assert log.geometry.sensor.value == "sonar ring"
    assert math.degrees(log.geometry.increment_rad) == pytest.approx(22.5)
    assert log.reference is None  # no corrected poses, so no /gmapping_pose
    # Ranges from the robot's centre: the same points as the log's, from each transducer.
    world = load_world(room)
    pts = islands.scan_points(log.ranges_m[0], log.geometry.angles(), 20.0)
    assert np.median(point_segment_distance(from_frame(pts, sim.truth[0]),
                                            world.segments).min(axis=1)) < 0.03
    # The same pipeline either way: the recording builds the log's islands, localizes the
    # same scans and covers the same relations (errors equal to float32 ranges).
    both = ["--relations", str(paths["relations"]), "--reference", str(paths["reference"])]
    assert main(["replay", str(bag), "--passive", *both, "--out", str(tmp_path / "rp")]) == 0
    assert main(["eval-relations", "--log", str(paths["log"]), *both,
                 "--out", str(tmp_path / "ev")]) == 0
    rp, ev = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in ("rp", "ev"))
    assert rp["mode"].startswith("sonar ring") and rp["island_count"] >= 1
    for key in ("scans", "island_count", "localized_scans"):
        assert rp[key] == ev[key], key
    assert rp["bridged"]["covered_relations"] == ev["bridged"]["covered_relations"] > 0
    assert rp["bridged"]["mean_trans_err_m"] == pytest.approx(ev["bridged"]["mean_trans_err_m"],
                                                              abs=1e-4)


def test_import_refuses_a_laser_a_laserscan_cannot_place(
        tmp_path: Path, room: str, capsys: pytest.CaptureFixture[str]) -> None:
    sim = syn.simulate_log(room, beams=181, goals=1, seed=3, mount=(0.3, 0.0, 0.0))
    paths = syn.write_all(sim, tmp_path / "mounted")
    assert main(["bag", "import-carmen", str(paths["log"]), "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err
    assert "mounted.log" in err and "eval-relations" in err and "Traceback" not in err
    assert not (tmp_path / "b").exists()


def test_imported_half_degree_scans_lie_on_the_known_walls(tmp_path: Path, room: str) -> None:
    """`bag import-carmen` writes the geometry it read: a 361-beam 0.5 deg scan replays onto
    the walls (the old 1 deg assumption put it > 10 cm off)."""
    from island_mapping.bag.scanlog import read_scan_log

    sim = syn.simulate_log(room, beams=361, goals=1, seed=4)
    paths = syn.write_all(sim, tmp_path / "half")
    bag = tmp_path / "bag"
    assert main(["bag", "import-carmen", str(paths["log"]), "--out", str(bag)]) == 0
    log, counts = read_scan_log(bag)
    assert counts["scans_before_odometry"] == 1
    assert math.degrees(log.geometry.increment_rad) == pytest.approx(0.5, abs=1e-6)
    assert math.degrees(log.geometry.angle_min_rad) == pytest.approx(-90.0, abs=1e-5)
    world = load_world(room)
    d = [point_segment_distance(
        from_frame(islands.scan_points(r, log.geometry.angles(), 20.0), pose),
        world.segments).min(axis=1) for r, pose in zip(log.ranges_m, sim.truth[1:], strict=True)]
    assert float(np.median(np.concatenate(d))) < 0.03
    # The recording's /gmapping_pose is its reference, taken at each scan by stamp.
    assert log.track_name == "the recording's /gmapping_pose"
    np.testing.assert_allclose(log.track.gmapping[log.track.scan_rows], sim.corrected[1:],
                               atol=1e-5)


def _bag_with_reference(path: Path) -> None:
    """Five 1 deg scans 1 s apart with odometry, and /ground_truth at 20 Hz whose x is its
    stamp, each second's written after that second's scan."""
    from island_mapping.bag.writer import BagWriter
    from island_msgs_py.conversions import arrays_to_scan, pose_to_odometry
    from island_msgs_py.types import Pose2D

    angles = np.radians(np.arange(-90.0, 90.5, 1.0))
    with BagWriter(path) as w:
        for k in range(5):
            t = 1.0 + k
            w.write("/odom", pose_to_odometry(Pose2D(0.1 * k, 0.0, 0.0), None, round(t * 1e9),
                                              "odom"), round(t * 1e9))
            w.write("/scan", arrays_to_scan(np.full(angles.size, 2.0), angles, (0.1, 30.0),
                                            round(t * 1e9)), round(t * 1e9))
            # Ground truth arrives late in the file (after the scan), stamped around it.
            for j in range(-10, 10):
                tg = t + 0.05 * j
                w.write("/ground_truth", pose_to_odometry(Pose2D(tg, 0.0, 0.0), None,
                                                          round(tg * 1e9), "map"),
                        round((t + 0.5) * 1e9))


def test_a_recorded_reference_is_taken_at_each_scan_by_stamp(tmp_path: Path) -> None:
    from island_mapping.bag.scanlog import read_scan_log

    _bag_with_reference(tmp_path / "b")
    log, _ = read_scan_log(tmp_path / "b")
    assert log.reference is not None and "/ground_truth" in log.reference.name
    # The nearest stamp (x = t), not the last message before the next scan (x = t + 0.45).
    np.testing.assert_allclose(log.track.gmapping[log.track.scan_rows][:, 0],
                               log.times_s, atol=1e-6)
    with pytest.raises(LogFormatError, match="no topic /nope"):
        read_scan_log(tmp_path / "b", reference_topic="/nope")


def test_a_log_without_relations_is_scored_against_its_reference_and_named(
        tmp_path: Path, room: str, capsys: pytest.CaptureFixture[str]) -> None:
    sim = syn.simulate_log(room, beams=181, goals=2, seed=6)
    paths = syn.write_all(sim, tmp_path / "plain")
    out = tmp_path / "o"
    assert main(["eval-relations", "--log", str(paths["log"]), "--reference",
                 str(paths["reference"]), "--out", str(out)]) == 0
    m = json.loads((out / "metrics.json").read_text())
    assert "bridged" not in m and "covered_relations" not in m
    ins = m["reference"]["inside_islands"]
    assert ins["count"] > 0 and ins["mean_trans_err_m"] < 0.05
    assert m["reference"]["time_offset"]["offset_s"] == pytest.approx(0.0, abs=0.01)
    assert m["places"]["computable"] is True
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("plain.log: ") and "inside islands vs" in "\n".join(lines)
    last = json.loads(lines[-1])
    assert last["log"] == "plain.log" and last["islands_per_place"] == m["places"][
        "islands_per_place"] and last["bridged_covered_relations"] is None
    # The figure is titled with the log's name, in the image and in its metadata.
    title = Image.open(out / "islands.png").text["Title"]
    assert "plain.log" in title and "Intel" not in title


def test_a_reference_of_another_log_is_refused_naming_it(
        tmp_path: Path, room: str, capsys: pytest.CaptureFixture[str]) -> None:
    sim = syn.simulate_log(room, beams=181, goals=1, seed=6)
    paths = syn.write_all(sim, tmp_path / "a")
    other = tmp_path / "other.reference"
    rng = np.random.default_rng(1)
    times = np.sort(rng.uniform(0.0, 500.0, 40))
    other.write_text("".join(f"{t:.6f} 0 0 0\n" for t in times))
    assert main(["eval-relations", "--log", str(paths["log"]), "--reference", str(other),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "other.reference" in err and "not a trajectory of this log" in err


def _flaser(t: float, n: int = 181, r: str = "1.0", pose: str = "0 0 0") -> str:
    return f"FLASER {n} " + " ".join([r] * n) + f" {pose} {pose} {t} h {t}"


def _odom(t: float, x: float = 0.0) -> str:
    return f"ODOM {x} 0 0 0 0 0 {t} h {t}"


GOOD = [_odom(0.5), _flaser(1.0), _odom(1.5, 0.1), _flaser(2.0, pose="0.1 0 0"),
        _odom(2.5, 0.2), _flaser(3.0, pose="0.2 0 0")]


@pytest.mark.parametrize(("lines", "rc", "says"), [
    ([*GOOD, "SONARX 1 2 3", "FOO"], 0, None),  # unknown lines: counted
    ([*GOOD[:3], _flaser(2.0, n=180)], 2, "mixed scan lengths"),
    ([*GOOD[:3], _flaser(2.0, r="nan")], 2, "NaN"),
    ([*GOOD[:3], _flaser(2.0, r="-0.5")], 2, "negative range"),
    ([*GOOD, _odom(3.5), _flaser(-9.0)], 2, "before an earlier scan"),
    ([*GOOD, _flaser(1.0)], 2, "share a timestamp"),
    ([_flaser(1.0), _flaser(2.0), _flaser(3.0)], 2, "no ODOM lines"),
    ([*GOOD[:3], "FLASER 181 1.0"], 2, "needs 192 fields"),
    (["SONAR 0.4 3 1 1 1 0 0 0 0 0 2 0 0 1.0 h 1.0", *GOOD[:1]], 2, "SONAR with 3"),
])
def test_bad_logs_are_one_line_errors_or_counted_skips(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], lines: list[str], rc: int,
        says: str | None) -> None:
    log = tmp_path / "bad.log"
    log.write_text("\n".join(lines) + "\n")
    assert main(["eval-relations", "--log", str(log), "--out", str(tmp_path / "o")]) == rc
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if rc == 0:
        m = json.loads((tmp_path / "o" / "metrics.json").read_text())
        assert m["skipped_lines"] == {"SONARX": 1, "FOO": 1}
        return
    assert len(err.strip().splitlines()) == 1 and "bad.log" in err and says in err
    assert not (tmp_path / "o").exists()


def test_relations_outside_the_log_are_counted_or_refused(
        tmp_path: Path, room: str, capsys: pytest.CaptureFixture[str]) -> None:
    sim = syn.simulate_log(room, beams=181, goals=1, seed=8)
    paths = syn.write_all(sim, tmp_path / "s")
    far = tmp_path / "far.relations"
    t1 = np.sort(np.random.default_rng(2).uniform(2.0e9, 2.0e9 + 1e4, 20))
    far.write_text("".join(f"{t:.6f} {t + 2.0:.6f} 1 0 0 0 0 0\n" for t in t1))
    assert main(["eval-relations", "--log", str(paths["log"]), "--relations", str(far),
                 "--time-offset-s", str(syn.UNIX_START_S), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "none of the 20 relations lies within the log's time span" in err
    assert "Traceback" not in err
    assert main(["eval-relations", "--log", str(paths["log"]), "--relations", str(far),
                 "--out", str(tmp_path / "o")]) == 2
    assert "not of this log" in capsys.readouterr().err
    assert main(["eval-relations", "--log", str(paths["log"]), "--scan-lines", "SONAR",
                 "--out", str(tmp_path / "o")]) == 2
    assert "no SONAR lines" in capsys.readouterr().err


def _bad_bag(path: Path, case: str) -> None:
    """A recording with one kind of bad input (see the test's cases)."""
    from island_mapping.bag.writer import BagWriter
    from island_msgs_py.conversions import arrays_to_scan, pose_to_odometry
    from island_msgs_py.types import Pose2D
    from sensor_msgs.msg import Range

    with BagWriter(path) as w:
        for k in range(4):
            log_ns = round((100.0 + k) * 1e9)  # recorded in order; stamped 20 s back at k = 3
            t_ns = log_ns - (round(20e9) if case == "time_back" and k == 3 else 0)
            w.write("/odom", pose_to_odometry(Pose2D(0.1 * k, 0.0, 0.0), None, t_ns, "odom"),
                    log_ns)
            n = 180 if case == "mixed" and k == 2 else 181
            if case == "ranges_only":
                w.write("/sonar/range_0", Range(range=1.0), log_ns)
                continue
            scan = arrays_to_scan(np.full(n, 2.0), np.radians(np.linspace(-90.0, 90.0, n)),
                                  (0.1, 30.0), t_ns)
            if case == "nan_ranges":  # NaN and negative ranges, as a driver may write them
                scan.ranges = [math.nan if i % 3 == 0 else -1.0 if i % 3 == 1 else 2.0
                               for i in range(n)]
            if case == "nan_angles":
                scan.angle_increment = math.nan
            w.write("/scan", scan, log_ns)


@pytest.mark.parametrize(("case", "says"), [
    ("nan_ranges", None),  # no return: counted
    ("mixed", "180 beams or other angles"),
    ("nan_angles", "--fov-deg"),
    ("time_back", "before an earlier scan"),
    ("ranges_only", "record the ring as one LaserScan"),
])
def test_bad_recordings_are_one_line_errors_or_counted_skips(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], case: str, says: str | None) -> None:
    bag = tmp_path / case
    _bad_bag(bag, case)
    rc = main(["replay", str(bag), "--passive", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if says is None:
        assert rc == 0
        m = json.loads((tmp_path / "o" / "metrics.json").read_text())
        assert m["skipped"]["no_return_ranges"] == 4 * 121
        return
    assert rc == 2 and case in err and says in err
