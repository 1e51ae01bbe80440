"""sim2d: a pymunk 2D world standing in for Player/Stage (see issue 3)."""
