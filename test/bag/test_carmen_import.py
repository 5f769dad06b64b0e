"""CARMEN importer: the Intel log's counts, the raw-odometry rule, sonar-like mode, bad lines."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

INTEL_SCANS = 910


@pytest.fixture(scope="module")
def intel_log(shared_data: Path) -> Path:
    path = shared_data / "intel" / "intel.gfs.log"
    if not path.is_file():
        pytest.skip(f"{path} missing")
    return path


def test_read_carmen_counts_and_raw_odometry_rule(intel_log: Path) -> None:
    from island_mapping.bag.carmen import read_carmen
    from island_msgs_py.geometry import relative_poses as relative_pose
    from island_msgs_py.geometry import wrap_angles as wrap_angle

    log = read_carmen(intel_log)
    assert log.n_scans == INTEL_SCANS
    assert log.ranges.shape == (INTEL_SCANS, 180)
    assert log.corrected.shape == log.raw_odometry.shape == (INTEL_SCANS, 3)
    # Logged stamps jitter (4 scans go backwards); the log times used in bags do not.
    assert np.all(np.diff(log.scan_log_times_s) >= 0)
    assert np.all(log.scan_log_times_s <= log.times_s)
    assert np.max(log.times_s - log.scan_log_times_s) < 1.0
    assert np.mean(log.times_s == log.scan_log_times_s) > 0.9
    assert log.times_s[0] == pytest.approx(32.9068)
    assert log.times_s[-1] - log.times_s[0] == pytest.approx(2651, abs=10)  # README: 2651 s
    # The rule, recomputed independently from the file text for a few steps.
    lines = intel_log.read_text().splitlines()
    scans, last_odom, prev_kind = [], None, ""
    corrected_prev = np.zeros(3)
    increments = []
    for line in lines:
        tok = line.split()
        if tok[0] == "FLASER":
            pose = np.array([float(v) for v in tok[182:185]])
            increments.append(relative_pose(corrected_prev, np.asarray(last_odom))[0])
            corrected_prev, last_odom = pose, None
            scans.append(pose)
        elif tok[0] == "ODOM" and prev_kind != "FLASER":
            last_odom = [float(v) for v in tok[1:4]]
        prev_kind = tok[0]
        if len(scans) == 6:
            break
    got = relative_pose(log.raw_odometry[:5], log.raw_odometry[1:6])
    np.testing.assert_allclose(got, np.asarray(increments[1:6]), atol=1e-9)
    np.testing.assert_allclose(log.raw_odometry[0], increments[0], atol=1e-12)
    # README: per step the raw increment differs from the corrected one by a median 5 cm / 2.6 deg.
    d = relative_pose(log.raw_odometry[:-1], log.raw_odometry[1:]) - relative_pose(
        log.corrected[:-1], log.corrected[1:]
    )
    assert np.median(np.hypot(d[:, 0], d[:, 1])) == pytest.approx(0.05, abs=0.01)
    assert math.degrees(np.median(np.abs(wrap_angle(d[:, 2])))) == pytest.approx(2.6, abs=0.3)
    # The raw odometry drifts away from the corrected path (it is not the corrected pose).
    drift = np.hypot(*(log.raw_odometry[-1, :2] - log.corrected[-1, :2]))
    assert drift > 1.0
    # ODOM stamps are non-decreasing, and the pose of the last ODOM before a scan is that scan's
    # raw odometry.
    assert np.all(np.diff(log.odom_times_s) >= 0)
    last = np.array([np.nonzero(log.odom_scan_index == i)[0].max() for i in range(1, 50)])
    np.testing.assert_allclose(log.odom_raw[last], log.raw_odometry[1:50], atol=1e-9)


@pytest.fixture(scope="module")
def intel_bag_16(intel_log: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    from island_mapping.cli import main

    out = tmp_path_factory.mktemp("carmen") / "intel16"
    assert main(["bag", "import-carmen", str(intel_log), "--out", str(out), "--beams", "16"]) == 0
    return out


def test_import_carmen_sonar_like_bag(intel_log: Path, intel_bag_16: Path) -> None:
    from island_mapping.bag.carmen import read_carmen, sonar_like_indices
    from island_mapping.bag.reader import open_bag

    log = read_carmen(intel_log)
    bag = open_bag(intel_bag_16)
    assert bag.topics["/scan"].message_count == INTEL_SCANS
    assert bag.topics["/scan"].type_name == "sensor_msgs/msg/LaserScan"
    assert bag.topics["/gmapping_pose"].message_count == INTEL_SCANS
    assert bag.topics["/odom"].message_count == log.odom_raw.shape[0]
    assert bag.topics["/clock"].type_name == "rosgraph_msgs/msg/Clock"
    idx = sonar_like_indices(180, 16)
    assert len(set(np.diff(idx).tolist()) - {11, 12}) == 0  # evenly spaced (11.25 beams)
    scans = [m.deserialize() for m in bag.messages(["/scan"], end_ns=int(40e9))]
    assert len(scans) >= 3
    first = scans[0]
    assert len(first.ranges) == 16 and first.header.frame_id == "base_laser"
    np.testing.assert_allclose(first.ranges, log.ranges[0, idx], rtol=1e-6)
    assert first.angle_increment == pytest.approx(math.radians(11.25), rel=1e-6)
    t0 = first.header.stamp.sec + first.header.stamp.nanosec * 1e-9
    assert t0 == pytest.approx(log.times_s[0], abs=1e-6)
    odom = [m.deserialize() for m in bag.messages(["/odom"], end_ns=int(33e9))]
    last = odom[-1]  # the last ODOM before the first scan is its raw odometry
    assert last.pose.pose.position.x == pytest.approx(log.raw_odometry[0, 0])
    yaw = 2 * math.atan2(last.pose.pose.orientation.z, last.pose.pose.orientation.w)
    assert yaw == pytest.approx(log.raw_odometry[0, 2], abs=1e-9)
    assert last.pose.covariance[0] > 0 and last.pose.covariance[35] > 0


def test_import_full_laser_keeps_180_beams(intel_log: Path, tmp_path: Path) -> None:
    from island_mapping.bag.carmen import FLASER_ANGLE_MIN_RAD, read_carmen
    from island_mapping.bag.reader import open_bag

    # A short log cut from the real one keeps this test fast.
    lines = intel_log.read_text().splitlines()
    n_flaser = 0
    cut = []
    for line in lines:
        cut.append(line)
        if line.startswith("FLASER"):
            n_flaser += 1
            if n_flaser == 3:
                break
    short = tmp_path / "short.log"
    short.write_text("\n".join(cut) + "\n")
    from island_mapping.bag.carmen import import_carmen

    rep = import_carmen(short, tmp_path / "bag")
    assert rep.scans == 3 and rep.beams == 180
    scans = [m.deserialize() for m in open_bag(tmp_path / "bag").messages(["/scan"])]
    assert len(scans) == 3 and len(scans[2].ranges) == 180
    assert scans[0].angle_min == pytest.approx(FLASER_ANGLE_MIN_RAD, rel=1e-6)
    np.testing.assert_allclose(scans[2].ranges, read_carmen(short).ranges[2], rtol=1e-6)


@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("FLASER 3 1.0 2.0 0 0 0 0 0 0 1.0 host 1.0", r"bad\.log:2: FLASER with 3 beams"),
        ("FLASER x 1.0", r"bad\.log:2: FLASER beam count 'x'"),
        ("FLASER 2 1.0 abc 0 0 0 0 0 0 1.0 host 1.0", r"bad\.log:2: FLASER: could not convert"),
        ("ODOM 1 2 3 0 0 0 1.0 host", r"bad\.log:2: ODOM needs 10 fields"),
        ("ODOM 1 nan 3 0 0 0 1.0 host 1.0", r"bad\.log:2: ODOM: NaN"),
    ],
)
def test_bad_lines_name_file_and_line(tmp_path: Path, line: str, match: str) -> None:
    from island_mapping.bag.carmen import read_carmen
    from island_mapping.bag.errors import CarmenFormatError

    bad = tmp_path / "bad.log"
    bad.write_text("ODOM 0 0 0 0 0 0 0.5 host 0.5\n" + line + "\n")
    with pytest.raises(CarmenFormatError, match=match):
        read_carmen(bad)


def test_cli_import_bad_input_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from island_mapping.cli import main

    empty = tmp_path / "empty.log"
    empty.write_text("NEFF 3\n")
    assert main(["bag", "import-carmen", str(empty), "--out", str(tmp_path / "o")]) == 2
    assert "no FLASER, ROBOTLASER1, RLASER, SONAR line" in capsys.readouterr().err
    assert main(["bag", "import-carmen", str(tmp_path / "missing.log"),
                 "--out", str(tmp_path / "o2")]) == 2
    assert "missing.log" in capsys.readouterr().err
