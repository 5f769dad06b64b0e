"""island_mapping: islands of reliability (Simhon & Dudek 1998) built, stored and used.

Layers, dependencies pointing down:
- app: `cli` (the `islands` tool), `runner` (every node in one process), `replay`, `viz`
  (matplotlib figures), `bag` (MCAP recording and replay);
- `evaluation`: simulator-backed evaluation of the core (may import island_sim, never rclpy);
- `nodes`: thin rclpy nodes (builder, localizer, graph server, recorder); nothing of island_sim;
- `core`: the mapping itself, numpy/scipy/networkx only (see its docstring).
This package module re-exports nothing.
"""
