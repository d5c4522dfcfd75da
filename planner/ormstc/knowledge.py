"""What one robot knows about the world and its peers, built only from its own sensing and
the messages it heard: cell owners, obstacles, dead and finished robots, pending claims.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from planner.ormstc.claims import ClaimBook
from planner.ormstc.types import (
    Cell,
    CellStatus,
    ClaimMsg,
    CompletionMsg,
    DeadRobotMsg,
    Message,
    Priority,
    StartMsg,
    SubCell,
    TreeEdgeMsg,
    WithdrawalMsg,
)


@dataclass
class Knowledge:
    """One robot's map and peer table (mutable, private to its machine)."""

    me: int
    team: int
    priority: Priority
    starts: dict[int, SubCell] = field(default_factory=dict)
    # owners per cell in the order heard; several only when a dead robot's cell was retaken
    owners: dict[Cell, list[int]] = field(default_factory=dict)
    obstacle: set[Cell] = field(default_factory=set)
    free: set[Cell] = field(default_factory=set)
    dead: set[int] = field(default_factory=set)
    released: set[int] = field(default_factory=set)
    completed: set[int] = field(default_factory=set)
    claim_ttl: float = float("inf")
    # in-order delivery per sender (MachineConfig.await_acks): a peer's claim, tree edge
    # or completion settles its earlier claims (it decides one claim at a time), and heard
    # claims never expire by time
    fifo: bool = False
    # robot -> how many of this machine's broadcasts it has acknowledged (PeerAck)
    acks: dict[int, float] = field(default_factory=dict)
    awaiting: bool = False  # the machine waits for acknowledgements: one sets ``changed``
    now: float = 0.0  # the owning machine keeps this current
    claims: ClaimBook = field(init=False)
    changed: bool = False  # a peer finished, withdrew or died since the flag was cleared
    # far cells of the connection table (planner/ormstc/connections.py may remove none) and
    # whether any of their owner lists changed: lets the table skip an unchanged re-scan
    watched: set[Cell] = field(default_factory=set)
    watched_changed: bool = False
    # (cell, robot): a live robot's tree edge into a cell this robot owns, queued for the
    # machine to resolve (planner/ormstc/conflicts.py); the edge is not recorded until then
    conflicts: list[tuple[Cell, int]] = field(default_factory=list)
    # message class -> what hearing it does; one dict lookup per message instead of a chain
    handlers: dict[type, Callable[[Any], None]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # with in-order delivery no claim expires by time, this robot's own included: its
        # decision may wait for acknowledgements past any ttl, and an own claim that lapsed
        # meanwhile lost to a rival that, holding it, lost too (chaos seed 63, trial 110)
        self._expiry = float("inf") if self.fifo else self.claim_ttl
        self.claims = ClaimBook(self.priority, self._expiry)
        self._pending = self.claims.pending  # the same dict, one attribute nearer
        self._fewest = self.priority is Priority.FEWEST
        self._others = frozenset(range(self.team)) - {self.me}
        self._claimed: dict[int, set[Cell]] = {}  # robot -> cells it claimed (fifo only)
        self.handlers = {TreeEdgeMsg: self._hear_edge, ClaimMsg: self._hear_claim,
                         StartMsg: self._hear_start, CompletionMsg: self._hear_completion,
                         WithdrawalMsg: self._hear_withdrawal, DeadRobotMsg: self._hear_dead}

    def own(self, cell: Cell, robot: int) -> None:
        if cell in self.watched:
            self.watched_changed = True
        holders = self.owners.setdefault(cell, [])
        if robot in holders:
            holders.remove(robot)
        holders.append(robot)

    def live_owner(self, cell: Cell) -> int | None:
        """The most recently heard owner of ``cell`` not known dead."""
        for robot in reversed(self.owners.get(cell, ())):
            if robot not in self.dead:
                return robot
        return None

    def dead_owners(self, cell: Cell) -> list[int]:
        return [robot for robot in self.owners.get(cell, ()) if robot in self.dead]

    def was_owned(self, cell: Cell) -> bool:
        return cell in self.owners

    def note_sensed(self, cell: Cell, status: CellStatus) -> None:
        # a robot body hides whatever is under it, so only free/obstacle are remembered
        if status is CellStatus.OBSTACLE:
            self.obstacle.add(cell)
        elif status is CellStatus.FREE:
            self.free.add(cell)

    def unknown_around(self, cell: Cell, skip: Cell, mine: set[Cell]) -> list[Cell]:
        """Neighbours of ``cell`` (but ``skip``) nothing is known about yet."""
        out = []
        for dr, dc in ((-1, 0), (0, -1), (1, 0), (0, 1)):
            other = (cell[0] + dr, cell[1] + dc)
            if (other != skip and other not in mine and other not in self.obstacle
                    and other not in self.free and other not in self.owners):
                out.append(other)
        return out

    def mark_dead(self, robot: int) -> None:
        if robot != self.me and robot not in self.dead:
            self.dead.add(robot)
            self.changed = True

    def acked(self, robot: int, upto: float) -> None:
        """PeerAck: ``robot`` had taken our first ``upto`` broadcasts, and all it said before
        telling us is known."""
        if upto > self.acks.get(robot, 0):
            self.acks[robot] = upto
            if self.awaiting:
                self.changed = True

    def acked_by_all(self, index: int) -> bool:
        """Whether every live peer has acknowledged our broadcast number ``index``."""
        acks, dead = self.acks, self.dead
        return all(acks.get(robot, 0) >= index for robot in self._others if robot not in dead)

    def _supersede(self, robot: int) -> None:
        """In-order delivery: ``robot`` has decided every claim it said before this message."""
        cells = self._claimed.pop(robot, None)
        if not cells:
            return
        pending = self._pending
        for cell in cells:
            heard = pending.get(cell)
            if heard is not None and heard.pop(robot, None) is not None and not heard:
                del pending[cell]

    def hear(self, message: Message) -> None:
        """Update the map from a peer's message (order across senders is arbitrary)."""
        handler = self.handlers.get(message.__class__)
        if handler is not None:  # ConnectionMsg and RetractionMsg are for monitors only
            handler(message)

    def _hear_edge(self, message: TreeEdgeMsg) -> None:
        child = message.child
        holders = self.owners.get(child)
        robot = message.robot
        if holders is None:
            self.owners[child] = [robot]
            if child in self.watched:
                self.watched_changed = True
        elif self.me in holders and robot != self.me and robot not in self.dead:
            self.conflicts.append((child, robot))
        else:
            self.own(child, robot)
        self._pending.pop(child, None)  # claims.settle
        if self.fifo:
            self._supersede(robot)

    def _hear_claim(self, message: ClaimMsg) -> None:
        # ClaimBook.hear with priority_key inlined: every robot hears every claim
        robot = message.robot
        claim = ((-message.covered, robot) if self._fewest else (0, robot),
                 self.now + self._expiry)
        if self.fifo:
            self._supersede(robot)
            self._claimed[robot] = {message.cell}
        pending = self._pending
        heard = pending.get(message.cell)
        if heard is None:
            pending[message.cell] = {robot: claim}
        else:
            heard[robot] = claim

    def _hear_start(self, message: StartMsg) -> None:
        sub = message.sub
        self.starts[message.robot] = sub
        self.own((sub[0] >> 1, sub[1] >> 1), message.robot)
        self.changed = True

    def _hear_completion(self, message: CompletionMsg) -> None:
        if self.fifo:
            self._supersede(message.robot)
        self.completed.add(message.robot)
        self.changed = True

    def _hear_withdrawal(self, message: WithdrawalMsg) -> None:
        self.completed.discard(message.robot)
        self.changed = True

    def _hear_dead(self, message: DeadRobotMsg) -> None:
        self.mark_dead(message.dead)
        self.released.add(message.dead)
        self.changed = True

    def all_started(self) -> bool:
        return all(r in self.starts or r in self.dead for r in range(self.team))

    def peers_settled(self) -> bool:
        """Every other robot finished, or died finished, or died and had its cells freed."""
        # set algebra, not a loop over the team: watchers ask this on every wake
        return not self._others.difference(self.completed, self.dead & self.released)
