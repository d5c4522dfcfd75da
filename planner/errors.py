"""Exceptions raised by the planner for user mistakes and infeasible inputs.

Every error a user can cause derives from :class:`PlannerError`; command-line front ends catch
that one class and print its message (never a traceback).
"""

from __future__ import annotations


class PlannerError(Exception):
    """Base class of every planner error a user can cause."""


class MapFormatError(PlannerError):
    """A map file is malformed. The message names file, line/column and what was expected."""

    def __init__(self, path: str, message: str, line: int | None = None,
                 column: int | None = None) -> None:
        where = path
        if line is not None:
            where += f":{line}"
            if column is not None:
                where += f":{column}"
        super().__init__(f"{where}: {message}")
        self.path = path
        self.line = line
        self.column = column


class EmptyMapError(PlannerError):
    """The map has no free coarse cell (every 2 x 2 block holds an obstacle)."""


class RobotPlacementError(PlannerError):
    """A robot start is outside the map, on an obstacle, in a discarded cell, or duplicated."""


class DisconnectedRobotsError(PlannerError):
    """Robots start in different connected components of the free cells."""


class InfeasiblePlanError(PlannerError):
    """No allocation satisfies the constraints (for example the robots' fuel limits)."""


class MapReadError(PlannerError):
    """A map file (or builtin world) cannot be found or read. The message names the path."""

    def __init__(self, path: str, message: str) -> None:
        super().__init__(f"{path}: {message}")
        self.path = path


class TreeError(PlannerError):
    """Cells cannot carry the requested spanning tree: disconnected, bad root, edge or kind."""


class UnsupportedPlanError(PlannerError):
    """A plan or failure schedule the takeover simulator cannot run (e.g. non-unit speeds)."""


class UnknownAlgorithmError(PlannerError):
    """An algorithm name that no dispatcher knows (the message lists the known names)."""


class RobotParameterError(PlannerError):
    """Per-robot speeds or fuel limits are malformed: wrong count, non-positive or non-finite."""


class TreeFormatError(MapFormatError):
    """A ``.tree`` file (connected tree coverage) is malformed: file, line and expectation."""
