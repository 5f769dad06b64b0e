"""`islands measure` and `islands fig3` end to end on a small world file."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from island_mapping.cli import main
from island_mapping.core.measure import MeasureConfig, line_measure

OUTLINE = [(0, 0), (8, 0), (8, 2), (40, 2), (40, 4), (8, 4), (8, 6), (0, 6)]
SEGMENTS = [[*OUTLINE[i], *OUTLINE[(i + 1) % len(OUTLINE)]] for i in range(len(OUTLINE))]


@pytest.fixture
def world_file(tmp_path: Path) -> Path:
    path = tmp_path / "room_corridor.json"
    path.write_text(json.dumps({"name": "room_corridor", "segments": SEGMENTS}))
    return path


def _rows(text: str) -> list[dict]:
    return [json.loads(line) for line in text.strip().splitlines()]


def test_measure_prints_one_json_object_per_point(world_file: Path, capsys) -> None:
    rc = main(["measure", "--world", str(world_file), "--at", "4,3", "--at", "24,3"])
    assert rc == 0
    rows = _rows(capsys.readouterr().out)
    assert [(r["x"], r["y"]) for r in rows] == [(4.0, 3.0), (24.0, 3.0)]
    assert all(set(r) == {"x", "y", "c_par", "c_perp", "q", "f", "r"} for r in rows)
    expected = line_measure(np.array(SEGMENTS, float), [[4.0, 3.0]], MeasureConfig())
    assert rows[0]["r"] == pytest.approx(expected.r[0], abs=1e-6)
    assert rows[0]["c_par"] == pytest.approx(expected.c_par[0], abs=1e-6)
    assert rows[1]["c_perp"] == 0.0 and rows[1]["r"] == 0.0  # mid-corridor


def test_measure_options_reach_the_config(world_file: Path, capsys) -> None:
    args = ["measure", "--world", str(world_file), "--at", "4,3"]
    main(args)
    base = _rows(capsys.readouterr().out)[0]
    main([*args, "--c", "2.0", "--k", "0.1", "--m", "2", "--reflect-deg", "45",
          "--max-range", "5", "--angular-res-deg", "1"])
    changed = _rows(capsys.readouterr().out)[0]
    cfg = MeasureConfig(k=0.1, c=2.0, m=2.0, reflect_deg=45.0, max_range_m=5.0,
                        angular_res_deg=1.0)
    want = line_measure(np.array(SEGMENTS, float), [[4.0, 3.0]], cfg)
    assert changed["r"] == pytest.approx(want.r[0], abs=1e-6) and changed["r"] != base["r"]
    main([*args, "--eps", "0.3", "--eps-step", "0.1"])
    eps = _rows(capsys.readouterr().out)[0]
    assert eps["r_point"] == base["r"] and eps["r"] != base["r"]


def test_measure_fisher_has_score_and_the_common_keys(world_file: Path, capsys) -> None:
    rc = main(["measure", "--world", str(world_file), "--at", "4,3", "--at", "24,3",
               "--model", "fisher"])
    assert rc == 0
    room, corridor = _rows(capsys.readouterr().out)
    assert {"x", "y", "c_par", "c_perp", "q", "f", "r", "score", "min_eig", "cond"} <= set(room)
    assert room["score"] == room["r"] > 0.3
    assert corridor["score"] == 0.0 and corridor["cond"] is None


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--at", "4;3"], "--at"),
        (["--at", "4,nan"], "finite"),
        (["--at", "4,3", "--c", "0"], "MeasureConfig.c"),
        (["--at", "4,3", "--model", "fisher", "--eps", "0.2"], "--eps"),
    ],
)
def test_measure_bad_input_exits_2_naming_it(world_file: Path, capsys, extra, message) -> None:
    assert main(["measure", "--world", str(world_file), *extra]) == 2
    assert message in capsys.readouterr().err


def test_measure_missing_world_exits_2(tmp_path: Path, capsys) -> None:
    assert main(["measure", "--world", str(tmp_path / "none.yaml"), "--at", "1,1"]) == 2
    assert "none.yaml" in capsys.readouterr().err


def test_fig3_writes_pictures_and_metrics(world_file: Path, tmp_path: Path, capsys) -> None:
    out = tmp_path / "fig3"
    rc = main(["fig3", "--world", str(world_file), "--out", str(out), "--resolution", "1.0",
               "--map-resolution", "1.0", "--trials", "1", "--seed", "4"])
    assert rc == 0
    captured = capsys.readouterr()
    assert "confidence map: 100%" in captured.err  # the progress bar (one line per tenth: no tty)
    for name in ("r_map.png", "fisher_map.png", "confidence_map.png", "residual.png"):
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    metrics = json.loads((out / "metrics.json").read_text())
    for model in ("line", "fisher"):
        for key in ("frac_residual_gt_0_4", "spearman", "auc"):
            assert key in metrics[model] and key in metrics[model]["fitted"]
    assert set(metrics["line"]["fitted"]["params"]) == {"k", "c", "m"}
    assert metrics["seed"] == 4 and metrics["params_source"] == "defaults"
    summary = json.loads(captured.out)
    assert summary["line"]["auc"] == metrics["line"]["auc"]

    # Parameters fit on one run, reported on another.
    out2 = tmp_path / "fig3b"
    rc = main(["fig3", "--world", str(world_file), "--out", str(out2), "--resolution", "1.0",
               "--map-resolution", "2.0", "--trials", "1", "--no-fit",
               "--params", str(out / "metrics.json")])
    assert rc == 0
    m2 = json.loads((out2 / "metrics.json").read_text())
    assert m2["line"]["params"] == metrics["line"]["fitted"]["params"]
    assert "fitted" not in m2["line"]


def test_fig3_bad_params_file_exits_2(world_file: Path, tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    rc = main(["fig3", "--world", str(world_file), "--out", str(tmp_path / "o"),
               "--params", str(bad)])
    assert rc == 2 and "--params" in capsys.readouterr().err
