"""Builtin worlds as ASCII maps; see planner.maps.worlds and docs/maps.md."""
