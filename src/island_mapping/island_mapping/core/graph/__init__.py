"""The global topological map M = {V, E} (paper eq. 1): model, planning, layout, formats, store.

Public API (import from `island_mapping.core.graph`; the submodules are implementation):

- model (`model.py`): `TopoGraph` (islands keyed by id, at most one directed edge per ordered
  pair; every change validated first, `GraphError` naming the island/edge otherwise), `PutMode`;
- errors (`errors.py`): `GraphError`, `NoRouteError`;
- strategy algebra (`strategy.py`): `normalize_strategy`, `reverse_strategy`,
  `strategy_displacement`, `without_loops`;
- planning (`planning.py`): `Route`, `Backend`, `SCIPY_MIN_ISLANDS`, `ROUTE_TREE_CACHE_SIZE`
  (`TopoGraph.plan_route` is the entry point);
- layout (`layout.py`): `display_layout` (`TopoGraph.display_layout`), for drawing only;
- formats (`formats/`): `GraphFormat`, `GEOJSON_FORMAT`, `GRAPHML_FORMAT` (and `TopoGraph`'s
  `to_/from_/save_/load_` json, geojson, graphml, `save_all`, `load_any`, `save_any`);
- exits (`exits.py`): `exit_state_counts` (`TopoGraph.set_exit`/`apply_exit_update` change one
  exit; the graph keeps exits and edges consistent);
- store (`store.py`): `GraphStore` (the graph persisted in a directory as SQLite),
  `GraphStoreError` (not a store, damaged, newer schema), `salvage_store` and
  `SalvageReport` (`store_salvage.py`: recovery of a damaged store);
- config (`config.py`): `GraphStoreConfig`, `GraphServerConfig`.

No rclpy here (numpy, scipy, networkx and island_msgs_py's ROS-free modules only).
"""

from island_mapping.core.graph.config import GraphServerConfig, GraphStoreConfig
from island_mapping.core.graph.errors import GraphError, NoRouteError
from island_mapping.core.graph.exits import exit_state_counts
from island_mapping.core.graph.formats import GEOJSON_FORMAT, GRAPHML_FORMAT, GraphFormat
from island_mapping.core.graph.layout import display_layout
from island_mapping.core.graph.model import PutMode, TopoGraph
from island_mapping.core.graph.planning import (
    ROUTE_TREE_CACHE_SIZE,
    SCIPY_MIN_ISLANDS,
    Backend,
    Route,
)
from island_mapping.core.graph.store import GraphStore, GraphStoreError
from island_mapping.core.graph.store_salvage import SalvageReport, salvage_store
from island_mapping.core.graph.strategy import (
    TURN_AROUND_DEG,
    normalize_strategy,
    reverse_strategy,
    strategy_displacement,
    without_loops,
)

__all__ = [
    "GEOJSON_FORMAT",
    "GRAPHML_FORMAT",
    "ROUTE_TREE_CACHE_SIZE",
    "SCIPY_MIN_ISLANDS",
    "TURN_AROUND_DEG",
    "Backend",
    "GraphError",
    "GraphFormat",
    "GraphServerConfig",
    "GraphStore",
    "GraphStoreConfig",
    "GraphStoreError",
    "NoRouteError",
    "PutMode",
    "Route",
    "SalvageReport",
    "TopoGraph",
    "display_layout",
    "exit_state_counts",
    "normalize_strategy",
    "reverse_strategy",
    "salvage_store",
    "strategy_displacement",
    "without_loops",
]
