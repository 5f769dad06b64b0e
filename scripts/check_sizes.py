"""Size limits of issue 15 for src/: files <= 600 lines, classes <= 400, functions <= 80.

Usage: python scripts/check_sizes.py [ROOT ...]   (default: src/ of this checkout)
Prints one line per breach (path:line: what, how long, the limit) and exits 1 if any.

A breach may stay if the file says why, in one line:
- a function or class: a comment `# size-ok: <reason>` on the line of its `def`/`class`, or on
  the line just above it (above its decorators);
- a file: a comment `# size-ok(file): <reason>` anywhere in it.
A `size-ok` without a reason does not count.
"""

from __future__ import annotations

import ast
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

MAX_FILE_LINES = 600
MAX_CLASS_LINES = 400
MAX_FUNCTION_LINES = 80
_REASON = re.compile(r"#\s*size-ok:\s*\S")
_FILE_REASON = re.compile(r"#\s*size-ok\(file\):\s*\S")


@dataclass(frozen=True)
class Breach:
    path: Path
    line: int
    what: str
    lines: int
    limit: int

    def relative_to(self, base: Path) -> str:
        """The breach with its path relative to `base` when it lies under it."""
        p = self.path.resolve()
        shown = p.relative_to(base.resolve()) if p.is_relative_to(base.resolve()) else p
        return f"{shown}:{self.line}: {self.what} is {self.lines} lines (limit {self.limit})"

    def __str__(self) -> str:
        return f"{self.path}:{self.line}: {self.what} is {self.lines} lines (limit {self.limit})"


def _justified(lines: list[str], node: ast.AST) -> bool:
    """A `# size-ok: reason` on the def/class line or the line above it (or its decorators)."""
    first = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
    candidates = {first - 1, first, node.lineno}  # 1-based line numbers
    return any(1 <= n <= len(lines) and _REASON.search(lines[n - 1]) for n in candidates)


def _defs(tree: ast.AST) -> Iterator[ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef]:
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
            yield node


def check_file(path: Path) -> list[Breach]:
    """Every unjustified breach of the limits in one Python file."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    out: list[Breach] = []
    if len(lines) > MAX_FILE_LINES and not _FILE_REASON.search(text):
        out.append(Breach(path, 1, "file", len(lines), MAX_FILE_LINES))
    for node in _defs(ast.parse(text, filename=str(path))):
        n = (node.end_lineno or node.lineno) - node.lineno + 1
        is_class = isinstance(node, ast.ClassDef)
        limit = MAX_CLASS_LINES if is_class else MAX_FUNCTION_LINES
        if n > limit and not _justified(lines, node):
            kind = "class" if is_class else "function"
            out.append(Breach(path, node.lineno, f"{kind} {node.name}", n, limit))
    return out


def main(argv: list[str]) -> int:
    roots = [Path(a) for a in argv] or [Path(__file__).resolve().parent.parent / "src"]
    breaches = [b for root in roots for p in sorted(root.rglob("*.py")) for b in check_file(p)]
    for b in breaches:
        print(b.relative_to(Path.cwd()))
    if breaches:
        print(f"{len(breaches)} size limit(s) broken; split the code, or give a one-line reason "
              "(see scripts/check_sizes.py)")
    return 1 if breaches else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
