"""topo_graph_server_node: holds the map M = {V, E}, persists it, serves it on standard types.

Topics (latched: reliable, transient local, depth 1; republished after every change):
  topo_graph/markers  visualization_msgs/MarkerArray  (display layout, see conversions.py),
                      stamped with the node's clock (sim time with use_sim_time)
  topo_graph/json     std_msgs/String                 (the versioned graph JSON document)
Services:
  topo_graph/add   rcl_interfaces/srv/SetParameters  each Parameter named `island`, `edge`,
                   `exit` or `new_exit` with a JSON string value; add or replace (an exit: set
                   its state; a new exit: add it to an existing island);
                   one result per item; at most `max_items_per_request` items
  topo_graph/get   std_srvs/srv/Trigger             message = the graph JSON
  topo_graph/plan  nav_msgs/srv/GetPlan             start/goal header.frame_id = island frames
                   (`island_<id>`); plan = the island origins in route order (empty if none)
  topo_graph/save  std_srvs/srv/Trigger             writes graph.json/.geojson/.graphml
Names are relative to the node's namespace (a fleet shares one server: remap the robots' clients
to it). storage_path is read-only; the other parameters take effect when set at run time (the
markers are republished when their frame settings change).
See docs/graph_server.md for why these types and how persistence works.
"""

from __future__ import annotations

import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from island_msgs_py.json_io import GraphFormatError
from island_msgs_py.qos import LATCHED
from island_msgs_py.ros_params import declare_config, log_ready, run_node
from island_msgs_py.types import ExitUpdate, Island, IslandTypeError, NewExit
from nav_msgs.msg import Path as PathMsg
from nav_msgs.srv import GetPlan
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.node import Node
from std_msgs.msg import String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from island_mapping.core.graph import (
    GraphError,
    GraphServerConfig,
    GraphStore,
    GraphStoreConfig,
    TopoGraph,
)
from island_msgs_py import conversions as cv

NODE_NAME = "topo_graph_server"
WARN_THROTTLE_S = 1.0
MEMORY_EXPORT_DIR = "topo_graph_export"  # save target when in memory and no output_dir


class TopoGraphServerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self.config: GraphServerConfig = declare_config(self, "", GraphServerConfig(),
                                                        on_change=self._reconfigure)
        storage = self.config.storage_path.strip()
        self.store: GraphStore | None = None
        if storage:
            self.store = GraphStore(os.path.expanduser(storage), GraphStoreConfig())
            self.graph = self.store.graph
        else:
            self.graph = TopoGraph()
        self.rejected = 0  # count of rejected add items and failed requests
        self.markers_pub = self.create_publisher(MarkerArray, "topo_graph/markers", LATCHED)
        self.json_pub = self.create_publisher(String, "topo_graph/json", LATCHED)
        self.create_service(SetParameters, "topo_graph/add", self._on_add)
        self.create_service(Trigger, "topo_graph/get", self._on_get)
        self.create_service(GetPlan, "topo_graph/plan", self._on_plan)
        self.create_service(Trigger, "topo_graph/save", self._on_save)
        where = storage or "memory only"
        self.get_logger().info(
            f"graph server: {len(self.graph)} islands, {self.graph.num_edges} edges ({where})"
        )
        self.publish()
        log_ready(self)

    def _reconfigure(self, config: GraphServerConfig) -> None:
        """A live parameter was set (storage_path is read-only): used from the next request on;
        new marker frames are published at once."""
        redraw = (config.display_frame, config.markers_in_island_frames) != (
            self.config.display_frame, self.config.markers_in_island_frames)
        self.config = config
        if redraw:
            self.publish()

    # --- publishing ----------------------------------------------------------------------------

    def publish(self) -> None:
        stamp = self.get_clock().now().to_msg()
        islands, edges = self.graph.islands(), self.graph.edges()
        self.markers_pub.publish(cv.graph_to_marker_array(
            islands, edges, self.graph.display_layout(), self.config.display_frame,
            self.config.markers_in_island_frames, stamp,
        ))
        self.json_pub.publish(cv.graph_to_string_msg(islands, edges))

    # --- changes -------------------------------------------------------------------------------

    def _apply(self, item: Any) -> str:
        """One change, to the store when there is one (it keeps the graph), else the graph."""
        target = self.store if self.store is not None else self.graph
        if isinstance(item, ExitUpdate):
            island = target.apply_exit_update(item)
            state = next(e for e in island.exits if e.index == item.index).state
            return f"set exit {item.index} of island {item.island} to {state.value}"
        if isinstance(item, NewExit):
            return f"added exit {item.exit.index} to island {target.add_exit(item).id}"
        if isinstance(item, Island):
            return f"{'replaced' if target.put_island(item) else 'added'} island {item.id}"
        replaced = target.put_edge(item)
        return f"{'replaced' if replaced else 'added'} edge {item.source}->{item.target}"

    @property
    def _add_name(self) -> str:
        """The add service's name as resolved in this node's namespace (for the log)."""
        return str(self.resolve_service_name("topo_graph/add"))

    def _on_add(self, request: SetParameters.Request, response: SetParameters.Response) -> Any:
        limit = self.config.max_items_per_request
        if len(request.parameters) > limit:
            reason = (f"request refused: {len(request.parameters)} items, the limit is {limit} "
                      "per request (max_items_per_request); send them in several requests")
            self._reject(f"{self._add_name} {reason}")
            response.results = [SetParametersResult(successful=False, reason=reason)
                                for _ in request.parameters]
            return response
        changed = False
        for k, param in enumerate(request.parameters):
            try:
                item = cv.parameter_to_item(param, f"parameters[{k}]")
                reason = self._apply(item)
                changed = True
                response.results.append(SetParametersResult(successful=True, reason=reason))
            except (GraphFormatError, GraphError, IslandTypeError) as exc:
                self._reject(f"{self._add_name} rejected parameters[{k}]: {exc}")
                response.results.append(SetParametersResult(successful=False, reason=str(exc)))
            except Exception as exc:  # e.g. disk full: never die, never acknowledge
                self._reject(f"{self._add_name} failed on parameters[{k}]: {exc!r}")
                response.results.append(
                    SetParametersResult(successful=False, reason=f"internal error: {exc!r}"))
        if changed:
            try:
                self.publish()
            except Exception as exc:
                self.get_logger().error(f"publishing the graph failed: {exc!r}")
        return response

    def _reject(self, message: str) -> None:
        self.rejected += 1
        self.get_logger().warning(message, throttle_duration_sec=WARN_THROTTLE_S)

    # --- queries -------------------------------------------------------------------------------

    def _on_get(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        try:
            response.message = self.graph.to_json()
            response.success = True
        except Exception as exc:
            response.success, response.message = False, f"internal error: {exc!r}"
        return response

    def _on_plan(self, request: GetPlan.Request, response: GetPlan.Response) -> Any:
        stamp = self.get_clock().now().to_msg()
        response.plan = PathMsg()
        try:
            ends = []
            for name, frame in (("start", request.start.header.frame_id),
                                ("goal", request.goal.header.frame_id)):
                island_id = self.graph.island_by_frame(frame)
                if island_id is None:
                    raise GraphError(f"plan: {name} frame {frame!r} is not an island frame "
                                     "(expected island_<id> of a known island)")
                ends.append(island_id)
            route = self.graph.plan_route(ends[0], ends[1])
            response.plan = cv.route_to_path(
                [self.graph.get_island(i) for i in route.islands], stamp)
        except GraphError as exc:
            self.rejected += 1
            self.get_logger().error(str(exc), throttle_duration_sec=WARN_THROTTLE_S)
        except Exception as exc:
            self.rejected += 1
            name = self.resolve_service_name("topo_graph/plan")
            self.get_logger().error(f"{name} failed: {exc!r}")
        return response

    def output_dir(self) -> Path:
        if self.config.output_dir.strip():
            return Path(os.path.expanduser(self.config.output_dir.strip()))
        if self.store is not None:
            return self.store.directory / "export"
        return Path.cwd() / MEMORY_EXPORT_DIR

    def _on_save(self, request: Trigger.Request, response: Trigger.Response) -> Any:
        try:
            paths = self.graph.save_all(self.output_dir())
            response.success = True
            response.message = json.dumps({k: str(v) for k, v in paths.items()})
        except Exception as exc:
            self.rejected += 1
            response.success, response.message = False, f"save failed: {exc}"
            self.get_logger().error(response.message)
        return response

    def destroy_node(self) -> None:
        if self.store is not None:
            self.store.close()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> int:
    return run_node(TopoGraphServerNode, "topo_graph_server_node", args,
                    config_errors=(GraphFormatError, GraphError, OSError, ValueError))


if __name__ == "__main__":
    sys.exit(main())
