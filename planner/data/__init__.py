"""Data files shipped with the planner (read with importlib.resources)."""
