"""The mission as a robotics viewer draws it: a neutral, pure picture of the tracker's state.

Everything a Foxglove channel or a ROS 2 topic shows is computed here once, from the fleet
model, in the viewers' conventions: a right-handed ``map`` frame in metres, x east along the
columns, y north (so sub-cell row 0, the map's top, has the largest y), one sub-cell per
metre, yaw counter-clockwise from east. The renderers (``deploy.robotics.fox`` for
Foxglove's protobuf schemas, ``deploy.robotics.ros`` for ROS 2 CDR) only translate these
values into their message types, so both show the same thing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from bus.messages import NO_ROBOT
from deploy.monitor.model import FleetModel
from deploy.monitor.robots import RobotView
from deploy.monitor.types import MonitorEvent
from planner.types import SubCell

FRAME = "map"
SUB_CELL_M = 1.0  # the scene's unit: one sub-cell per metre (the tool size D is not on the wire)

Point = tuple[float, float]
U8Array = npt.NDArray[np.uint8]

# Event kinds a viewer should show as warnings or errors (the rest are information).
WARNING_KINDS = frozenset({"died", "detected_dead", "takeover", "conflict_lost", "withdrawn",
                           "bump", "left"})
ERROR_KINDS = frozenset({"mission_failed", "fenced", "stopped"})


@dataclass(frozen=True)
class GridLayers:
    """Per sub-cell, row 0 = the map's top row: free (1) or blocked (0), visit count
    (saturating at 255) and the robot that entered first (255: nobody or unknown)."""

    free: U8Array
    visits: U8Array
    owner: U8Array

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.free.shape[0]), int(self.free.shape[1]))


@dataclass(frozen=True)
class RobotMark:
    robot: int
    x: float
    y: float
    yaw: float
    label: str
    path: tuple[Point, ...]  # sub-cell centres entered, in order
    dead: bool
    done: bool
    left: bool


@dataclass(frozen=True)
class TreeSegment:
    """A spanning-tree edge between the centres of two 2 x 2 cells, and whose tree it is."""

    a: Point
    b: Point
    robot: int


@dataclass(frozen=True)
class LogLine:
    t: float  # seconds since the mission's t = 0 (as the model's records)
    level: str  # "info", "warning" or "error"
    name: str  # the event kind
    text: str


@dataclass(frozen=True)
class Scene:
    """One picture of the mission at model time ``t``."""

    t: float
    map_name: str
    grid: GridLayers | None  # None until the world has answered once
    robots: tuple[RobotMark, ...]
    tree: tuple[TreeSegment, ...]


def sub_cell_centre(cell: SubCell, rows: int) -> Point:
    """The centre of ``cell`` in the map frame of a map ``rows`` sub-cells tall."""
    return ((cell[1] + 0.5) * SUB_CELL_M, (rows - cell[0] - 0.5) * SUB_CELL_M)


def cell_centre(cell: SubCell, rows: int) -> Point:
    """The centre of the 2 x 2 cell ``cell`` (coarse coordinates)."""
    return ((2 * cell[1] + 1.0) * SUB_CELL_M, (rows - 2 * cell[0] - 1.0) * SUB_CELL_M)


def heading_yaw(heading: int) -> float:
    """planner.geometry's heading (0 = N, clockwise) as a yaw (0 = east, counter-clockwise)."""
    return math.pi / 2 - heading * math.pi / 2


def grid_layers(model: FleetModel) -> GridLayers | None:
    cover = model.cover
    if cover.free is None:
        return None
    shape = cover.free.shape
    visits = np.zeros(shape, dtype=np.uint8)
    owner = np.full(shape, NO_ROBOT, dtype=np.uint8)
    for (r, c), n in cover.covered_cells().items():
        if 0 <= r < shape[0] and 0 <= c < shape[1]:
            visits[r, c] = min(n, 255)
    for (r, c), robot in cover.owner.items():
        if 0 <= r < shape[0] and 0 <= c < shape[1] and 0 <= robot < NO_ROBOT:
            owner[r, c] = robot
    return GridLayers(cover.free.astype(np.uint8), visits, owner)


def _state_label(view: RobotView) -> str:
    if view.left:
        return "left"
    if view.dead:
        return "dead"
    return "done" if view.done else view.state


def robot_mark(view: RobotView, rows: int) -> RobotMark | None:
    if view.pose is None:
        return None
    x, y = sub_cell_centre((view.pose[0], view.pose[1]), rows)
    label = f"{view.robot} {_state_label(view)} · {view.moves} moves"
    return RobotMark(view.robot, x, y, heading_yaw(view.pose[2]), label,
                     tuple(sub_cell_centre(cell, rows) for cell in view.path),
                     view.dead, view.done, view.left)


def scene(model: FleetModel) -> Scene:
    """The picture of everything ``model`` knows now."""
    grid = grid_layers(model)
    rows = grid.shape[0] if grid is not None else 0
    marks = (robot_mark(v, rows) for _, v in sorted(model.robots.items()))
    tree = tuple(TreeSegment(cell_centre(a, rows), cell_centre(b, rows), robot)
                 for (a, b), robot in sorted(model.edges.items()))
    return Scene(model.t, model.cover.map_name, grid,
                 tuple(m for m in marks if m is not None), tree)


def log_lines(events: Iterable[MonitorEvent]) -> list[LogLine]:
    """The tracker's events as log lines, with a level a viewer can filter on."""
    out = []
    for event in events:
        level = "error" if event.kind in ERROR_KINDS else \
            "warning" if event.kind in WARNING_KINDS else "info"
        out.append(LogLine(event.t, level, event.kind, event.text))
    return out
