"""Parameter overrides given on the command line: `NAME=VALUE`, the value parsed as YAML."""

from __future__ import annotations

import math
from typing import Any

from island_msgs_py.inputs import load_yaml
from island_msgs_py.json_checks import describe

from island_mapping.cli import CliError

NODE_SEPARATOR = ":"
"""Between the node and the parameter in `--param NODE:NAME=VALUE` (names contain dots)."""


def parse_assignments(items: list[str], flag: str) -> dict[str, Any]:
    """{name: value} from `NAME=VALUE` strings; a CliError naming `flag` and the item when one
    is not NAME=VALUE or its value is not a YAML bool, number or string."""
    out: dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name.strip():
            raise CliError(f"{flag} {describe(item)}: expected NAME=VALUE")
        try:
            value = load_yaml(text, "value", CliError)
        except CliError as exc:
            raise CliError(f"{flag} {describe(item)}: value is not YAML ({exc})") from None
        if value is None and not text.strip():
            raise CliError(f"{flag} {describe(item)}: expected NAME=VALUE with a value")
        if not isinstance(value, (bool, int, float, str)):
            raise CliError(f"{flag} {describe(item)}: value must be a bool, number or string")
        if isinstance(value, float) and not math.isfinite(value):
            raise CliError(f"{flag} {describe(item)}: value must be finite")
        out[name.strip()] = value
    return out


def parse_node_assignments(items: list[str], flag: str) -> dict[str, dict[str, Any]]:
    """{node: {name: value}} from `NODE:NAME=VALUE` strings (errors as parse_assignments)."""
    out: dict[str, dict[str, Any]] = {}
    for name, value in parse_assignments(items, flag).items():
        node, sep, param = name.partition(NODE_SEPARATOR)
        if not sep or not node.strip() or not param.strip():
            raise CliError(f"{flag} {name!r}: expected NODE{NODE_SEPARATOR}NAME=VALUE, e.g. "
                           f"odometry_node{NODE_SEPARATOR}odometry.wheelbase_error=0.01")
        out.setdefault(node.strip(), {})[param.strip()] = value
    return out
