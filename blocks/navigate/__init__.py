"""Navigation: plan on an occupancy grid and drive there.

The algorithms are plain modules, testable without the framework:

``grid``
    Obstacles inflated by the robot's radius, a clearance cost that keeps
    paths in the middle of doors and corridors, world <-> cell conversion.
``planner``
    A* on the 8-connected cost grid (pyastar2d), line-of-sight shortcutting,
    multi-leg plans through waypoints.
``pursuit``
    An adaptive pure-pursuit path follower for a skid-steer robot.
``visit``
    A go-to-goal state machine: plan, follow, look around, replan, give up.

``blocks.navigate.blocks`` adapts them to the dataflow (``navigate.goto``).
"""
