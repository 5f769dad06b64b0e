"""island_mapping."""
