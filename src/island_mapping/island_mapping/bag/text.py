"""Messages as YAML-like text, like `ros2 topic echo` (one function for bag echo and topic echo).

Nested messages are indented blocks; arrays of numbers are one flow list (`[1.0, 2.0]`), cut
after `max_array` items with a comment giving the full length; arrays of messages are block lists
cut the same way. float32 values print at float32 precision (0.1, not 0.10000000149). Works on
any rclpy message object (duck-typed on `get_fields_and_field_types`); imports no rclpy.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import numpy as np

DEFAULT_MAX_ARRAY = 36
"""Array items shown before '...': a 6x6 covariance fits, a 180-beam scan is cut."""
MESSAGE_SEPARATOR = "---"

_PLAIN_RE = re.compile(r"^[A-Za-z_/][A-Za-z0-9_./\-]*$")
_YAML_WORDS = frozenset({"true", "false", "yes", "no", "on", "off", "null", "none", "~"})


def _is_message(value: Any) -> bool:
    return hasattr(value, "get_fields_and_field_types")


def _scalar(value: Any, ftype: str) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, (bytes, bytearray)):
        return str(list(value))
    if isinstance(value, (float, np.floating)):
        f = float(value)
        if math.isnan(f):
            return ".nan"
        if math.isinf(f):
            return ".inf" if f > 0 else "-.inf"
        if ftype in ("float", "float32") or isinstance(value, np.float32):
            return str(np.float32(f))
        return repr(f)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return _string(str(value))


def _string(s: str) -> str:
    if _PLAIN_RE.match(s) and s.lower() not in _YAML_WORDS:
        return s
    if "\n" in s or any(ord(c) < 32 for c in s):
        return json.dumps(s)
    return "'" + s.replace("'", "''") + "'"


def _element_type(ftype: str) -> str:
    m = re.match(r"^sequence<([^,>]+)(?:,\s*\d+)?>$", ftype)
    if m:
        return m.group(1)
    m = re.match(r"^([^\[]+)\[\d*\]$", ftype)
    if m:
        return m.group(1)
    return ftype


def _lines(msg: Any, indent: int, max_array: int) -> list[str]:
    pad = "  " * indent
    out: list[str] = []
    for name, ftype in msg.get_fields_and_field_types().items():
        value = getattr(msg, name)
        if _is_message(value):
            out.append(f"{pad}{name}:")
            out.extend(_lines(value, indent + 1, max_array))
        elif isinstance(value, (list, tuple, np.ndarray)) or type(value).__name__ == "array":
            out.extend(_array_lines(name, list(value), _element_type(ftype), pad, indent,
                                    max_array))
        else:
            out.append(f"{pad}{name}: {_scalar(value, ftype)}")
    return out


def _array_lines(
    name: str, items: list[Any], etype: str, pad: str, indent: int, max_array: int
) -> list[str]:
    n = len(items)
    shown = items if max_array <= 0 else items[:max_array]
    more = n - len(shown)
    if n == 0:
        return [f"{pad}{name}: []"]
    if not any(_is_message(v) for v in shown):
        body = ", ".join(_scalar(v, etype) for v in shown)
        if more:
            return [f"{pad}{name}: [{body}, '...']  # {n} items, first {len(shown)} shown"]
        return [f"{pad}{name}: [{body}]"]
    out = [f"{pad}{name}:"]
    for v in shown:
        sub = _lines(v, indent + 2, max_array)
        if sub:
            first = sub[0][len(pad) + 4 :]
            out.append(f"{pad}  - {first}")
            out.extend(f"{pad}    {line[len(pad) + 4:]}" for line in sub[1:])
        else:
            out.append(f"{pad}  - {{}}")
    if more:
        out.append(f"{pad}  - '...'  # {n} items, first {len(shown)} shown")
    return out


def message_to_text(msg: Any, max_array: int = DEFAULT_MAX_ARRAY) -> str:
    """YAML-like text of an rclpy message (no trailing separator). max_array <= 0: no cut."""
    if not _is_message(msg):
        raise TypeError(f"{type(msg).__name__} is not a ROS message")
    return "\n".join(_lines(msg, 0, max_array))
