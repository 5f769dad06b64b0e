"""Simulator-backed evaluation of the mapping core.

The only layer of island_mapping besides the app layer (cli, runner) that may import island_sim:
it drives a simulated robot to measure what the core builds (offline exploration, route
following against the world's truth, confidence maps, the world's own places). It never imports
rclpy; nodes never import it.

- `navigate`: SimSetup, SimRunner (the simulated robot driven by the route-following
  generators of `island_mapping.core.route`, which hold NavigateConfig and the motions);
- `routes`: follow_route, follow_route_global_odometry, evaluate_routes (routes by the map vs
  global odometry); `explore`: explore, ExplorationResult (offline exploration, deterministic);
- `validation`: confidence maps with the simulated sonar vs the measures (run_validation).
Import from the modules: this package module re-exports nothing.
"""
