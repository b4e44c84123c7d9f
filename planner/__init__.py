"""lutgen's planner: physics and optimisation for grasping a tumbling satellite.

Knows nothing of grids or files beyond its own configs; ``lut`` builds on it, never the reverse.
"""
