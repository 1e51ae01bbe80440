"""Exploration toolbox: the two-layer fuzzy perimeter follower (blocks and a subgraph)."""
