"""Parameter overrides given on the command line: `NAME=VALUE`, the value parsed as YAML."""

from __future__ import annotations

from typing import Any

import yaml

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
            raise CliError(f"{flag} {item!r}: expected NAME=VALUE")
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise CliError(f"{flag} {item!r}: value is not YAML ({exc})") from None
        if not isinstance(value, (bool, int, float, str)):
            raise CliError(f"{flag} {item!r}: value must be a bool, number or string")
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
