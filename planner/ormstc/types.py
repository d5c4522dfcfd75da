"""Frozen value types of the ORMSTC state machine: configuration, requests, events, messages.

The machine is sans-I/O: it emits *requests* (sense, move, ask about a peer, broadcast, done)
and consumes *events* (the answers, peer messages, peer deaths and clock ticks). The
``*Msg`` classes are what robots broadcast to each other; the bus gives them codecs.
Coordinates are (row, col) with rows growing downwards; a cell (r, c) is the sub-cells
(2r..2r+1, 2c..2c+1). No bounds are known: cells may lie anywhere.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum

from planner.geometry import Cell, SubCell


class SenseMode(Enum):
    """How a robot looks at neighbouring cells."""

    ALL = "all"  # the three neighbouring cells at once (the algorithm's assumption)
    SINGLE = "single"  # RV-400: one cell at a time (turn, sense, turn back)


class Priority(Enum):
    """Who wins a contested claim."""

    ID = "id"  # highest robot id
    FEWEST = "fewest"  # fewest covered cells, then highest id


class CellStatus(Enum):
    FREE = "free"
    OBSTACLE = "obstacle"  # an obstacle in at least one sub-cell, or outside the world
    ROBOT = "robot"  # a robot body in at least one sub-cell (static obstacle unknown)
    # the half the walk enters is free, the other half not seen yet: only when the Sense
    # allowed it (``enter``); the robot then grows, enters and looks (planner/ormstc/inside.py)
    HALF = "half"


@dataclass(frozen=True)
class MachineConfig:
    """One robot's parameters. ``start`` is its absolute position in sub-cell units."""

    robot: int
    team: int
    start: tuple[float, float]
    claim_wait: float = 2.0
    sense_mode: SenseMode = SenseMode.ALL
    priority: Priority = Priority.ID
    watch_interval: float = 10.0
    bump_backoff: float = 3.0
    # how long a body must have held the robot up before it walks round a passage or steps
    # aside (planner/ormstc/passage.py), besides a count of bumps
    hold_up: float = 0.0
    announce_connections: bool = False  # broadcast ConnectionMsg (for monitors only)
    # decide a claim only once every live peer has acknowledged it (PeerAck), and let a
    # peer's later claim, edge or completion settle its earlier claims (needs in-order
    # delivery per sender: agent/ormstc/wire.py over planner/ormstc/streams.py)
    await_acks: bool = False
    seed: int = 0
    # how long a lost claim's winner has to be heard building its tree edge before the loser
    # decides the cell again (None: 2 claim_wait + 1, enough when every message arrives
    # within the window; a driver that waits for acknowledgements passes longer)
    claim_ttl: float | None = None


# ---- requests (machine -> driver) ----

@dataclass(frozen=True, slots=True)
class Sense:
    """Report the status of these cells (SINGLE mode: one cell, ``turn`` = look sideways).

    With ``enter`` the first cell may be reported HALF. A first cell that is the one the body
    stands in (planner/ormstc/inside.py) is looked at from inside.
    """

    cells: tuple[Cell, ...]
    turn: bool = False
    enter: bool = False


@dataclass(frozen=True, slots=True)
class Move:
    """Move the body to the 4-adjacent sub-cell ``to``."""

    to: SubCell


@dataclass(frozen=True, slots=True)
class IsAlive:
    """Ask the failure detector whether ``robot`` is alive."""

    robot: int


@dataclass(frozen=True, slots=True)
class Broadcast:
    """Send ``message`` to every peer (fire and forget; per-sender FIFO assumed)."""

    message: Message


@dataclass(frozen=True, slots=True)
class Done:
    """This robot believes the mission is over (may be followed by more work on a death)."""

    now: float


Request = Sense | Move | IsAlive | Broadcast | Done


# ---- events (driver -> machine) ----

@dataclass(frozen=True, slots=True)
class Tick:
    now: float


@dataclass(frozen=True, slots=True)
class SenseResult:
    statuses: tuple[tuple[Cell, CellStatus], ...]


@dataclass(frozen=True, slots=True)
class MoveResult:
    ok: bool  # False: bumped, the body did not move


@dataclass(frozen=True, slots=True)
class AliveResult:
    robot: int
    alive: bool


@dataclass(frozen=True, slots=True)
class PeerMessage:
    sender: int
    message: Message


@dataclass(frozen=True, slots=True)
class PeerDied:
    robot: int


@dataclass(frozen=True, slots=True)
class PeerAck:
    """``robot`` had taken this machine's first ``upto`` broadcasts, in order, when it said
    so, and every message it said before that has been delivered (``upto`` = inf: it will
    say nothing more that matters: dead, gone, or not taking part)."""

    robot: int
    upto: float


Event = Tick | SenseResult | MoveResult | AliveResult | PeerMessage | PeerDied | PeerAck


# ---- messages (robot -> robots) ----

@dataclass(frozen=True, slots=True)
class StartMsg:
    """Alg. 1 line 10: my starting sub-cell (its cell is mine from now on)."""

    robot: int
    sub: SubCell


@dataclass(frozen=True, slots=True)
class ClaimMsg:
    """Lines 15/34, first half: I want to build a tree edge into ``cell``."""

    robot: int
    cell: Cell
    covered: int  # cells owned when claiming (for Priority.FEWEST)


@dataclass(frozen=True, slots=True)
class TreeEdgeMsg:
    """Lines 15/34: I built the tree edge ``parent`` -> ``child``; ``child`` is mine."""

    robot: int
    parent: Cell
    child: Cell


@dataclass(frozen=True, slots=True)
class RetractionMsg:
    """I take back my tree edge ``parent`` -> ``child``: I grew into ``child`` on its near half
    and found an obstacle or a dead robot's body in it from inside (planner/ormstc/inside.py).
    For monitors only: peers keep ``child`` as mine, so nobody grows into it again."""

    robot: int
    parent: Cell
    child: Cell


@dataclass(frozen=True, slots=True)
class ConnectionMsg:
    """Lines 9-10: my cell ``mine`` borders ``theirs`` of robot ``peer`` (monitoring only)."""

    robot: int
    peer: int
    mine: Cell
    theirs: Cell


@dataclass(frozen=True, slots=True)
class DeadRobotMsg:
    """Lines 13-14/27/33: robot ``dead`` is dead; its cells are empty again."""

    robot: int
    dead: int


@dataclass(frozen=True, slots=True)
class CompletionMsg:
    """Line 24: I have covered every cell I can reach."""

    robot: int
    cells: int


@dataclass(frozen=True, slots=True)
class WithdrawalMsg:
    """Line 28: I take back my completion to cover cells robot ``peer`` no longer holds."""

    robot: int
    peer: int


Message = (StartMsg | ClaimMsg | TreeEdgeMsg | ConnectionMsg | DeadRobotMsg | CompletionMsg
           | WithdrawalMsg | RetractionMsg)
