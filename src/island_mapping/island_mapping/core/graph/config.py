"""Frozen config dataclasses of the graph store and the graph server (the single source of
their defaults; the node declares them as ROS parameters)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass(frozen=True)
class GraphStoreConfig:
    """How the graph store writes and checks its database."""

    fsync: bool = field(
        default=True,
        metadata={"help": "commit each change with synchronous=FULL (fsync of the write-ahead "
                          "log before the acknowledgement: survives power loss); false = "
                          "NORMAL (survives a killed process, not a power cut) [bool]"},
    )
    full_integrity_check: bool = field(
        default=False,
        metadata={"help": "check the database on open with PRAGMA integrity_check (every page "
                          "and index) instead of quick_check [bool]"},
    )


@dataclass(frozen=True)
class GraphServerConfig:
    """Parameters of topo_graph_server_node (declared as top-level ROS parameters; storage_path
    is read-only, the others take effect when set at run time)."""

    storage_path: str = field(
        default="~/.ros/islands/topo_graph",
        metadata={"help": "directory holding the persisted graph (graph.sqlite3, created in a "
                          "missing or empty directory); reloaded and checked on start; empty = "
                          "in memory only [path]"},
    )
    output_dir: str = field(
        default="",
        metadata={"help": "where /topo_graph/save writes graph.json, graph.geojson, "
                          "graph.graphml; empty = <storage_path>/export, or ./topo_graph_export "
                          "when in memory [path]", "live": True},
    )
    max_items_per_request: int = field(
        default=256,
        metadata={"help": "most items one /topo_graph/add request may carry; a longer request "
                          "is refused whole (each item a durable write: the bound keeps one "
                          "request from holding the server for long) [items]",
                  "live": True, "range": (1, math.inf)},
    )
    display_frame: str = field(
        default="islands_layout",
        metadata={"help": "frame of the display layout the markers are drawn in (no metric "
                          "meaning: islands share no global frame) [frame id]", "live": True},
    )
    markers_in_island_frames: bool = field(
        default=False,
        metadata={"help": "draw each island's model in its own frame island_<id> (needs TF from "
                          "elsewhere) instead of placing it in display_frame [bool]",
                  "live": True},
    )

    def __post_init__(self) -> None:
        if self.max_items_per_request < 1:
            raise ValueError(
                f"max_items_per_request must be >= 1, got {self.max_items_per_request}")
