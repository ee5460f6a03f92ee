"""Domain-transform filter (depth super-resolution) in hardware."""
