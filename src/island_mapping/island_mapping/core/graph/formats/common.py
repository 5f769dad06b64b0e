"""What the file formats share: the loaders' result type and reading JSON text from files."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.types import Edge, Island

Parts = tuple[list[Island], list[Edge]]
"""What a loader returns: the islands and the edges, each validated on its own; the graph
checks how they fit together."""


def read_json_file(path: str | os.PathLike[str]) -> Any:
    """A JSON file's value; GraphFormatError naming the file when unreadable or not JSON."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise GraphFormatError(str(path), f"cannot read: {exc}") from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise GraphFormatError(str(path), f"not valid JSON: {exc}") from exc


def json_attr(text: Any, path: str) -> Any:
    """The value of a JSON-encoded string attribute (GraphML keeps lists as JSON strings)."""
    if not isinstance(text, str):
        raise GraphFormatError(path, "expected a JSON string attribute")
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise GraphFormatError(path, f"not valid JSON: {exc}") from exc
