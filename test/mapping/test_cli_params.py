"""Parameter overrides on the command line, and the ones a recorded run was made with."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from island_mapping.cli import CliError
from island_mapping.cli.params import parse_assignments, parse_node_assignments
from island_mapping.cli.replay import recorded_builder_params


def test_assignments_parse_values_as_yaml() -> None:
    got = parse_assignments(["a.b=0.5", "c=true", "d=text", " e =3"], "--x")
    assert got == {"a.b": 0.5, "c": True, "d": "text", "e": 3}
    nodes = parse_node_assignments(["n1:a.b=1", "n1:c=2", "n2:d=x"], "--param")
    assert nodes == {"n1": {"a.b": 1, "c": 2}, "n2": {"d": "x"}}


@pytest.mark.parametrize(("item", "message"), [
    ("=1", "expected NAME=VALUE"),
    ("a.b: [1", "expected NAME=VALUE"),
    ("a=[1, 2]", "must be a bool, number or string"),
    ("a={x: 1}", "must be a bool, number or string"),
    ("a=[", "value is not YAML"),
])
def test_bad_assignments_name_the_flag_and_item(item: str, message: str) -> None:
    with pytest.raises(CliError, match=message) as info:
        parse_assignments([item], "--builder-param")
    assert "--builder-param" in str(info.value) and repr(item) in str(info.value)


def test_node_assignments_need_a_node() -> None:
    with pytest.raises(CliError, match="expected NODE:NAME=VALUE"):
        parse_node_assignments(["odometry.seed=1"], "--param")
    with pytest.raises(CliError, match="expected NODE:NAME=VALUE"):
        parse_node_assignments([":seed=1"], "--param")


def _run_dir(tmp_path: Path, summary: object | None) -> Path:
    bag = tmp_path / "run" / "run_bag"
    bag.mkdir(parents=True)
    if summary is not None:
        text = summary if isinstance(summary, str) else json.dumps(summary)
        (tmp_path / "run" / "summary.json").write_text(text)
    return bag


def test_a_replay_takes_the_builder_parameters_the_run_was_made_with(tmp_path: Path) -> None:
    bag = _run_dir(tmp_path, {"parameters": {
        "island_builder_node": {"builder.register_legs": False},
        "odometry_node": {"seed": 3},
    }})
    assert recorded_builder_params(bag) == {"builder.register_legs": False}
    assert recorded_builder_params(bag / "run_bag_0.mcap") == {"builder.register_legs": False}


def test_a_run_without_overrides_or_summary_gives_none(tmp_path: Path) -> None:
    assert recorded_builder_params(_run_dir(tmp_path / "a", None)) == {}
    assert recorded_builder_params(_run_dir(tmp_path / "b", {"seed": 1})) == {}


@pytest.mark.parametrize(("summary", "message"), [
    ("{not json", "not valid JSON"),
    ({"parameters": {"island_builder_node": [1]}}, "is not a mapping"),
])
def test_a_damaged_summary_is_named(tmp_path: Path, summary: object, message: str) -> None:
    with pytest.raises(CliError, match=message) as info:
        recorded_builder_params(_run_dir(tmp_path, summary))
    assert "summary.json" in str(info.value)
