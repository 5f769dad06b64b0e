"""Every `islands` subcommand refuses hostile input in one line with exit code 2 (issue 17);
an internal error is one line naming its log. bench/hostile_run.py runs more cases as
processes; these run in process."""

from __future__ import annotations

from pathlib import Path

import pytest
from island_mapping.cli import main
from island_mapping.core.graph import TopoGraph

EXAMPLE_GRAPH = Path(__file__).resolve().parents[2] / "bags" / "example_graph.json"


@pytest.fixture
def files(tmp_path: Path) -> dict[str, Path]:
    texts = {
        "deep.json": "[" * 100_000 + "]" * 100_000,
        "alias.yaml": "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
            f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n"
            for p, c in zip("abcdefgh", "bcdefghi", strict=True)) + "segments: *i\n",
        "carmen.log": "ODOM 0 0 0 0 0 0 1e12 pippo 1e12\n"
                      "FLASER 180 " + "1.0 " * 180 + "0 0 0 0 0 0 1e12 pippo 1e12\n",
        "plain": "x",
    }
    out = {}
    for name, text in texts.items():
        out[name] = tmp_path / name
        out[name].write_text(text)
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: " + "[" * 100_000)
    out["bag"] = bag
    out["graph.json"] = TopoGraph.load_json(EXAMPLE_GRAPH).save_json(tmp_path / "g.json")
    return out


CASES = [
    (["world", "{alias.yaml}"], "YAML aliases"),
    (["world", "{deep.json}"], "nested"),
    (["scan", "--world", "corridor", "--pose", "1,1,0", "--seed", "-1"], "--seed"),
    (["measure", "--world", "corridor", "--at", "1e308,1e308"], "the limit"),
    (["measure", "--world", "corridor", "--at", "1,1", "--angular-res-deg", "1e-9"],
     "angular_res_deg"),
    (["fig3", "--world", "corridor", "--out", "{plain}"], "not a directory"),
    (["fig3", "--world", "corridor", "--out", "{tmp}/f", "--resolution", "1e-9"], "points"),
    (["explore", "--out", "{tmp}/e", "--domain-id", "999"], "[0, 232]"),
    (["explore", "--out", "{tmp}/e", "--sim-seconds", "nan"], "finite"),
    (["graph", "info", "{deep.json}"], "nested"),
    (["graph", "plan", "{graph.json}", "--from", str(2**63), "--to", "1"], "--from"),
    (["graph", "convert", "{graph.json}", "{tmp}"], "is a directory"),
    (["bag", "info", "{bag}"], "metadata.yaml"),
    (["bag", "play", "{bag}", "--wait-timeout", "nan"], "--wait-timeout"),
    (["bag", "import-carmen", "{carmen.log}", "--out", "{tmp}/imp"], "range of a ROS stamp"),
    (["topic", "echo", "/x", "--limit", str(10**50)], "digits"),
    (["replay", "{bag}", "--out", "{tmp}/r"], "metadata.yaml"),
    (["sonar-ring", "--data", "{carmen.log}", "--out", "{tmp}/s", "--limit", "0"], "--limit"),
    (["eval-relations", "--seed", str(10**30)], "--seed"),
]


@pytest.mark.parametrize(("argv", "message"), CASES, ids=[" ".join(c[0][:2]) for c in CASES])
def test_hostile_input_is_one_line_and_exit_2(
    files: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str],
    argv: list[str], message: str,
) -> None:
    names = {k.replace(".", "_"): str(v) for k, v in files.items()}
    args = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    args = [names.get(a.strip("{}").replace(".", "_"), a) if a.startswith("{") else a
            for a in args]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert message in err and "Traceback" not in err


def test_an_internal_error_is_one_line_naming_its_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A bug (a subcommand raising what no input error is) ends as one line with the log's
    path, and the log holds the traceback."""
    import island_mapping.cli.world as world_cli

    def broken(_args: object) -> int:
        raise ZeroDivisionError("a bug")

    monkeypatch.setenv("ISLANDS_LOG_DIR", str(tmp_path / "logs"))
    monkeypatch.setattr(world_cli, "run", broken)
    assert main(["world", "corridor"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "internal error" in err and "ZeroDivisionError" in err
    logs = list((tmp_path / "logs").glob("islands-world-*.log"))
    assert len(logs) == 1 and str(logs[0]) in err
    assert "Traceback" in logs[0].read_text() and "a bug" in logs[0].read_text()
