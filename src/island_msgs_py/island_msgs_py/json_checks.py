"""The validation layer of JSON input: bounded parsing and typed field readers (numpy only).

`loads`/`read_json_file` parse JSON within the limits of `island_msgs_py.limits` (text size,
nesting depth, integer literal length) and the readers (`obj`, `int_`, `float_`, `str_`,
`list_`) check one field each. Every refusal is a `GraphFormatError` whose message starts with
the path of the field or the file: never a RecursionError, an OverflowError or an int-conversion
ValueError.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from island_msgs_py.errors import InputError
from island_msgs_py.limits import (
    MAX_GRAPH_FILE_BYTES,
    MAX_ISLAND_ID,
    MAX_JSON_DEPTH,
    MAX_JSON_INT_DIGITS,
    MAX_LENGTH_M,
)

_SCAN_CHUNK_BYTES = 1 << 22  # the nesting-depth scan looks at this many bytes at a time


class GraphFormatError(InputError):
    """A JSON document is not a valid island/edge/graph; the message starts with the field path."""

    def __init__(self, path: str, problem: str) -> None:
        super().__init__(f"{path}: {problem}" if path else problem)
        self.path = path
        self.problem = problem


# ----------------------------------------------------------------------------- validation helpers


def describe(value: Any) -> str:
    if isinstance(value, float) and math.isnan(value):
        return "NaN"
    if isinstance(value, float) and math.isinf(value):
        return "infinite value"
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        return f"an integer of {value.bit_length()} bits"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def obj(value: Any, path: str, keys: set[str], required: set[str]) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise GraphFormatError(path, f"expected an object, got {type(value).__name__}")
    unknown = sorted(set(value) - keys)
    if unknown:
        raise GraphFormatError(f"{path}.{unknown[0]}", "unknown key")
    missing = sorted(required - set(value))
    if missing:
        raise GraphFormatError(f"{path}.{missing[0]}", "missing")
    return value


def int_(value: Any, path: str, minimum: int | None = 0, maximum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise GraphFormatError(path, f"expected an integer, got {describe(value)}")
    if minimum is not None and value < minimum:
        raise GraphFormatError(path, f"must be >= {minimum}, got {describe(value)}")
    if maximum is not None and value > maximum:
        raise GraphFormatError(path, f"must be <= {maximum} (the limit), got {describe(value)}")
    return int(value)


def island_id(value: Any, path: str) -> int:
    """An island id: an integer in [0, MAX_ISLAND_ID]."""
    return int_(value, path, 0, MAX_ISLAND_ID)


def float_(
    value: Any, path: str, minimum: float | None = None, bound: float | None = None
) -> float:
    """A finite number, optionally >= minimum and with |value| <= bound."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise GraphFormatError(path, f"expected a number, got {describe(value)}")
    try:
        f = float(value)
    except OverflowError:
        raise GraphFormatError(path, f"{describe(value)} is out of range") from None
    if not math.isfinite(f):
        raise GraphFormatError(path, describe(f))
    if minimum is not None and f < minimum:
        raise GraphFormatError(path, f"must be >= {minimum}, got {f}")
    if bound is not None and abs(f) > bound:
        raise GraphFormatError(path, f"|value| must be <= {bound:g} (the limit), got {f:g}")
    return f


def length(value: Any, path: str) -> float:
    """A length [m]: finite, >= 0, <= MAX_LENGTH_M."""
    return float_(value, path, minimum=0.0, bound=MAX_LENGTH_M)


def str_(value: Any, path: str) -> str:
    if not isinstance(value, str):
        raise GraphFormatError(path, f"expected a string, got {describe(value)}")
    return value


def list_(value: Any, path: str, max_len: int | None = None) -> Sequence[Any]:
    if not isinstance(value, list | tuple):
        raise GraphFormatError(path, f"expected a list, got {type(value).__name__}")
    if max_len is not None and len(value) > max_len:
        raise GraphFormatError(path, f"{len(value)} entries (the limit is {max_len})")
    return value


# ----------------------------------------------------------------------------- bounded parsing


_STRING_RE = re.compile(rb'"[^"\\]*(?:\\.[^"\\]*)*"')


def json_depth(text: str | bytes) -> int:
    """The deepest nesting of arrays and objects in JSON text (brackets inside strings are not
    counted). Linear and vectorized: no recursion, whatever the input."""
    data = text.encode("utf-8", "surrogatepass") if isinstance(text, str) else bytes(text)
    stripped = _STRING_RE.sub(b'""', data)
    buf = np.frombuffer(stripped, dtype=np.uint8)
    deepest, depth = 0, 0
    for start in range(0, len(buf), _SCAN_CHUNK_BYTES):
        chunk = buf[start: start + _SCAN_CHUNK_BYTES]
        brackets = chunk[(chunk == ord("[")) | (chunk == ord("{"))
                         | (chunk == ord("]")) | (chunk == ord("}"))]
        if not brackets.size:
            continue
        steps = np.where((brackets == ord("[")) | (brackets == ord("{")), 1, -1)
        running = np.cumsum(steps, dtype=np.int64) + depth
        deepest = max(deepest, int(running.max()))
        depth = int(running[-1])
    return deepest


def _bounded_int(path: str) -> Any:
    def parse(digits: str) -> int:
        n = len(digits.lstrip("-"))
        if n > MAX_JSON_INT_DIGITS:
            raise GraphFormatError(
                path, f"an integer of {n} digits (the limit is {MAX_JSON_INT_DIGITS})")
        return int(digits)
    return parse


def loads(text: str | bytes, path: str = "", max_bytes: int = MAX_GRAPH_FILE_BYTES) -> Any:
    """json.loads within the limits: text size, nesting depth, integer length.

    Every refusal is a GraphFormatError starting with `path` (a field path or a file name):
    never a RecursionError or an int-conversion ValueError.
    """
    if len(text) > max_bytes:
        raise GraphFormatError(path, f"{len(text)} bytes of JSON (the limit is {max_bytes})")
    depth = json_depth(text)
    if depth > MAX_JSON_DEPTH:
        raise GraphFormatError(
            path, f"JSON nested {depth} deep (the limit is {MAX_JSON_DEPTH})")
    try:
        return json.loads(text, parse_int=_bounded_int(path))
    except json.JSONDecodeError as exc:
        raise GraphFormatError(path, f"not valid JSON: {exc}") from exc
    except UnicodeDecodeError as exc:
        raise GraphFormatError(path, f"not UTF-8 text: {exc}") from exc


def read_json_file(path: str | os.PathLike[str], max_bytes: int = MAX_GRAPH_FILE_BYTES) -> Any:
    """A JSON file's value within the limits; GraphFormatError naming the file otherwise."""
    p = Path(path)
    try:
        size = p.stat().st_size
        if size > max_bytes:
            raise GraphFormatError(str(p), f"{size} bytes (the limit is {max_bytes})")
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise GraphFormatError(str(p), f"cannot read: {exc.strerror or exc}") from exc
    except UnicodeDecodeError as exc:
        raise GraphFormatError(str(p), f"not UTF-8 text: {exc}") from exc
    return loads(text, str(p), max_bytes)
