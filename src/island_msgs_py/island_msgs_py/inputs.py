"""The validation layer of input files (ROS-free: the standard library, numpy, PyYAML).

Every file the project reads goes through one of these before its format's own checks:

- `read_bytes` / `read_text`: a regular file (never a directory, a FIFO or /dev/zero), at most
  `max_bytes`, UTF-8 text (a bad byte is named by offset and line);
- `load_yaml`: `yaml.safe_load` within limits: nesting depth and aliases (counted expanded, so
  a "billion laughs" file is refused) are checked on the parser's events before anything is
  built, integers longer than MAX_INT_DIGITS are refused; a syntax error is one line;
- `load_json`: `json_checks.loads` (size, depth, integer length) with the caller's error type;
- `read_structured`: the top-level mapping of a YAML or JSON file;
- `parse_float` / `parse_int`: one number of a text format, finite and within a bound.

Each refusal is raised as the caller's own error type (`error=WorldError`, ...; the default is
`InputError`) with a one-line message that starts with the file (or `file:line`) and names the
field and the limit.
"""

from __future__ import annotations

import math
import os
import re
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any, NoReturn

import yaml

from island_msgs_py import json_checks
from island_msgs_py.errors import InputError
from island_msgs_py.limits import (
    MAX_INT_DIGITS,
    MAX_TEXT_FILE_BYTES,
    MAX_YAML_ALIAS_NODES,
    MAX_YAML_DEPTH,
)

ErrorType = Callable[[str], Exception]
"""How a caller's error is made from a one-line message (e.g. the class `WorldError`)."""

MAX_MESSAGE_CHARS = 400
"""Longest error message (a value quoted in it is cut short): one line, never megabytes."""

_SPACE_RUN = re.compile(r"\s*\n\s*")

try:  # libyaml's parser when PyYAML has it (~10x faster); the pure-Python one otherwise
    _SAFE_LOADER: type[Any] = yaml.CSafeLoader
except AttributeError:  # pragma: no cover - wheels ship libyaml
    _SAFE_LOADER = yaml.SafeLoader


def one_line(text: str, max_chars: int = MAX_MESSAGE_CHARS) -> str:
    """`text` on one line (line breaks and the indentation after them become one space), cut
    to `max_chars`."""
    flat = _SPACE_RUN.sub(" ", str(text)).strip()
    return flat if len(flat) <= max_chars else flat[: max_chars - 3] + "..."


def _fail(error: ErrorType, message: str) -> NoReturn:
    raise error(one_line(message))


# ----------------------------------------------------------------------------- files


def read_bytes(path: str | os.PathLike[str], max_bytes: int = MAX_TEXT_FILE_BYTES,
               error: ErrorType = InputError, what: str = "file") -> bytes:
    """The bytes of a regular file of at most `max_bytes`; `error` naming the file otherwise."""
    p = Path(path)
    try:
        st = p.stat()
        if stat.S_ISDIR(st.st_mode):
            _fail(error, f"{p}: cannot read: is a directory, expected a {what}")
        if not stat.S_ISREG(st.st_mode):
            _fail(error, f"{p}: cannot read: not a regular file (a device, FIFO or socket), "
                         f"expected a {what}")
        if st.st_size > max_bytes:
            _fail(error, f"{p}: {st.st_size} bytes, the limit for a {what} is {max_bytes}")
        with p.open("rb") as fh:
            data = fh.read(max_bytes + 1)
    except OSError as exc:
        _fail(error, f"{p}: cannot read: {exc.strerror or exc}")
    if len(data) > max_bytes:  # grew while we read it
        _fail(error, f"{p}: more than {max_bytes} bytes, the limit for a {what}")
    return data


def decode_utf8(data: bytes, source: str, error: ErrorType = InputError) -> str:
    """`data` as UTF-8 text; `error` naming `source`, the line and the byte offset otherwise."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        _fail(error, f"{source}: not UTF-8 text: byte 0x{data[exc.start]:02x} at offset "
                     f"{exc.start} (line {line})")


def read_text(path: str | os.PathLike[str], max_bytes: int = MAX_TEXT_FILE_BYTES,
              error: ErrorType = InputError, what: str = "file") -> str:
    """The UTF-8 text of a regular file of at most `max_bytes` (see read_bytes)."""
    return decode_utf8(read_bytes(path, max_bytes, error, what), str(path), error)


# ----------------------------------------------------------------------------- YAML


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """A YAML error as `line L column C: problem (context)` on one line."""
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        where = f"line {mark.line + 1} column {mark.column + 1}: " if mark is not None else ""
        context = f" ({exc.context})" if exc.context else ""
        return f"{where}{exc.problem or 'malformed'}{context}"
    return one_line(str(exc))


def _line(event: yaml.Event) -> int:
    """The 1-based line where a parser event starts (0 when the parser gave no position)."""
    mark = event.start_mark
    return mark.line + 1 if mark is not None else 0


def check_yaml_events(text: str, source: str, error: ErrorType = InputError,
                      max_depth: int = MAX_YAML_DEPTH,
                      max_alias_nodes: int = MAX_YAML_ALIAS_NODES) -> None:
    """Refuse YAML nested deeper than `max_depth`, or whose aliases stand for more than
    `max_alias_nodes` nodes, from the parser's events (linear; nothing is built)."""
    open_nodes: list[tuple[str | None, int]] = []  # (anchor, node count when it opened)
    sizes: dict[str, int] = {}  # anchor -> nodes it stands for, expanded
    total = alias_nodes = 0
    try:
        for ev in yaml.parse(text, Loader=_SAFE_LOADER):
            if isinstance(ev, yaml.CollectionStartEvent):
                open_nodes.append((ev.anchor, total))
                total += 1
                if len(open_nodes) > max_depth:
                    _fail(error, f"{source}: line {_line(ev)}: YAML nested more than "
                                 f"{max_depth} deep (the limit)")
            elif isinstance(ev, yaml.CollectionEndEvent):
                anchor, start = open_nodes.pop()
                if anchor is not None:
                    sizes[anchor] = total - start
            elif isinstance(ev, yaml.ScalarEvent):
                total += 1
                if ev.anchor is not None:
                    sizes[ev.anchor] = 1
            elif isinstance(ev, yaml.AliasEvent):
                if ev.anchor not in sizes:
                    if any(a == ev.anchor for a, _ in open_nodes):
                        _fail(error, f"{source}: line {_line(ev)}: alias *{ev.anchor}"
                                     " refers to a node that contains it (a recursive structure)")
                    _fail(error, f"{source}: line {_line(ev)}: undefined alias "
                                 f"*{ev.anchor}")
                total += sizes[ev.anchor]
                alias_nodes += sizes[ev.anchor]
                if alias_nodes > max_alias_nodes:
                    _fail(error, f"{source}: line {_line(ev)}: YAML aliases stand for "
                                 f"more than {max_alias_nodes} nodes (the limit; an alias bomb?)")
    except yaml.YAMLError as exc:
        _fail(error, f"{source}: not valid YAML: {_yaml_problem(exc)}")


class _BoundedLoader(_SAFE_LOADER):
    """yaml.safe_load's loader, refusing integers of more than MAX_INT_DIGITS digits."""

    def construct_yaml_int(self, node: yaml.ScalarNode) -> int:
        text = str(node.value)
        digits = sum(ch.isalnum() for ch in text)
        if digits > MAX_INT_DIGITS + 2:  # a `0x` prefix is two characters more
            raise yaml.constructor.ConstructorError(
                None, None, f"an integer of {digits} digits (the limit is {MAX_INT_DIGITS})",
                node.start_mark)
        return int(super().construct_yaml_int(node))


_BoundedLoader.add_constructor("tag:yaml.org,2002:int", _BoundedLoader.construct_yaml_int)


def load_yaml(text: str, source: str, error: ErrorType = InputError,
              max_depth: int = MAX_YAML_DEPTH,
              max_alias_nodes: int = MAX_YAML_ALIAS_NODES) -> Any:
    """`yaml.safe_load(text)` within the limits (see check_yaml_events); every refusal and
    every syntax error is `error` with a one-line message starting with `source`."""
    check_yaml_events(text, source, error, max_depth, max_alias_nodes)
    try:
        return yaml.load(text, Loader=_BoundedLoader)
    except yaml.YAMLError as exc:
        _fail(error, f"{source}: not valid YAML: {_yaml_problem(exc)}")
    except (ValueError, OverflowError) as exc:  # a scalar the resolver took for a number
        _fail(error, f"{source}: not valid YAML: {exc}")


# ----------------------------------------------------------------------------- JSON, structured


def load_json(text: str | bytes, source: str, error: ErrorType = InputError,
              max_bytes: int = MAX_TEXT_FILE_BYTES) -> Any:
    """`json.loads` within json_checks' limits (size, depth, integer length), as `error`."""
    try:
        return json_checks.loads(text, source, max_bytes)
    except json_checks.GraphFormatError as exc:
        _fail(error, str(exc))


def read_json(path: str | os.PathLike[str], error: ErrorType = InputError,
              max_bytes: int = MAX_TEXT_FILE_BYTES, what: str = "JSON file") -> Any:
    """The value of a JSON file, within the limits (see read_text and load_json)."""
    return load_json(read_text(path, max_bytes, error, what), str(path), error, max_bytes)


def read_structured(path: str | os.PathLike[str], error: ErrorType = InputError,
                    max_bytes: int = MAX_TEXT_FILE_BYTES, what: str = "file") -> dict[str, Any]:
    """The top-level mapping of a YAML file, or of a JSON file (`.json`), within the limits."""
    p = Path(path)
    text = read_text(p, max_bytes, error, what)
    if p.suffix.lower() == ".json":
        data = load_json(text, str(p), error, max_bytes)
    else:
        data = load_yaml(text, str(p), error)
    if not isinstance(data, dict):
        _fail(error, f"{p}: expected a mapping at the top level, got {type(data).__name__}")
    return data


# ----------------------------------------------------------------------------- numbers


def parse_float(text: str, where: str, error: ErrorType = InputError,
                bound: float | None = None, minimum: float | None = None) -> float:
    """A finite number from `text` (with |value| <= bound, >= minimum when given); `error`
    naming `where` (e.g. `file:line: field`) otherwise."""
    try:
        value = float(text)
    except (TypeError, ValueError):
        _fail(error, f"{where}: not a number: {json_checks.describe(text)}")
    if not math.isfinite(value):
        _fail(error, f"{where}: not a finite number: {json_checks.describe(text)}")
    if bound is not None and abs(value) > bound:
        _fail(error, f"{where}: |value| must be <= {bound:g} (the limit), got {value:g}")
    if minimum is not None and value < minimum:
        _fail(error, f"{where}: must be >= {minimum:g}, got {value:g}")
    return value


def parse_int(text: str, where: str, error: ErrorType = InputError,
              minimum: int | None = None, maximum: int | None = None) -> int:
    """An integer from decimal `text` of at most MAX_INT_DIGITS digits, within
    [minimum, maximum] when given; `error` naming `where` otherwise."""
    s = str(text).strip()
    digits = len(s.lstrip("+-"))
    if digits > MAX_INT_DIGITS:
        _fail(error, f"{where}: an integer of {digits} digits (the limit is {MAX_INT_DIGITS})")
    try:
        value = int(s, 10)
    except ValueError:
        _fail(error, f"{where}: not an integer: {json_checks.describe(s)}")
    if minimum is not None and value < minimum:
        _fail(error, f"{where}: must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        _fail(error, f"{where}: must be <= {maximum} (the limit), got {value}")
    return value
