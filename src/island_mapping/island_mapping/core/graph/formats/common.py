"""What the file formats share: the loaders' result type and reading JSON within the limits."""

from __future__ import annotations

from typing import Any, Protocol

from island_msgs_py.json_io import GraphFormatError, loads, read_json_file
from island_msgs_py.limits import MAX_ITEM_JSON_BYTES
from island_msgs_py.types import Edge, Island, Pose2D

Parts = tuple[list[Island], list[Edge]]
"""What a loader returns: the islands and the edges, each validated on its own; the graph
checks how they fit together."""



class GraphView(Protocol):
    """What a saver reads of a graph (TopoGraph is one); the savers need no more, so the
    formats do not import the model that imports them."""

    def __len__(self) -> int: ...
    def islands(self) -> list[Island]: ...
    def edges(self) -> list[Edge]: ...
    def island_ids(self) -> list[int]: ...
    def has_edge(self, source: int, target: int) -> bool: ...
    def display_layout(self, margin_m: float = ...) -> dict[int, Pose2D]: ...


__all__ = ["GraphView", "Parts", "json_attr", "read_json_file"]


def json_attr(text: Any, path: str) -> Any:
    """The value of a JSON-encoded string attribute (GraphML keeps lists as JSON strings),
    parsed within the limits of `island_msgs_py.limits`."""
    if not isinstance(text, str):
        raise GraphFormatError(path, "expected a JSON string attribute")
    return loads(text, path, MAX_ITEM_JSON_BYTES)
