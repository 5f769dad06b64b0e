"""Workspace invariants: layering, ament_python boilerplate, README <-> CI agreement."""

from __future__ import annotations

import ast
import configparser
import json
import re
import subprocess
import sys
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import networkx as nx
import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("island_msgs_py", "island_sim", "island_mapping")


# island_msgs_py's message-facing modules (they use rclpy); every other module is ROS-free.
MSGS_MESSAGE_FACING = ("conversions", "qos", "ros_params", "scan_inputs", "serialized")


def _modules_under(pkg: str, sub: str) -> list[str]:
    """Dotted names of every module and package below src/<pkg>/<pkg>/<sub>."""
    base = ROOT / "src" / pkg
    out = []
    for p in sorted((base / pkg / sub).rglob("*.py")):
        parts = p.relative_to(base).with_suffix("").parts
        out.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
    return out


def _msgs_core_modules() -> list[str]:
    return [m for m in _modules_under("island_msgs_py", "")
            if m != "island_msgs_py" and m.split(".")[1] not in MSGS_MESSAGE_FACING]


def _core_modules() -> list[str]:
    mods = _msgs_core_modules()
    for pkg in ("island_sim", "island_mapping"):
        mods += _modules_under(pkg, "core")
    return mods


def _loaded_after_import(mods: list[str], roots: tuple[str, ...]) -> list[str]:
    """Modules under `roots` that importing `mods` in a fresh interpreter loads."""
    code = (
        "import importlib, sys\n"
        f"for m in {mods!r}: importlib.import_module(m)\n"
        f"print(','.join(sorted(k for k in sys.modules if k.split('.')[0] in {roots!r})))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return [m for m in out.stdout.strip().split(",") if m]


def test_core_modules_do_not_load_rclpy() -> None:
    mods = _core_modules()
    assert len(mods) >= 3
    bad = _loaded_after_import(
        mods, ("rclpy", "rosidl_parser", "sensor_msgs", "nav_msgs", "geometry_msgs", "matplotlib")
    )
    assert bad == [], f"core modules pulled in: {bad}"


def test_import_contract_covers_every_ros_free_module_of_island_msgs_py() -> None:
    """A new module of island_msgs_py is either message-facing or in the no-ROS contract."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    sources = [set(c["source_modules"]) for c in config["contracts"]
               if "rclpy" in c.get("forbidden_modules", ())]
    core = set(_msgs_core_modules())
    assert "island_msgs_py.types" in core
    assert any(core <= s for s in sources), (
        f"add {sorted(core - max(sources, key=lambda s: len(s & core)))} to the island_msgs_py "
        "contract of pyproject.toml [tool.importlinter], or to MSGS_MESSAGE_FACING here")


def test_mapping_core_loads_nothing_of_island_sim() -> None:
    """The mapping core runs on a robot without the simulator (issue 15)."""
    mods = _modules_under("island_mapping", "core")
    assert "island_mapping.core.localize" in mods
    assert _loaded_after_import(mods, ("island_sim",)) == []


def _import_graph() -> dict[str, set[str]]:
    """Module -> the src modules it imports, from every import statement (also those inside
    functions, which would otherwise hide a cycle); a package's own __init__ is no edge."""
    mods = {m: ROOT / "src" / m.split(".")[0] for pkg in PACKAGES for m in _modules_under(pkg, "")}
    graph: dict[str, set[str]] = {}
    for name in mods:
        rel = Path(*name.split("."))
        path = mods[name] / rel.with_suffix(".py")
        if not path.is_file():
            path = mods[name] / rel / "__init__.py"
        edges = graph.setdefault(name, set())
        for node in ast.walk(ast.parse(path.read_text())):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets = [
                    f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in mods else node.module
                    for a in node.names
                ]
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != name and not name.startswith(t + "."):
                    edges.add(t)
    return graph


def test_no_import_cycles_in_src() -> None:
    graph = _import_graph()
    assert "island_sim.core.world" in graph["island_sim.core.importers"]  # the graph is real
    cycles = [
        sorted(c)
        for c in nx.strongly_connected_components(nx.DiGraph(
            [(a, b) for a, targets in graph.items() for b in targets]))
        if len(c) > 1
    ]
    assert cycles == [], f"import cycles: {cycles}"


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
