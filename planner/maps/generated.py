"""Generated worlds named by a spec string: the same spec, the same map, on every host.

    open:20x30                  # 20 x 30 cells, no obstacle
    obstacles:40x40:30%:7       # 30 % of the cells blocked at random (seed 7), kept connected
    obstacles:20x30:80:7        # exactly 80 blocked cells
    rooms:30x40:3               # rooms behind one-cell walls, joined by doors
    maze:15x23:2                # one-cell corridors (odd sides), one way between two cells
    city:128x128:5              # streets, blocks, yards and parks

Sizes are in cells (2 x 2 sub-cells each, the grid the planners work on); the last field
is the seed. A spec is just a name to every tool that takes a world (``mstc up --world``,
``mstc chaos --worlds``, the benchmarks), so a fleet's processes each build the map
themselves and agree on it without a file to share.
"""

from __future__ import annotations

import re

import numpy as np

from planner.errors import MapReadError
from planner.experiments.instances import grid_with_obstacles, maze_cells
from planner.grid import expand
from planner.maps.city import city_cells
from planner.maps.rooms import rooms_cells
from planner.types import OccupancyGrid

KINDS = ("open", "obstacles", "rooms", "maze", "city")
EXAMPLES = ("open:20x30", "obstacles:40x40:30%:7", "rooms:30x40:3", "maze:15x23:2",
            "city:128x128:5")
MAX_SIDE = 1024  # cells: a typo should not allocate gigabytes
_SIZE = re.compile(r"^(\d+)x(\d+)$")


def is_generated(spec: str) -> bool:
    """True if ``spec`` names a generated world (``kind:...`` with a known kind)."""
    return spec.split(":", 1)[0] in KINDS and ":" in spec


def generated_world(spec: str) -> OccupancyGrid:
    """The map ``spec`` names; MapReadError saying what is wrong with a malformed one."""
    kind, *fields = spec.split(":")
    if kind not in KINDS:
        raise _error(spec, f"unknown kind {kind!r}")
    expected = {"open": 1, "obstacles": 3, "rooms": 2, "maze": 2, "city": 2}[kind]
    if len(fields) != expected:
        raise _error(spec, f"{kind} takes {expected} field(s) after '{kind}:'")
    rows, cols = _size(spec, fields[0])
    if kind == "open":
        return OccupancyGrid(expand(np.ones((rows, cols), dtype=bool)), name=spec)
    seed = _integer(spec, fields[-1], "seed")
    rng = np.random.default_rng(seed)
    if kind == "maze" and (rows % 2 == 0 or cols % 2 == 0):
        raise _error(spec, f"a maze has odd sides (corridor, wall, corridor...), got "
                           f"{rows}x{cols}")
    blocked = _obstacles(spec, fields[1], rows * cols) if kind == "obstacles" else 0
    try:  # the generators' own ValueErrors (obstacles that would disconnect the map)
        if kind == "obstacles":
            cells = grid_with_obstacles(rows, cols, blocked, rng)
        elif kind == "rooms":
            cells = rooms_cells(rows, cols, rng)
        elif kind == "maze":
            cells = maze_cells((rows + 1) // 2, (cols + 1) // 2, rng)
        else:
            cells = city_cells(rows, cols, rng)
    except ValueError as exc:
        raise _error(spec, str(exc)) from exc
    return OccupancyGrid(expand(cells), name=spec)


def _error(spec: str, problem: str) -> MapReadError:
    return MapReadError(spec, f"{problem}; generated worlds look like " + ", ".join(EXAMPLES))


def _size(spec: str, text: str) -> tuple[int, int]:
    match = _SIZE.match(text)
    if match is None:
        raise _error(spec, f"size {text!r} is not ROWSxCOLS")
    rows, cols = int(match[1]), int(match[2])
    if not (1 <= rows <= MAX_SIDE and 1 <= cols <= MAX_SIDE):
        raise _error(spec, f"sides must be 1..{MAX_SIDE} cells, got {rows}x{cols}")
    return rows, cols


def _integer(spec: str, text: str, what: str) -> int:
    if not text.isdigit():
        raise _error(spec, f"{what} {text!r} is not a whole number")
    return int(text)


def _obstacles(spec: str, text: str, cells: int) -> int:
    """Blocked cells: a count, or a percentage of all cells ("30%")."""
    if text.endswith("%"):
        percent = _integer(spec, text[:-1], "obstacle share")
        if percent >= 100:
            raise _error(spec, f"obstacle share {text} leaves no free cell")
        return cells * percent // 100
    count = _integer(spec, text, "obstacle count")
    if count >= cells:
        raise _error(spec, f"{count} obstacles leave no free cell of {cells}")
    return count
