"""island_msgs_py."""
