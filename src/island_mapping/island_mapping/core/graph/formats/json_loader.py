"""Loader of the project's JSON graph document (format `islands-graph`, island_msgs_py.json_io)."""

from __future__ import annotations

import os

from island_mapping.core.graph.formats.common import Parts
from island_msgs_py import json_io


def load_json(path: str | os.PathLike[str]) -> Parts:
    """Read and validate a graph document; errors name the file and the bad field."""
    islands, edges = json_io.load_graph_json(path)
    return islands, edges
