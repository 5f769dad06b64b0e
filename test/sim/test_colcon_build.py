"""`colcon build` puts every node executable where `ros2 run <pkg> <exe>` looks for it, and
`islands` on PATH once `install/setup.sh` is sourced."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = ("island_msgs_py", "island_sim", "island_mapping")


def _colcon() -> str | None:
    beside = Path(sys.executable).parent / "colcon"
    return str(beside) if beside.exists() else shutil.which("colcon")


def _console_scripts(pkg: str) -> list[str]:
    setup_py = (ROOT / "src" / pkg / "setup.py").read_text()
    block = re.search(r"'console_scripts'\s*:\s*\[(.*?)\]", setup_py, re.S)
    if block is None:
        return []
    return re.findall(r"'\s*([\w-]+)\s*=\s*[\w.]+:\w+\s*'", block.group(1))


def test_colcon_build_installs_every_console_script(tmp_path: Path) -> None:
    colcon = _colcon()
    if colcon is None:
        pytest.skip("colcon is not installed")
    out = subprocess.run(
        [colcon, "--log-base", str(tmp_path / "log"), "build", "--base-paths", "src",
         "--build-base", str(tmp_path / "build"), "--install-base", str(tmp_path / "install")],
        cwd=ROOT, capture_output=True, text=True, timeout=300,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    expected = {pkg: _console_scripts(pkg) for pkg in PACKAGES}
    assert {"sonar_node", "odometry_node", "hall_follower_node"} <= set(expected["island_sim"])
    for pkg, scripts in expected.items():
        assert (tmp_path / "install" / pkg / "share" / pkg / "package.xml").is_file()
        for script in scripts:
            exe = tmp_path / "install" / pkg / "lib" / pkg / script
            assert exe.is_file(), f"{pkg}: {script} missing from {exe.parent}"
            assert os.access(exe, os.X_OK), f"{exe} is not executable"
    # the installed executable runs: a bad parameter gives exit code 2 and names the problem
    exe = tmp_path / "install" / "island_sim" / "lib" / "island_sim" / "odometry_node"
    run = subprocess.run(
        [str(exe), "--ros-args", "-p", "world:=no_such_world"],
        capture_output=True, text=True, timeout=60,
    )
    assert run.returncode == 2, run.stderr[-2000:]
    assert "no_such_world" in run.stderr
    # after `. install/setup.sh` the README's `islands` commands work: it is on PATH
    install = tmp_path / "install"
    shell = subprocess.run(
        ["sh", "-c", f". '{install}/setup.sh' && command -v islands && islands world corridor"],
        capture_output=True, text=True, timeout=60,
        env={"HOME": os.environ.get("HOME", "/"), "PATH": "/usr/bin:/bin"},
    )
    assert shell.returncode == 0, shell.stdout[-2000:] + shell.stderr[-2000:]
    where, world = shell.stdout.splitlines()[:2]
    assert Path(where) == install / "island_mapping" / "bin" / "islands"
    assert '"name": "corridor"' in world
