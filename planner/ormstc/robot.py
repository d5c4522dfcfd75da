"""What the ORMSTC machine's phases see of the robot: the state and primitives shared by the
DFS (machine.py), the watch-and-take-over phase (watch.py) and conflict resolution
(conflicts.py).

The phases are written as free functions over this protocol rather than as methods of one
large class, so each fits on a page; the protocol is their contract, and machine.py is the one
module that knows all three. Generator flows yield ``(wait kind, argument)`` actions that the
machine's ``step`` resumes.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Protocol

from planner.ormstc.connections import Connections
from planner.ormstc.knowledge import Knowledge
from planner.ormstc.types import Cell, CellStatus, MachineConfig, Message, Request, SubCell

# wait kinds of a yielded action: an answer, a time, a time or a change of knowledge, the end
ANSWER, UNTIL, WAKE, FINISHED = 0, 1, 2, 3
Action = tuple[int, object]
Flow = Generator[Action, object, object]


class Robot(Protocol):
    config: MachineConfig
    me: int
    know: Knowledge
    connections: Connections
    now: float
    home: SubCell
    pos: SubCell
    mine: set[Cell]
    edges: dict[Cell, int]
    decided: dict[Cell, int]
    parent: dict[Cell, Cell]
    ceded: dict[Cell, int]
    passing: set[Cell]
    bumps: int
    conflicts: set[tuple[Cell, int]]
    cut: int
    given_up: int
    freed: list[int]
    withdrawn_for: int | None
    asked: Request | None
    finished: bool
    idle: bool
    done_sent: bool
    outbox: list[Request]

    def send(self, message: Message) -> None: ...

    def release(self, robot: int) -> None: ...

    def has_edge(self, cell: Cell, side: int) -> bool: ...

    def cover(self, root: Cell) -> Flow: ...

    def decide(self, cell: Cell, side: int) -> Flow: ...

    def move_to(self, to: SubCell) -> Flow: ...

    def moved(self, to: SubCell) -> None: ...

    def backoff(self) -> float: ...

    def ask_alive(self, robot: int) -> Flow: ...

    def sensed(self, target: Cell, result: object) -> CellStatus: ...
