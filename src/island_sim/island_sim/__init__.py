"""island_sim: the simulated robot (line-segment worlds, sonar ring, drifting odometry, hall
following).

- `island_sim.core`: the simulation itself, numpy/scipy only (see its docstring);
- `conversions`: the simulator's own messages (clock_msg, range_msg); the generic ones are in
  `island_msgs_py.conversions`;
- `nodes`: odometry_node, sonar_node, hall_follower_node (thin rclpy nodes).
Nothing of island_mapping is imported here. This package module re-exports nothing.
"""
