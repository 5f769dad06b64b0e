"""`islands eval-relations` and `islands sonar-ring` end to end on the first part of the data."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from island_mapping.cli import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def test_eval_relations_writes_metrics_and_islands_figure(shared_data: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    out = tmp_path / "run"
    rc = main([
        "eval-relations", "--log", str(shared_data / "intel" / "intel.gfs.log"),
        "--relations", str(shared_data / "intel" / "intel.relations"), "--out", str(out),
        "--max-scans", "30", "--seed", "3", "--time-offset-s", "976052857.338",
    ])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    for key in ("covered_relations", "mean_trans_err_m", "median_trans_err_m", "mean_rot_err_deg",
                "median_rot_err_deg", "island_count", "gmapping_same_relations",
                "gmapping_all_relations", "bridged"):
        assert key in m, key
    assert m["scans"] == 30 and m["seed"] == 3 and m["beams"] == 180
    assert m["place_recognition"] is False and m["revisit_relations_covered"] == 0
    assert m["island_count"] >= 1
    # The README's offset gives its GMapping figure; the geometry is read from the log.
    assert round(m["gmapping_all_relations"]["mean_trans_err_m"], 3) == 0.065
    assert m["time_offset"]["source"].startswith("given")
    assert m["geometry"]["beams"] == 180 and m["geometry"]["increment_deg"] == 1.0
    assert m["log"] == "intel.gfs.log"
    b = m["bridged"]
    assert b["covered_relations"] >= 1
    assert b["mean_trans_err_m"] < 0.1
    assert b["gmapping_same_relations"]["count"] == b["covered_relations"]
    assert (out / "islands.png").read_bytes()[:8] == PNG_MAGIC
    assert not list(out.glob(".*tmp*"))  # atomic writes leave no temporaries
    printed_lines = capsys.readouterr().out.strip().splitlines()
    printed = json.loads(printed_lines[-1])
    assert printed["island_count"] == m["island_count"]
    # The console gives the headline (bridged) figures, not only the strict ones.
    assert any("bridged, headline" in ln and f"{b['covered_relations']} covered" in ln
               for ln in printed_lines)


def test_eval_relations_bad_relations_file_exit_2_with_line(shared_data: Path, tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]
                                                            ) -> None:
    bad = tmp_path / "bad.relations"
    bad.write_text("976052905.1 976052911.8 0.1 0.2 0 0 0 0.3\n976052905.1 976052911.8 0.1\n")
    rc = main(["eval-relations", "--log", str(shared_data / "intel" / "intel.gfs.log"),
               "--relations", str(bad), "--out", str(tmp_path / "o")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "bad.relations:2" in err and "expected 8 fields" in err
    assert not (tmp_path / "o").exists()


def test_eval_relations_missing_log_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                           ) -> None:
    rel = tmp_path / "r.relations"
    rel.write_text("1 2 0 0 0 0 0 0\n")
    rc = main(["eval-relations", "--log", str(tmp_path / "missing.log"), "--relations",
               str(rel), "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "missing.log" in capsys.readouterr().err


def test_sonar_ring_cli_scores_labels(shared_data: Path, tmp_path: Path) -> None:
    out = tmp_path / "ring"
    rc = main(["sonar-ring", "--data", str(shared_data / "sonar" / "sensor_readings_24.data"),
               "--out", str(out), "--limit", "120"])
    assert rc == 0
    m = json.loads((out / "metrics.json").read_text())
    assert m["readings"] == 120
    per = m["per_label"]
    assert sum(v["count"] for v in per.values()) == 120
    for v in per.values():
        assert 0.0 <= v["median_r"] <= 1.0 and 0.0 <= v["mean_fisher"] <= 1.0
    assert m["geometry"]["sensors"] == 24
    assert (out / "sonar_ring.png").read_bytes()[:8] == PNG_MAGIC


def test_sonar_ring_cli_malformed_line_exit_2(tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "ring.data"
    good = ",".join(["1.0"] * 24) + ",Move-Forward\n"
    data.write_text("S1,S2,OUTPUT\n" + good + good + "1.0,2.0\n")
    rc = main(["sonar-ring", "--data", str(data), "--out", str(tmp_path / "o")])
    assert rc == 2
    err = capsys.readouterr().err
    assert "ring.data:4" in err
