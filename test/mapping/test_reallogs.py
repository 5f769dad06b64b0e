"""Logs other than Intel's: scan geometry and times read from the data, bad input refused or
counted, islands built and scored on small synthetic CARMEN logs of other buildings."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from island_mapping.cli import main
from island_mapping.core.lines import point_segment_distance
from island_mapping.evaluation import synthetic_log as syn
from island_mapping.logs import carmen, geometry, islands, times
from island_msgs_py.geometry import from_frame
from island_sim.core.world_loader import load_world

ROOM = "house_expo_room_0000.json"
ODOM = "ODOM 0 0 0 0 0 0 0.5 h 0.5"  # the raw odometry a log must have


@pytest.fixture(scope="module")
def room(shared_data: Path) -> str:
    return str(shared_data / "floorplans" / ROOM)


def _write(tmp_path: Path, lines: list[str], name: str = "syn.log") -> Path:
    p = tmp_path / name
    p.write_text("\n".join(lines) + "\n")
    return p


def _wall_distance(world_spec: str, log: carmen.CarmenLog, truth: np.ndarray,
                   angles: np.ndarray) -> float:
    """Median distance [m] of the scans' points, placed at the true poses, to the walls."""
    world = load_world(world_spec)
    d = []
    for r, pose in zip(log.ranges_m, truth, strict=True):
        pts = islands.scan_points(r, angles, 20.0)
        d.append(point_segment_distance(from_frame(pts, pose), world.segments).min(axis=1))
    return float(np.median(np.concatenate(d)))


@pytest.mark.parametrize(("beams", "params"), [(361, True), (181, True), (181, False),
                                               (361, False)])
def test_imported_scan_points_lie_on_the_known_walls(tmp_path: Path, room: str, beams: int,
                                                     params: bool) -> None:
    sim = syn.simulate_log(room, beams=beams, goals=1, seed=3)
    path = _write(tmp_path, syn.carmen_lines(sim, params=params))
    log = carmen.carmen_log(carmen.read_carmen_records(path))
    assert log.geometry is not None
    assert log.geometry.n_beams == beams
    assert math.degrees(log.geometry.increment_rad) == pytest.approx(180.0 / (beams - 1))
    assert math.degrees(log.geometry.angle_min_rad) == pytest.approx(-90.0)
    assert ("PARAM" in log.geometry.source) == params
    # The scans read with their geometry lie on the walls (1 cm range noise) ...
    assert _wall_distance(room, log, sim.truth, log.geometry.angles()) < 0.03
    # ... and the old assumption (1 deg from -90 deg for any count) does not for 0.5 deg scans.
    if beams == 361:
        wrong = -math.pi / 2 + np.radians(np.arange(beams, dtype=float))
        assert _wall_distance(room, log, sim.truth, wrong) > 0.1


def test_a_geometry_the_log_does_not_give_is_an_error_naming_the_options(tmp_path: Path,
                                                                       room: str) -> None:
    sim = syn.simulate_log(room, beams=271, fov_deg=270.0, goals=1, seed=4)
    path = _write(tmp_path, syn.carmen_lines(sim, params=False), "hokuyo.log")
    with pytest.raises(geometry.ScanGeometryError, match=r"hokuyo\.log.*--fov-deg"):
        carmen.carmen_log(carmen.read_carmen_records(path))
    given = geometry.GeometryOverride(fov_deg=270.0)
    log = carmen.carmen_log(carmen.read_carmen_records(path), given)
    assert log.geometry is not None and log.geometry.fov_deg == pytest.approx(270.0)
    assert _wall_distance(room, log, sim.truth, log.geometry.angles()) < 0.03
    # The CLI says the same, exit 2, no traceback.
    rc = main(["eval-relations", "--log", str(path), "--out", str(tmp_path / "o")])
    assert rc == 2


def test_param_lines_that_contradict_the_beam_count_are_an_error(tmp_path: Path) -> None:
    lines = ["PARAM laser_front_laser_resolution 1.0", "PARAM laser_front_laser_fov 180",
             "FLASER 361 " + " ".join(["1.0"] * 361) + " 0 0 0 0 0 0 1.0 h 1.0"]
    with pytest.raises(geometry.ScanGeometryError, match="do not fit"):
        carmen.carmen_log(carmen.parse_carmen(lines, "contra.log"))


def test_robotlaser1_carries_its_own_angles() -> None:
    n = 5
    ranges = " ".join(["2.0"] * n)
    line = (f"ROBOTLASER1 0 -1.0 2.0 0.5 30.0 0.01 0 {n} {ranges} 0 0.1 0 0 0 0 0 0 0 0 0 0 "
            "12.5 host 12.5")
    recs = carmen.parse_carmen([ODOM, line, line.replace("12.5", "13.5")], "rl1.log")
    log = carmen.carmen_log(recs)
    assert log.geometry is not None and log.geometry.source == "ROBOTLASER1 fields"
    assert log.geometry.angles() == pytest.approx([-1.0, -0.5, 0.0, 0.5, 1.0])
    assert log.mount == pytest.approx((0.1, 0.0, 0.0))  # laser 0.1 m ahead of the robot


def test_g_times_that_collapse_scans_are_refused(tmp_path: Path, room: str) -> None:
    sim = syn.simulate_log(room, beams=181, goals=1, seed=5)
    path = _write(tmp_path, syn.carmen_lines(sim, unix_times=True, g_times=True), "g.log")
    with pytest.raises(times.LogTimeError, match=r"g\.log.*share a timestamp.*%g"):
        carmen.carmen_log(carmen.read_carmen_records(path))
    # At full precision the same log reads, every scan at its own time.
    full = _write(tmp_path, syn.carmen_lines(sim, unix_times=True), "full.log")
    log = carmen.carmen_log(carmen.read_carmen_records(full))
    assert np.unique(log.times_s).size == sim.times_s.size
    assert log.times_s - syn.UNIX_START_S == pytest.approx(sim.times_s, abs=1e-6)


def _flaser(t: float, n: int = 181, r: str = "1.0") -> str:
    return f"FLASER {n} " + " ".join([r] * n) + f" 0 0 0 0 0 0 {t} h {t}"


@pytest.mark.parametrize(("lines", "error", "match"), [
    ([_flaser(1.0), _flaser(2.0, n=180)], carmen.CarmenFormatError, "mixed scan lengths"),
    ([_flaser(1.0), _flaser(2.0, r="nan")], carmen.CarmenFormatError, "NaN"),
    ([_flaser(1.0), _flaser(2.0, r="-1.0")], carmen.CarmenFormatError, "negative range"),
    ([_flaser(100.0), _flaser(90.0)], times.LogTimeError, "before an earlier scan"),
    ([_flaser(1.0), _flaser(1.0)], times.LogTimeError, "share a timestamp"),
])
def test_bad_logs_are_clear_errors(lines: list[str], error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        carmen.carmen_log(carmen.parse_carmen(lines, "bad.log"))


def test_unknown_lines_and_small_steps_back_are_counted() -> None:
    lines = ["SONARX 3 1 2 3", ODOM, _flaser(1.0), "FOO bar", _flaser(2.0), _flaser(1.5),
             _flaser(3.0)]
    log = carmen.carmen_log(carmen.parse_carmen(lines, "jitter.log"))
    assert log.skipped == {"SONARX": 1, "FOO": 1}
    assert log.times is not None and log.times.backwards == 1
    assert log.times.max_backward_s == pytest.approx(0.5)


@pytest.mark.parametrize("world", ["gen:office:seed=3", ROOM])
def test_islands_on_a_synthetic_building_through_the_cli(
        tmp_path: Path, shared_data: Path, capsys: pytest.CaptureFixture[str], world: str) -> None:
    spec = str(shared_data / "floorplans" / world) if world == ROOM else world
    sim = syn.simulate_log(spec, beams=361, goals=2, seed=7)
    paths = syn.write_all(sim, tmp_path / "b", unix_times=False)
    # Relations outside the log's span are counted and left out, not scored.
    rel = paths["relations"].read_text().splitlines()
    paths["relations"].write_text("\n".join([*rel, "2e9 2e9 1 0 0 0 0 0"]) + "\n")
    out = tmp_path / "out"
    rc = main(["eval-relations", "--log", str(paths["log"]), "--relations",
               str(paths["relations"]), "--reference", str(paths["reference"]),
               "--out", str(out)])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["log"] == "b.log" and m["geometry"]["increment_deg"] == 0.5
    assert m["time_offset"]["offset_s"] == pytest.approx(syn.UNIX_START_S, abs=1e-3)
    assert m["relations_outside_log"] == 1 and m["relations"] == len(rel)
    assert m["island_count"] >= 1 and m["bridged"]["covered_relations"] > 0
    # Laser islands on a true-geometry log: centimetre agreement with the truth.
    assert m["bridged"]["mean_trans_err_m"] < 0.05
    inside = m["reference"]["inside_islands"]
    assert inside["count"] > 0 and inside["mean_trans_err_m"] < 0.05
    assert m["places"]["places"] >= 1
    text = capsys.readouterr().out
    assert "b.log" in text and "bridged, headline" in text and "islands per place" in text


def test_replay_passive_of_an_imported_log_builds_the_same_islands(
        tmp_path: Path, room: str, capsys: pytest.CaptureFixture[str]) -> None:
    sim = syn.simulate_log(room, beams=181, goals=2, seed=9)
    paths = syn.write_all(sim, tmp_path / "r")
    bag = tmp_path / "bag"
    assert main(["bag", "import-carmen", str(paths["log"]), "--out", str(bag)]) == 0
    assert main(["eval-relations", "--log", str(paths["log"]), "--relations",
                 str(paths["relations"]), "--out", str(tmp_path / "ev")]) == 0
    assert main(["replay", str(bag), "--passive", "--relations", str(paths["relations"]),
                 "--out", str(tmp_path / "rp")]) == 0
    ev = json.loads((tmp_path / "ev" / "metrics.json").read_text())
    rp = json.loads((tmp_path / "rp" / "metrics.json").read_text())
    assert rp["geometry"]["source"] == "LaserScan fields"
    assert rp["geometry"]["increment_deg"] == pytest.approx(1.0)
    # The bag has no odometry before the first scan: that scan is dropped, and counted.
    assert rp["skipped"]["scans_before_odometry"] == 1 and rp["scans"] == ev["scans"] - 1
    assert rp["island_count"] == ev["island_count"] >= 1
    assert rp["bridged"]["covered_relations"] == pytest.approx(
        ev["bridged"]["covered_relations"], abs=3)
    assert rp["bridged"]["mean_trans_err_m"] < 0.05
    assert "the recording's /gmapping_pose" in rp["reference"]["name"]
    assert "rp" not in capsys.readouterr().err
