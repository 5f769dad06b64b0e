"""Saver of the project's JSON graph document (format `islands-graph`, island_msgs_py.json_io)."""

from __future__ import annotations

import os
from pathlib import Path

from island_mapping.core.graph.formats.common import GraphView
from island_msgs_py import json_io


def save_json(graph: GraphView, path: str | os.PathLike[str]) -> Path:
    """Write the graph document atomically (indented for reading and diffing)."""
    return json_io.save_graph_json(path, graph.islands(), graph.edges())
