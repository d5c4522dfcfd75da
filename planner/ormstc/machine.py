"""ORMSTC (Hazon, Mieli & Kaminka 2006, Alg. 1 and 2) as a sans-I/O state machine.

Drive it with ``requests = machine.step(events)``: pass every event that arrived (answers to
the previous requests, peer messages, peer deaths, and clock ticks) and carry out the returned
requests. At most one of Sense / Move / IsAlive is outstanding at a time and must be answered
(SenseResult / MoveResult / AliveResult) in a later ``step``; Broadcast and Done need no
answer. Waits (claims, bump back-off, watching peers) only end on a Tick, so a driver must
tick the machine while it has nothing else to say. Nothing assumes lockstep delivery: peer
messages may come late and in any order across senders (FIFO per sender is assumed).

The algorithm is written as one generator (the recursive DFS of Alg. 2 unrolled into the STC
walk around the growing tree); ``step`` resumes it when what it waits for has arrived.
"""

from __future__ import annotations

import math
import random
from collections.abc import Generator, Iterable

from planner.ormstc.connections import Connections, Link
from planner.ormstc.knowledge import Knowledge
from planner.ormstc.types import (
    AliveResult,
    Broadcast,
    Cell,
    CellStatus,
    ClaimMsg,
    CompletionMsg,
    ConnectionMsg,
    DeadRobotMsg,
    Done,
    Event,
    IsAlive,
    MachineConfig,
    Message,
    Move,
    MoveResult,
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
    WithdrawalMsg,
)
from planner.ormstc.walk import (
    DELTA,
    arrival_side,
    cell_of,
    neighbour,
    predecessor,
    side_of,
    side_towards,
    sub_facing,
    successor,
    walk_index,
)

_ANSWER, _UNTIL, _WAKE, _FINISHED = 0, 1, 2, 3
Action = tuple[int, object]
Flow = Generator[Action, object, object]


class OrmstcMachine:
    """One robot's ORMSTC controller. Public state is read-only for drivers and tests."""

    def __init__(self, config: MachineConfig) -> None:
        self.config = config
        self.me = config.robot
        # a claim heard at t is decided by t + wait and its edge heard by t + wait + D, with
        # D <= (wait + 1) / 2; 2 wait + 1 is past both
        self.know = Knowledge(config.robot, config.team, config.priority,
                              claim_ttl=2 * config.claim_wait + 1)
        self.now = 0.0
        start = config.start
        self.home: SubCell = (round(start[0]), round(start[1]))
        self.pos: SubCell = self.home
        self.mine: set[Cell] = set()
        self.edges: dict[Cell, int] = {}  # bit per side: own tree edge on that side
        self.decided: dict[Cell, int] = {}  # bit per side: the DFS has dealt with it
        self.connections = Connections()
        self.moves = 0
        self.bumps = 0
        self.sense_turns = 0
        self.takeovers = 0
        self.finished = False  # announced completion and not withdrawn
        self.idle = False  # finished with nothing to take over; waiting for peers
        self.done_sent = False
        self._heading: int | None = None
        self._rng = random.Random(config.seed * 1_000_003 + config.robot)
        self._out: list[Request] = []
        self._gen: Flow = self._run()
        self._wait = _ANSWER
        self._wait_until = 0.0
        self._answer: object = None
        self._started = False

    # ---- driver API ----

    def step(self, events: Iterable[Event] = ()) -> list[Request]:
        """Feed what happened; get what to do next. Put a Tick before the messages it dates."""
        know = self.know
        for event in events:
            kind = type(event)
            if kind is PeerMessage:
                if event.sender != self.me:  # type: ignore[union-attr]
                    know.hear(event.message)  # type: ignore[union-attr]
            elif kind is Tick:
                if event.now > self.now:  # type: ignore[union-attr]
                    self.now = know.now = event.now  # type: ignore[union-attr]
            elif kind is PeerDied:
                know.mark_dead(event.robot)  # type: ignore[union-attr]
            else:
                self._answer = event
        self._advance()
        out, self._out = self._out, []
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

    def _advance(self) -> None:
        if not self._started:
            self._started = True
            self._resume(None)
        while True:
            if self._wait == _ANSWER:
                if self._answer is None:
                    return
                value, self._answer = self._answer, None
            elif self._wait == _UNTIL:
                if self.now < self._wait_until:
                    return
                value = None
            elif self._wait == _WAKE:
                if self.now < self._wait_until and not self.know.changed:
                    return
                value = None
            else:
                return
            self._resume(value)

    def _resume(self, value: object) -> None:
        try:
            kind, arg = self._gen.send(value)
        except StopIteration:
            self._wait = _FINISHED
            return
        self._wait = kind
        if kind == _ANSWER:
            self._out.append(arg)  # type: ignore[arg-type]
        else:
            self._wait_until = float(arg)  # type: ignore[arg-type]

    def _send(self, message: Message) -> None:
        self._out.append(Broadcast(message))

    # ---- Alg. 1 and the top level of Alg. 2 ----

    def _run(self) -> Flow:
        if self.config.start != (float(self.home[0]), float(self.home[1])):
            yield from self._move_to(self.home)  # Alg. 1 lines 4-6: snap to a centre
        root = cell_of(self.home)
        self._take(root)
        self.know.starts[self.me] = self.home
        self._send(StartMsg(self.me, self.home))
        while not self.know.all_started():
            self.know.changed = False
            yield (_WAKE, self.now + 1)
        yield from self._cover(root)
        yield from self._watch()
        return None

    def _cover(self, root: Cell) -> Flow:
        """The DFS of Alg. 2 as the walk around the growing tree, back to ``root``.

        Standing on a sub-cell means deciding the side it faces (lines 2-17); a side with a
        tree edge is crossed (into a child, or back to the parent: lines 18-20). The walk
        ends on re-entering ``root`` at a sub-cell whose side is already decided.
        """
        pos = self.pos
        while True:
            cell = cell_of(pos)
            side = side_of(pos)
            if not self.decided.get(cell, 0) >> side & 1:
                yield from self._decide(cell, side)
            nxt = successor(pos, self._has_edge)
            result = yield (_ANSWER, Move(nxt))
            if result.__class__ is MoveResult and result.ok:
                self._moved(nxt)
            else:
                self.bumps += 1
                yield (_UNTIL, self.now + self._backoff())
                yield from self._move_to(nxt)
            pos = nxt
            if cell_of(pos) == root and self.decided.get(root, 0) >> side_of(pos) & 1:
                return None

    def _decide(self, cell: Cell, side: int) -> Flow:
        """Lines 3-17 for the neighbour on ``side``: skip, connect, or grow into it."""
        self._mark_decided(cell, side)
        other = neighbour(cell, side)
        know = self.know
        if other in self.mine or other in know.obstacle:
            return None
        holder = know.live_owner(other)
        if holder is not None:
            alive = yield from self._ask_alive(holder)
            if alive:
                self._connect(holder, cell, other)
                return None
        for robot in know.dead_owners(other):
            self._release(robot)  # lines 12-14: a dead robot's cell is empty again
        status = yield from self._sense(cell, side, other)
        if status is CellStatus.OBSTACLE:
            return None
        if status is CellStatus.ROBOT:
            leader = know.claims.leader(other, know.dead, self.now)
            if leader is not None and leader != self.me:
                self._connect(leader, cell, other, unsure=True)
            return None  # otherwise a dead body: nobody can cover this cell
        won = yield from self._claim(cell, other)
        if won and know.was_owned(other):
            # its owner may have died inside it while we waited: look again before entering
            status = yield from self._sense(cell, side, other)
            won = status is CellStatus.FREE
        if won:
            self._grow(cell, side)
        return None

    # ---- claims, tree edges, connections ----

    def _claim(self, cell: Cell, target: Cell) -> Flow:
        know = self.know
        know.claims.hear(target, self.me, len(self.mine), self.now)
        self._send(ClaimMsg(self.me, target, len(self.mine)))
        yield (_UNTIL, self.now + self.config.claim_wait)
        outcome = know.claims.decide(target, self.me, know.live_owner(target), know.dead,
                                     self.now)
        if not outcome.won and outcome.winner is not None:
            self._connect(outcome.winner, cell, target, unsure=know.live_owner(target) is None)
        return outcome.won

    def _grow(self, cell: Cell, side: int) -> None:
        child = neighbour(cell, side)
        self._take(child)
        self.edges[cell] = self.edges.get(cell, 0) | 1 << side
        back = (side + 2) % 4
        self.edges[child] = self.edges.get(child, 0) | 1 << back
        self._mark_decided(child, back)
        self.know.claims.settle(child)
        self._send(TreeEdgeMsg(self.me, cell, child))

    def _take(self, cell: Cell) -> None:
        self.mine.add(cell)
        self.know.own(cell, self.me)

    def _connect(self, holder: int, mine: Cell, theirs: Cell, unsure: bool = False) -> None:
        """Record a connection; ``unsure``: the holder only claimed, its edge is not heard."""
        retry_at = self.now + self.know.claim_ttl if unsure else None
        self.connections.record(holder, (mine, theirs), retry_at)
        if self.config.announce_connections:
            self._send(ConnectionMsg(self.me, holder, mine, theirs))

    def _release(self, robot: int) -> None:
        know = self.know
        know.mark_dead(robot)
        if robot not in know.released:
            know.released.add(robot)
            self._send(DeadRobotMsg(self.me, robot))

    def _mark_decided(self, cell: Cell, side: int) -> None:
        self.decided[cell] = self.decided.get(cell, 0) | 1 << side

    def _has_edge(self, cell: Cell, side: int) -> bool:
        return bool(self.edges.get(cell, 0) >> side & 1)

    # ---- sensing, moving, liveness ----

    def _sense(self, cell: Cell, side: int, target: Cell) -> Flow:
        know = self.know
        fresh = know.was_owned(target)  # a robot may have died there since
        if not fresh and target in know.free:
            return CellStatus.FREE
        if self.config.sense_mode is SenseMode.SINGLE:
            cells: tuple[Cell, ...] = (target,)
            turn = self._heading != side
            if turn:
                self.sense_turns += 2  # turn towards the cell and back (paper's 3 steps)
        else:
            cells = (target, *know.unknown_around(cell, target, self.mine))
            turn = False
        result = yield (_ANSWER, Sense(cells, turn))
        status = CellStatus.OBSTACLE
        if isinstance(result, SenseResult):
            for sensed, value in result.statuses:
                know.note_sensed(sensed, value)
                if sensed == target:
                    status = value
        return status

    def _move_to(self, to: SubCell) -> Flow:
        while True:
            result = yield (_ANSWER, Move(to))
            if isinstance(result, MoveResult) and result.ok:
                self._moved(to)
                return None
            self.bumps += 1
            yield (_UNTIL, self.now + self._backoff())

    def _moved(self, to: SubCell) -> None:
        delta = (to[0] - self.pos[0], to[1] - self.pos[1])
        self._heading = DELTA.index(delta) if delta in DELTA else None
        self.pos = to
        self.moves += 1

    def _backoff(self) -> float:
        # paper's bump heuristic: back off for a random short time, then try again
        return self.config.bump_backoff * (1.0 + self._rng.random())

    def _ask_alive(self, robot: int) -> Flow:
        if robot in self.know.dead:
            return False
        result = yield (_ANSWER, IsAlive(robot))
        alive = isinstance(result, AliveResult) and result.alive
        if not alive:
            self.know.mark_dead(robot)
        return alive

    # ---- lines 21-36: completion, watching, takeover ----

    def _watch(self) -> Flow:
        know, table = self.know, self.connections
        next_poll = self.now
        while True:
            know.changed = False
            targets, retry_at = table.targets(know, self.mine, self.now, self._mission_over())
            if not targets:
                if not self.finished:
                    self.finished = True
                    know.completed.add(self.me)
                    self._send(CompletionMsg(self.me, len(self.mine)))
                self.idle = retry_at == math.inf
                if self.idle and self._mission_over() and not self.done_sent:
                    self.done_sent = True
                    self._out.append(Done(self.now))
                if self.now >= next_poll:
                    next_poll = self.now + self.config.watch_interval
                    for robot in sorted(table.holders() - know.dead):
                        yield from self._ask_alive(robot)
                    continue
                yield (_WAKE, min(next_poll, retry_at))
                continue
            self.idle = False
            self.done_sent = False
            if self.finished:
                self.finished = False
                know.completed.discard(self.me)
                self._send(WithdrawalMsg(self.me, table.links[targets[0]]))
            for link in targets:
                if table.links[link] in know.dead:
                    self._release(table.links[link])
            yield from self._take_over(self._closest(targets))

    def _mission_over(self) -> bool:
        return self.finished and self.know.peers_settled()

    def _closest(self, targets: list[Link]) -> Link:
        """The target reached soonest walking either way round the own tree (line 29)."""
        n = 4 * len(self.mine)
        index = walk_index(self.pos, self._has_edge, n)

        def distance(link: Link) -> int:
            ahead = index.get(sub_facing(link[0], side_towards(*link)), 0)
            return min(ahead, n - ahead)

        return min(targets, key=distance)

    def _take_over(self, link: Link) -> Flow:
        """Lines 30-36: walk to my side of the connection and grow into the freed cell."""
        mine, theirs = link
        side = side_towards(mine, theirs)
        yield from self._walk_to(sub_facing(mine, side))
        self.connections.drop(link)
        self.decided[mine] = self.decided.get(mine, 0) & ~(1 << side)
        yield from self._decide(mine, side)
        if self._has_edge(mine, side):
            self.takeovers += 1
            yield from self._cover(mine)
        return None

    def _walk_to(self, target: SubCell) -> Flow:
        n = 4 * len(self.mine)
        ahead = walk_index(self.pos, self._has_edge, n).get(target, 0)
        step = successor if ahead <= n - ahead else predecessor
        while self.pos != target:
            yield from self._move_to(step(self.pos, self._has_edge))
        return None


def initial_arrival(start: SubCell) -> Cell:
    """Fig. 1: the cell W the robot is deemed to have arrived from, given its start."""
    return neighbour(cell_of(start), arrival_side(start))
