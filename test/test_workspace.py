"""Workspace invariants: layering, ament_python boilerplate, README <-> CI agreement."""

from __future__ import annotations

import configparser
import json
import re
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("island_msgs_py", "island_sim", "island_mapping")


def _core_modules() -> list[str]:
    mods = ["island_msgs_py.types", "island_msgs_py.json_io"]
    for pkg in ("island_sim", "island_mapping"):
        core = ROOT / "src" / pkg / pkg / "core"
        mods += [f"{pkg}.core.{p.stem}" for p in sorted(core.glob("*.py")) if p.stem != "__init__"]
    return [
        m for m in mods
        if (ROOT / "src" / m.split(".")[0] / (m.replace(".", "/") + ".py")).exists()
    ]


def test_core_modules_do_not_load_rclpy() -> None:
    mods = _core_modules()
    assert len(mods) >= 3
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        "bad = sorted(k for k in sys.modules if k.split('.')[0] in "
        "('rclpy', 'rosidl_parser', 'sensor_msgs', 'nav_msgs', 'geometry_msgs', 'matplotlib'))\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"core modules pulled in: {out.stdout.strip()}"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_ament_python_boilerplate(pkg: str) -> None:
    d = ROOT / "src" / pkg
    root = ET.parse(d / "package.xml").getroot()
    assert root.get("format") == "3"
    assert root.findtext("name") == pkg
    assert root.find("export/build_type").text == "ament_python"  # type: ignore[union-attr]
    assert (d / "resource" / pkg).is_file()
    cfg = configparser.ConfigParser()
    cfg.read(d / "setup.cfg")
    assert cfg["develop"]["script_dir"] == f"$base/lib/{pkg}"
    assert cfg["install"]["install_scripts"] == f"$base/lib/{pkg}"


@pytest.mark.parametrize("pkg", ("island_sim", "island_mapping"))
def test_every_node_has_an_entry_point_and_a_config(pkg: str) -> None:
    setup_py = (ROOT / "src" / pkg / "setup.py").read_text()
    entries = dict(re.findall(r"'(\w+) = ([\w.]+):main'", setup_py))
    nodes = sorted(p.stem for p in (ROOT / "src" / pkg / pkg / "nodes").glob("*_node.py"))
    assert nodes, "no nodes"
    for node in nodes:
        assert entries.get(node) == f"{pkg}.nodes.{node}", f"{node} has no entry point"
        assert (ROOT / "src" / pkg / "config" / f"{node}.yaml").is_file(), f"{node} has no config"


def test_ci_runs_exactly_the_readme_test_command() -> None:
    readme = (ROOT / "README.md").read_text()
    block = re.search(r"<!-- test-command -->\s*```(?:bash|sh)?\n(.+?)\n```", readme, re.S)
    assert block is not None, "README must mark its test command with <!-- test-command -->"
    command = block.group(1).strip()
    ci_lines = [
        ln.strip()
        for ln in (ROOT / ".ci" / "run").read_text().splitlines()
        if ln.strip() and not ln.strip().startswith(("#", "set ", "cd "))
    ]
    assert ci_lines == [command]


def test_colcon_meta_names_every_package() -> None:
    meta = json.loads((ROOT / "colcon.meta").read_text())
    assert set(meta["names"]) == set(PACKAGES)


@pytest.mark.parametrize("pkg", ("island_sim", "island_mapping"))
def test_console_scripts_are_on_the_venv_bin(pkg: str) -> None:
    """scripts/setup.sh promises every node and `islands` on .venv/bin (not only in lib/<pkg>)."""
    setup_py = (ROOT / "src" / pkg / "setup.py").read_text()
    names = re.findall(r"'(\w+) = [\w.]+:main'", setup_py)
    assert names
    bindir = Path(sys.executable).parent
    missing = [n for n in names if not (bindir / n).exists()]
    assert not missing, f"not in {bindir}: {missing} (run scripts/setup.sh)"
