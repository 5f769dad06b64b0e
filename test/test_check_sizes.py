"""scripts/check_sizes.py: issue 15's size limits, and the one-line reasons that excuse a breach."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "check_sizes.py"


def _module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("check_sizes", SCRIPT)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["check_sizes"] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _function(name: str, body_lines: int, above: str = "") -> str:
    body = "".join(f"    x{i} = {i}\n" for i in range(body_lines))
    return f"{above}def {name}() -> None:\n{body}\n\n"


def test_long_functions_classes_and_files_are_found_unless_a_reason_is_given(tmp_path: Path
                                                                           ) -> None:
    cs = _module()
    src = tmp_path / "pkg"
    src.mkdir()
    (src / "ok.py").write_text(_function("short", 79))  # 80 lines with the def: at the limit
    (src / "long.py").write_text(
        _function("too_long", 80)
        + _function("excused", 80, above="# size-ok: a table of cases, one per line\n")
        + _function("no_reason", 80, above="# size-ok:\n")
    )
    methods = "".join("    " + line + "\n" for f in range(6)
                      for line in _function(f"m{f}", 70).splitlines())
    (src / "cls.py").write_text("class Big:\n" + methods)
    (src / "big.py").write_text("x = 0\n" * 601)
    (src / "big_ok.py").write_text("# size-ok(file): generated tables\n" + "x = 0\n" * 601)
    found = sorted((b.path.name, b.what) for p in sorted(src.glob("*.py"))
                   for b in cs.check_file(p))
    assert found == [("big.py", "file"), ("cls.py", "class Big"),
                     ("long.py", "function no_reason"), ("long.py", "function too_long")]
    run = subprocess.run([sys.executable, str(SCRIPT), str(src)], capture_output=True, text=True)
    assert run.returncode == 1 and "function too_long is 81 lines (limit 80)" in run.stdout


def test_the_projects_sources_keep_the_limits() -> None:
    run = subprocess.run([sys.executable, str(SCRIPT)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout
