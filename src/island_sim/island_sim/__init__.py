"""island_sim."""
