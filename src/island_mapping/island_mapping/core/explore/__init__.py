"""Exploration by the map (issue 16): exits, the explorer's mission, loop closure.

Pure (numpy/scipy/networkx and the other cores; no rclpy, no island_sim). Public API:

- `ExitConfig`, `DoorwayConfig`, `NoveltyConfig`, `ExplorerConfig`, `ExploreError` (config);
- `ExitEvidence`, `find_exits`, `arrival_exit`, `gate`, `free_lanes` (exits: where free space
  leads away from an island, in its frame);
- `Target`, `nearest_unexplored`, `route_edges`, `unexplored_count` (planner);
- `known_space_costs` (novelty: the planner's extra cost of exits into space the map knows);
- `plan_departure`, `DeparturePlan`, `choose_lane`, `drive_departure`, `go_clear` (departure
  through an exit's gate or doorway; a drive that stops short of a wall ahead);
- `pass_doorway` (a doorway no lane shows: found by a look at its wall and jambs, passed at its
  middle);
- `relocalize` (a second look at the island left when the way back did not localize);
- `Explorer` (mission: one step per scan); `ExplorerCommand`, `ExplorerState`,
  `ExplorerStatus`, `Docked`, `Handover`, `Abort`, `Confirm`, `Reject` (requests: what it says
  and asks);
- `apply_to_builder`, `Applied`, `FollowerAction` (the requests as the builder takes
  them: one dispatch for the builder node and the offline harness);
- `rehearse` (more evidence for a held star: a known island's edge driven to its neighbour);
- `explorer_hooks`, `arrival_agrees`, `loop_closure_gate`, `loop_closure_hooks` (the builder
  hooks an explorer installs; the loop closure's gate and topological evidence; the loop
  closure alone, as a recording's passive mode installs it).
"""

from island_mapping.core.explore.apply import (
    Applied,
    FollowerAction,
    apply_to_builder,
)
from island_mapping.core.explore.config import (
    DoorwayConfig,
    ExitConfig,
    ExploreError,
    ExplorerConfig,
    NoveltyConfig,
)
from island_mapping.core.explore.departure import (
    DeparturePlan,
    choose_lane,
    drive_departure,
    go_clear,
    plan_departure,
)
from island_mapping.core.explore.doorway import pass_doorway
from island_mapping.core.explore.exits import (
    ExitEvidence,
    arrival_exit,
    find_exits,
    free_lanes,
    gate,
)
from island_mapping.core.explore.hooks import (
    arrival_agrees,
    explorer_hooks,
    loop_closure_gate,
    loop_closure_hooks,
)
from island_mapping.core.explore.mission import Explorer
from island_mapping.core.explore.novelty import known_space_costs
from island_mapping.core.explore.planner import (
    Target,
    nearest_unexplored,
    route_edges,
    unexplored_count,
)
from island_mapping.core.explore.relocalize import relocalize
from island_mapping.core.explore.requests import (
    Abort,
    Confirm,
    Docked,
    ExplorerCommand,
    ExplorerState,
    ExplorerStatus,
    Handover,
    Reject,
)

__all__ = [
    "Abort",
    "Applied",
    "Confirm",
    "DeparturePlan",
    "Docked",
    "DoorwayConfig",
    "ExitConfig",
    "ExitEvidence",
    "ExploreError",
    "Explorer",
    "ExplorerCommand",
    "ExplorerConfig",
    "ExplorerState",
    "ExplorerStatus",
    "FollowerAction",
    "Handover",
    "NoveltyConfig",
    "Reject",
    "Target",
    "apply_to_builder",
    "arrival_agrees",
    "arrival_exit",
    "choose_lane",
    "drive_departure",
    "explorer_hooks",
    "find_exits",
    "free_lanes",
    "gate",
    "go_clear",
    "known_space_costs",
    "loop_closure_gate",
    "loop_closure_hooks",
    "nearest_unexplored",
    "pass_doorway",
    "plan_departure",
    "relocalize",
    "route_edges",
    "unexplored_count",
]
