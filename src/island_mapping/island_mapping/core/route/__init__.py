"""Route following by the map, as generators of velocity commands (no ROS, no simulator).

Public API:
- `NavigateConfig`, `NavigateError` (config): route following's parameters;
- `Sense`, `Drive`, `Command`, `RouteTimeoutError` and the primitives `step`, `rotate_to`,
  `rotate_by`, `go_to`, `go_along_hall`, `execute_strategy`, `look_around`, and `stalled` (a wall
  stopped the robot, from its command and odometry) (motion);
- `Fix`, `localize_multi`, `localize_and_dock`, `search_along_axis`, `unconstrained_axis_rad`
  (arrival);
- `follow_route`, `route_edges`, `RouteObserver`, `TrustedArrivals`, `RouteOutcome`, `RouteEnd`
  (follower).

A generator yields one `(v, w)` per sensor period; its runner updates the shared `Sense` before
resuming it (the simulated evaluation after a physics step, the explorer node per scan).
"""

from island_mapping.core.route.arrival import (
    Fix,
    localize_and_dock,
    localize_multi,
    search_along_axis,
    unconstrained_axis_rad,
)
from island_mapping.core.route.config import NavigateConfig, NavigateError
from island_mapping.core.route.follower import (
    RouteEnd,
    RouteObserver,
    RouteOutcome,
    TrustedArrivals,
    follow_route,
    route_edges,
)
from island_mapping.core.route.motion import (
    Command,
    Drive,
    RouteDeviationError,
    RouteTimeoutError,
    Sense,
    execute_strategy,
    go_along_hall,
    go_to,
    look_around,
    rotate_by,
    rotate_to,
    stalled,
    step,
)

__all__ = [
    "Command",
    "Drive",
    "Fix",
    "NavigateConfig",
    "NavigateError",
    "RouteDeviationError",
    "RouteEnd",
    "RouteObserver",
    "RouteOutcome",
    "RouteTimeoutError",
    "Sense",
    "TrustedArrivals",
    "execute_strategy",
    "follow_route",
    "go_along_hall",
    "go_to",
    "localize_and_dock",
    "localize_multi",
    "look_around",
    "rotate_by",
    "rotate_to",
    "route_edges",
    "search_along_axis",
    "stalled",
    "step",
    "unconstrained_axis_rad",
]
