"""`islands scan` and `islands world` through island_mapping.cli.main."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from island_mapping.cli import main
from island_msgs_py.types import Pose2D
from island_sim.core.sonar import SonarConfig, SonarModel
from island_sim.core.world_loader import load_world


def _run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, dict, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, (json.loads(out) if code == 0 else {}), err


def test_scan_ideal_matches_the_model(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = _run(capsys, "scan", "--world", "paper_fig4", "--pose", "12,9,0", "--ideal")
    assert code == 0
    assert len(out["angles"]) == len(out["ranges"]) == 16
    assert out["angles"][4] == pytest.approx(math.pi / 2)
    expect = SonarModel(SonarConfig(ideal=True)).scan(load_world("paper_fig4"), Pose2D(12, 9, 0))
    got = np.array([math.inf if r is None else r for r in out["ranges"]])
    assert np.array_equal(got, expect)
    assert out["ranges"][4] == pytest.approx(1.0)  # the corridor wall 1 m to the left
    assert out["ranges"][0] is None  # 50 m of corridor ahead: beyond range -> null


def test_scan_noise_is_seeded(capsys: pytest.CaptureFixture[str]) -> None:
    args = ("scan", "--world", "square_room", "--pose", "3,4,0.2")
    a = _run(capsys, *args, "--seed", "1")[1]
    b = _run(capsys, *args, "--seed", "1")[1]
    c = _run(capsys, *args, "--seed", "2")[1]
    assert a == b and a["ranges"] != c["ranges"]
    d = _run(capsys, "scan", "--world", "square_room")[1]  # default: the start pose
    assert d["pose"] == [5.0, 5.0, 0.0]
    e = _run(capsys, "scan", "--world", "square_room", "--pose=-1,2,-0.5")[1]
    assert e["pose"] == [-1.0, 2.0, -0.5]


def test_scan_world_file(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "wall.yaml"
    path.write_text("segments: [[-10, 2, 10, 2]]\nstart_pose: [0, 0, 1.5707963267948966]\n")
    code, out, _ = _run(capsys, "scan", "--world", str(path), "--ideal")
    assert code == 0 and out["world"] == "wall"
    assert out["ranges"][0] == pytest.approx(2.0)


@pytest.mark.parametrize(
    ("pose", "match"),
    [("1,2", "three numbers"), ("a,b,c", "not a number"), ("1,nan,0", "NaN")],
)
def test_scan_bad_pose(capsys: pytest.CaptureFixture[str], pose: str, match: str) -> None:
    code, _, err = _run(capsys, "scan", "--world", "corridor", "--pose", pose)
    assert code == 2
    assert match in err and err.startswith("islands scan: error:")


def test_scan_bad_world(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("segments: [[0, 0, 0, 0]]\n")
    code, _, err = _run(capsys, "scan", "--world", str(bad), "--pose", "0,0,0")
    assert code == 2 and "bad.yaml" in err and "zero length" in err


def test_world_summary_and_save(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out_path = tmp_path / "fig3.yaml"
    code, out, _ = _run(capsys, "world", "paper_fig3", "--save", str(out_path))
    assert code == 0
    world = load_world("paper_fig3")
    assert out["segments"] == world.segments.shape[0]
    assert out["bounds"] == list(world.bounds)
    assert out["name"] == "paper_fig3"
    code, again, _ = _run(capsys, "world", str(out_path))
    assert code == 0 and again["segments"] == out["segments"]
    assert again["start_pose"] == out["start_pose"]


def test_world_image_with_resolution(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    img = np.full((10, 20), 255, dtype=np.uint8)
    img[0, :] = img[-1, :] = img[:, 0] = img[:, -1] = 0
    path = tmp_path / "box.pgm"
    path.write_bytes(b"P5\n20 10\n255\n" + img.tobytes())
    code, out, _ = _run(capsys, "world", str(path), "--resolution", "0.5")
    assert code == 0
    assert out["size"] == pytest.approx([10.0, 5.0])
    code, _, err = _run(capsys, "world", str(path), "--resolution", "-1")
    assert code == 2 and "--resolution" in err


@pytest.mark.parametrize(
    ("name", "content", "match"),
    [
        ("w.yaml", "name: x\n", "missing key 'segments'"),
        ("w.yaml", "segments: [[0, 0, .nan, 1]]\n", "NaN"),
        ("w.txt", "x", "unknown world file extension"),
        ("w.png", "not an image", "not a PNG"),
        ("absent.yaml", None, "no such file"),
    ],
)
def test_world_errors_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, content: str | None, match: str
) -> None:
    path = tmp_path / name
    if content is not None:
        path.write_text(content)
    code, _, err = _run(capsys, "world", str(path))
    assert code == 2
    assert err.startswith("islands world: error:") and name in err and match in err
    assert "Traceback" not in err
