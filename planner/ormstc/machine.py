"""ORMSTC (Hazon, Mieli & Kaminka 2006, Alg. 1 and 2) as a sans-I/O state machine.

Drive it with ``requests = machine.step(events)``: pass every event that arrived (answers to
the previous requests, peer messages, peer deaths, and clock ticks) and carry out the returned
requests. At most one of Sense / Move / IsAlive is outstanding at a time and must be answered
(SenseResult / MoveResult / AliveResult) in a later ``step``; Broadcast and Done need no
answer. Waits (claims, bump back-off, watching peers) only end on a Tick, so a driver must
tick the machine while it has nothing else to say. Nothing assumes lockstep delivery: peer
messages may come late and in any order across senders (FIFO per sender is assumed).

The algorithm is written as one generator (the recursive DFS of Alg. 2 unrolled into the STC
walk around the growing tree); ``step`` resumes it when what it waits for has arrived. Every
driver answers the same Sense / IsAlive requests — the lockstep simulator from its ground
truth within the step, the agent from simhw and its peer table — so the papers' figures and
the fleet run one sensing path. Lines 21-36 (completion, watching, takeover) are in
planner/ormstc/watch.py, the resolution of two live owners of one cell in
planner/ormstc/conflicts.py.
"""

from __future__ import annotations

import random
from collections.abc import Iterable

from planner.ormstc.conflicts import settle
from planner.ormstc.connections import Connections
from planner.ormstc.inside import enter_to_look
from planner.ormstc.knowledge import Knowledge
from planner.ormstc.passage import reach
from planner.ormstc.robot import ANSWER, FINISHED, UNTIL, WAKE, Flow
from planner.ormstc.types import (
    AliveResult,
    Broadcast,
    Cell,
    CellStatus,
    ClaimMsg,
    ConnectionMsg,
    DeadRobotMsg,
    Event,
    IsAlive,
    MachineConfig,
    Message,
    Move,
    MoveResult,
    PeerAck,
    PeerDied,
    PeerMessage,
    Request,
    Sense,
    SenseMode,
    SenseResult,
    StartMsg,
    SubCell,
    Tick,
    TreeEdgeMsg,
)
from planner.ormstc.walk import DELTA, SIDE_AT, cell_of, neighbour, sub_facing
from planner.ormstc.watch import watch

_ANSWER, _UNTIL, _WAKE, _FINISHED = ANSWER, UNTIL, WAKE, FINISHED  # locals of the hot loop
_HEADING = {delta: side for side, delta in enumerate(DELTA)}


class OrmstcMachine:
    """One robot's ORMSTC controller. Public state is read-only for drivers and tests."""

    def __init__(self, config: MachineConfig) -> None:
        self.config = config
        self.me = config.robot
        # a claim heard at t is decided by t + wait and its edge heard by t + wait + D, with
        # D <= (wait + 1) / 2; 2 wait + 1 is past both
        ttl = 2 * config.claim_wait + 1 if config.claim_ttl is None else config.claim_ttl
        self.know = Knowledge(config.robot, config.team, config.priority, claim_ttl=ttl,
                              fifo=config.await_acks)
        self.now = 0.0
        start = config.start
        self.home: SubCell = (round(start[0]), round(start[1]))
        self.pos: SubCell = self.home
        self.mine: set[Cell] = set()
        self.edges: dict[Cell, int] = {}  # bit per side: own tree edge on that side
        self.decided: dict[Cell, int] = {}  # bit per side: the DFS has dealt with it
        self.parent: dict[Cell, Cell] = {}  # own cells in the order grown -> their parent
        self.ceded: dict[Cell, int] = {}  # own cells lost in a conflict, still walked: winner
        self.passing: set[Cell] = set()  # passages being walked round (passage.py): kept
        self.conflicts: set[tuple[Cell, int]] = set()  # (cell, other owner) resolved
        self.cut = 0  # cells given up in conflicts
        # cells grown into on their near half and given up: an obstacle or a dead robot's
        # body inside (inside.py)
        self.given_up = 0
        self.freed: list[int] = []  # dead robots whose cells this robot announced free
        self.withdrawn_for: int | None = None  # the peer of the last WithdrawalMsg sent
        self.asked: Request | None = None  # the last Sense / Move / IsAlive asked
        self.connections = Connections()
        self.moves = 0
        self.bumps = 0
        self.sense_turns = 0
        self.ack_waits = 0  # claims that waited past their window for acknowledgements
        self.broadcasts = 0  # Broadcast requests returned by step (their index, from 1)
        self.finished = False  # announced completion and not withdrawn
        self.idle = False  # finished with nothing to take over; waiting for peers
        self.done_sent = False
        self._heading: int | None = None
        self._rng = random.Random(config.seed * 1_000_003 + config.robot)
        self.outbox: list[Request] = []
        self._gen: Flow = self._run()
        self._wait = _ANSWER
        self._wait_until = 0.0
        self._answer: object = None
        self._started = False

    # ---- driver API ----

    def step(self, events: Iterable[Event] = ()) -> list[Request]:
        """Feed what happened; get what to do next. Put a Tick before the messages it dates."""
        know = self.know
        handlers, me = know.handlers, self.me
        for event in events:
            kind = event.__class__
            if kind is PeerMessage:
                if event.sender != me:  # type: ignore[union-attr]
                    message = event.message  # type: ignore[union-attr]
                    handler = handlers.get(message.__class__)  # Knowledge.hear, inlined
                    if handler is not None:
                        handler(message)
            elif kind is Tick:
                if event.now > self.now:  # type: ignore[union-attr]
                    self.now = know.now = event.now  # type: ignore[union-attr]
            elif kind is PeerDied:
                know.mark_dead(event.robot)  # type: ignore[union-attr]
            elif kind is PeerAck:
                know.acked(event.robot, event.upto)  # type: ignore[union-attr]
            else:
                self._answer = event
        if know.conflicts or self.ceded:
            settle(self)  # planner/ormstc/conflicts.py
        if self._ready():
            self._advance()
        out, self.outbox = self.outbox, []
        if self.config.await_acks:
            self.broadcasts += sum(1 for r in out if r.__class__ is Broadcast)
        return out

    def wake_time(self) -> float | None:
        """When a machine that hears nothing new next has something to do (None: now).

        A driver may skip ``step`` until then if no event is pending: a lockstep shortcut.
        """
        if not self._started:
            return None
        if self._wait == _ANSWER:
            return None if self._answer is not None else float("inf")
        if self._wait == _FINISHED:
            return float("inf")
        if self._wait == _WAKE and self.know.changed:
            return None
        return self._wait_until

    def tree_edges(self) -> list[tuple[Cell, Cell]]:
        """Own tree edges, each once (to the east or south neighbour)."""
        return [(cell, neighbour(cell, side)) for cell, bits in self.edges.items()
                for side in (2, 3) if bits >> side & 1]

    # ---- coroutine plumbing ----

    def _ready(self) -> bool:
        """Whether what the generator waits for has come (a machine that only heard, not)."""
        wait = self._wait
        if wait == _ANSWER:
            return self._answer is not None or not self._started
        if wait == _UNTIL:
            return self.now >= self._wait_until
        return wait == _WAKE and (self.now >= self._wait_until or self.know.changed)

    def _advance(self) -> None:
        """Resume the generator until it waits for something that has not come yet."""
        send = self._gen.send
        value: object = None
        if not self._started:
            self._started = True
        elif self._wait == _ANSWER:
            value, self._answer = self._answer, None
        while True:
            try:
                kind, arg = send(value)
            except StopIteration:
                self._wait = _FINISHED
                return
            self._wait = kind
            if kind == _ANSWER:
                self.asked = arg  # type: ignore[assignment]
                self.outbox.append(arg)  # type: ignore[arg-type]
                value = self._answer
                if value is None:
                    return
                self._answer = None
            else:
                until = self._wait_until = float(arg)  # type: ignore[arg-type]
                if self.now < until and (kind == _UNTIL or not self.know.changed):
                    return
                value = None

    def send(self, message: Message) -> None:
        self.outbox.append(Broadcast(message))

    # ---- Alg. 1 and the top level of Alg. 2 ----

    def _run(self) -> Flow:
        if self.config.start != (float(self.home[0]), float(self.home[1])):
            yield from self.move_to(self.home)  # Alg. 1 lines 4-6: snap to a centre
        root = cell_of(self.home)
        self._take(root)
        self.know.starts[self.me] = self.home
        self.send(StartMsg(self.me, self.home))
        while not self.know.all_started():
            self.know.changed = False
            yield (_WAKE, self.now + 1)
        yield from self.cover(root)
        yield from watch(self)
        return None

    def cover(self, root: Cell) -> Flow:
        """The DFS of Alg. 2 as the walk around the growing tree, back to ``root``.

        Standing on a sub-cell means deciding the side it faces (lines 2-17); a side with a
        tree edge is crossed (into a child, or back to the parent: lines 18-20). The walk
        ends on re-entering ``root`` at a sub-cell whose side is already decided.
        """
        # walk.cell_of / side_of / successor inlined: this loop runs once per move
        decided, edges = self.decided, self.edges
        mine, obstacle = self.mine, self.know.obstacle
        r, c = self.pos
        while True:
            cell = (r >> 1, c >> 1)
            side = SIDE_AT[(r & 1) << 1 | (c & 1)]
            bits = decided.get(cell, 0)
            if not bits >> side & 1:
                dr, dc = DELTA[side]
                other = (cell[0] + dr, cell[1] + dc)
                if other in mine or other in obstacle:
                    decided[cell] = bits | 1 << side  # _decide's first exit, without a frame
                else:
                    yield from self.decide(cell, side)
                    if self.pos != (r, c):
                        r, c = self.pos  # it entered the cell it grew into to look (inside.py)
                        continue
            go = side if edges.get(cell, 0) >> side & 1 else (side + 1) & 3
            dr, dc = DELTA[go]
            nxt = (r + dr, c + dc)
            result = yield (_ANSWER, Move(nxt))
            if result.__class__ is MoveResult and result.ok:
                self._heading = go
                self.pos = nxt
                self.moves += 1
            else:
                self.bumps += 1
                reached, over = yield from reach(self, nxt, root)
                if over:
                    return None
                nxt = reached
            r, c = nxt
            if ((r >> 1, c >> 1) == root
                    and decided.get(root, 0) >> SIDE_AT[(r & 1) << 1 | (c & 1)] & 1):
                return None

    def decide(self, cell: Cell, side: int) -> Flow:
        """Lines 3-17 for the neighbour on ``side``: skip, connect, or grow into it."""
        self.decided[cell] = self.decided.get(cell, 0) | 1 << side
        dr, dc = DELTA[side]
        other = (cell[0] + dr, cell[1] + dc)
        know = self.know
        if other in self.mine or other in know.obstacle or cell in self.ceded:
            return None  # a ceded cell's neighbours are its new owner's to decide
        if other in know.owners:
            holder = know.live_owner(other)
            if holder is not None:
                alive = yield from self.ask_alive(holder)
                if alive:
                    self._connect(holder, cell, other)
                    return None
            for robot in know.dead_owners(other):
                self.release(robot)  # lines 12-14: a dead robot's cell is empty again
        # standing on the sub-cell facing the cell, the robot can enter its near half to see
        # the rest (inside.py); elsewhere (passage.py decides from beside) it cannot
        enter = self.pos == sub_facing(cell, side)
        status = yield from self._sense(cell, side, other, enter=enter)
        if status is CellStatus.OBSTACLE:
            return None
        if status is CellStatus.ROBOT:
            leader = know.claims.leader(other, know.dead, self.now)
            if leader is not None and leader != self.me:
                self._connect(leader, cell, other, unsure=True)
            return None  # otherwise a dead body: nobody can cover this cell
        won = yield from self._claim(cell, other)
        if won and (know.was_owned(other) or know.claims.claimed_by_any(other, know.dead)):
            # its owner, or a rival that won it and died before its tree edge came, may have
            # died inside it while we waited: look again before entering
            status = yield from self._sense(cell, side, other, again=True, enter=enter)
            won = status is CellStatus.FREE or status is CellStatus.HALF
        if won:
            self._grow(cell, side)
            if status is CellStatus.HALF:
                yield from enter_to_look(self, cell, side)
        return None

    # ---- claims, tree edges, connections ----

    def _claim(self, cell: Cell, target: Cell) -> Flow:
        know = self.know
        covered = len(self.mine)
        know.claims.hear(target, self.me, covered, self.now)
        self.outbox.append(Broadcast(ClaimMsg(self.me, target, covered)))
        index = self.broadcasts + sum(1 for r in self.outbox if r.__class__ is Broadcast)
        yield (_UNTIL, self.now + self.config.claim_wait)
        if self.config.await_acks:
            yield from self._await_acks(index)
        outcome = know.claims.decide(target, self.me, know.live_owner(target), know.dead,
                                     self.now)
        if cell in self.ceded:
            return False  # handed over in a conflict while waiting: not ours to grow from
        if not outcome.won and outcome.winner is not None:
            self._connect(outcome.winner, cell, target, unsure=know.live_owner(target) is None)
        return outcome.won

    def _await_acks(self, index: int) -> Flow:
        """Wait until every live peer acknowledged broadcast ``index`` (this claim) and all it
        said before is known (docs/ormstc.md, "Claims under message loss")."""
        know = self.know
        if not know.acked_by_all(index):
            self.ack_waits += 1
            while not know.acked_by_all(index):
                know.awaiting, know.changed = True, False
                # an acknowledgement wakes the machine; the time is only a fallback (an
                # agent's window may be 0: the acknowledgements alone make a claim safe)
                yield (_WAKE, self.now + (self.config.claim_wait or self.config.watch_interval))
            know.awaiting = False
        return None

    def _grow(self, cell: Cell, side: int) -> None:
        dr, dc = DELTA[side]
        child = (cell[0] + dr, cell[1] + dc)
        self._take(child)
        self.parent[child] = cell
        edges = self.edges
        edges[cell] = edges.get(cell, 0) | 1 << side
        back = (side + 2) & 3
        edges[child] = edges.get(child, 0) | 1 << back
        self.decided[child] = self.decided.get(child, 0) | 1 << back
        self.know.claims.pending.pop(child, None)  # claims.settle
        self.outbox.append(Broadcast(TreeEdgeMsg(self.me, cell, child)))

    def _take(self, cell: Cell) -> None:
        self.mine.add(cell)
        self.know.own(cell, self.me)

    def _connect(self, holder: int, mine: Cell, theirs: Cell, unsure: bool = False) -> None:
        """Record a connection; ``unsure``: the holder only claimed, its edge is not heard."""
        retry_at = self.now + self.know.claim_ttl if unsure else None
        self.connections.record(holder, (mine, theirs), retry_at)
        if self.config.announce_connections:
            self.send(ConnectionMsg(self.me, holder, mine, theirs))

    def release(self, robot: int) -> None:
        know = self.know
        know.mark_dead(robot)
        if robot not in know.released:
            know.released.add(robot)
            self.freed.append(robot)
            self.send(DeadRobotMsg(self.me, robot))

    def has_edge(self, cell: Cell, side: int) -> bool:
        return bool(self.edges.get(cell, 0) >> side & 1)

    # ---- sensing, moving, liveness ----

    def _sense(self, cell: Cell, side: int, target: Cell, again: bool = False,
               enter: bool = False) -> Flow:
        if not again and target not in self.know.owners and target in self.know.free:
            return CellStatus.FREE  # static and never owned: nobody can have died there
        cells, turn = self._look(cell, side, target)
        result = yield (_ANSWER, Sense(cells, turn, enter))
        return self.sensed(target, result)

    def _look(self, cell: Cell, side: int, target: Cell) -> tuple[tuple[Cell, ...], bool]:
        """The cells to sense for ``target`` and whether the robot must turn to see it."""
        if self.config.sense_mode is SenseMode.SINGLE:
            turn = self._heading != side
            if turn:
                self.sense_turns += 2  # turn towards the cell and back (paper's 3 steps)
            return (target,), turn
        return (target, *self.know.unknown_around(cell, target, self.mine)), False

    def sensed(self, target: Cell, result: object) -> CellStatus:
        """``target``'s status in a Sense's answer (OBSTACLE when missing); every status
        answered is noted in the knowledge."""
        statuses = result.statuses if isinstance(result, SenseResult) else ()
        status = CellStatus.OBSTACLE
        note = self.know.note_sensed
        for sensed, value in statuses:
            note(sensed, value)
            if sensed == target:
                status = value
        return status

    def move_to(self, to: SubCell) -> Flow:
        while True:
            result = yield (_ANSWER, Move(to))
            if isinstance(result, MoveResult) and result.ok:
                self.moved(to)
                return None
            self.bumps += 1
            yield (_UNTIL, self.now + self.backoff())

    def moved(self, to: SubCell) -> None:
        self._heading = _HEADING.get((to[0] - self.pos[0], to[1] - self.pos[1]))
        self.pos = to
        self.moves += 1

    def backoff(self) -> float:
        # paper's bump heuristic: back off for a random short time, then try again
        return self.config.bump_backoff * (1.0 + self._rng.random())

    def ask_alive(self, robot: int) -> Flow:
        if robot in self.know.dead:
            return False
        result = yield (_ANSWER, IsAlive(robot))
        alive = isinstance(result, AliveResult) and result.alive
        if not alive:
            self.know.mark_dead(robot)
        return alive
