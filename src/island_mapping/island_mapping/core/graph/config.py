"""Frozen config dataclasses of the graph store and the graph server (the single source of
their defaults; the node declares them as ROS parameters)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class GraphStoreConfig:
    """How the graph server persists accepted changes."""

    compact_every: int = field(
        default=200,
        metadata={"help": "rewrite the snapshot and empty the change log after this many "
                          "logged changes [changes]"},
    )
    fsync: bool = field(
        default=True,
        metadata={"help": "fsync the change log before acknowledging a change (needed to "
                          "survive power loss; a SIGKILL is survived either way) [bool]"},
    )

    def __post_init__(self) -> None:
        if self.compact_every < 1:
            raise ValueError(f"compact_every must be >= 1, got {self.compact_every}")


@dataclass(frozen=True)
class GraphServerConfig:
    """Parameters of topo_graph_server_node (declared as top-level ROS parameters)."""

    storage_path: str = field(
        default="~/.ros/islands/topo_graph",
        metadata={"help": "directory holding the persisted graph (snapshot.json + changes.jsonl); "
                          "reloaded on start; empty = in memory only [path]"},
    )
    output_dir: str = field(
        default="",
        metadata={"help": "where /topo_graph/save writes graph.json, graph.geojson, "
                          "graph.graphml; empty = <storage_path>/export, or ./topo_graph_export "
                          "when in memory [path]"},
    )
    compact_every: int = field(
        default=200,
        metadata={"help": "snapshot the graph and reset the change log every N changes [changes]"},
    )
    display_frame: str = field(
        default="islands_layout",
        metadata={"help": "frame of the display layout the markers are drawn in (no metric "
                          "meaning: islands share no global frame) [frame id]"},
    )
    markers_in_island_frames: bool = field(
        default=False,
        metadata={"help": "draw each island's model in its own frame island_<id> (needs TF from "
                          "elsewhere) instead of placing it in display_frame [bool]"},
    )
