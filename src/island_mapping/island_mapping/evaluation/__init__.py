"""Simulator-backed evaluation of the mapping core.

The only layer of island_mapping besides the app layer (cli, runner) that may import island_sim:
it drives a simulated robot to measure what the core builds (offline exploration, route
following against the world's truth, confidence maps, the world's own places). It never imports
rclpy; nodes never import it.
"""
