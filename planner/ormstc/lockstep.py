"""In-process lockstep simulator: k ORMSTC machines on one world grid, no Zenoh, no clock.

Every step each live robot, in id order, receives the messages due that step and a Tick,
then acts: its sense and liveness questions are answered at once from the ground truth, one
move per step is executed (a body never enters an occupied sub-cell: it bumps instead), and
its broadcasts are delivered to every peer after a delay drawn from the seed (kept FIFO per
sender and receiver). Failures kill a robot at a chosen step; its body stays where it stopped
and the others' failure detectors report it ``detect_delay`` steps later. The run ends when
every live robot is idle (finished, nothing left to take over) and no message is in flight.
"""

from __future__ import annotations

import gc
import random
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from planner.errors import RobotPlacementError
from planner.metrics import RV400, KinematicParams, path_time
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import (
    AliveResult,
    Broadcast,
    Cell,
    CellStatus,
    ClaimMsg,
    Done,
    Event,
    IsAlive,
    MachineConfig,
    Move,
    MoveResult,
    PeerDied,
    PeerMessage,
    Priority,
    Request,
    RetractionMsg,
    Sense,
    SenseMode,
    SenseResult,
    StartMsg,
    SubCell,
    Tick,
    TreeEdgeMsg,
)
from planner.types import BoolArray, IntArray, OccupancyGrid

_MOVED, _BUMPED = MoveResult(True), MoveResult(False)  # frozen: shared by every answer
_STEPS = frozenset({(-1, 0), (1, 0), (0, -1), (0, 1)})


@dataclass(frozen=True)
class SimConfig:
    """Run parameters. ``delay`` is (min, max) message delay in steps, drawn per message."""

    sense_mode: SenseMode = SenseMode.ALL
    priority: Priority = Priority.ID
    delay: tuple[int, int] = (1, 1)
    detect_delay: int = 1
    failures: tuple[tuple[int, int], ...] = ()  # (robot, step)
    seed: int = 0
    max_steps: int | None = None
    claim_wait: float | None = None  # default: 2 x max delay - 1, the tight safe bound
    watch_interval: float = 10.0
    announce_connections: bool = False
    kinematics: KinematicParams = RV400
    # a thin sonar's answers where the machine allows them: HALF for a cell whose half the
    # walk enters is free (the rest unseen), the cell a robot stands in judged from inside
    # (planner/ormstc/inside.py); exact whole cells otherwise, as the paper's model
    half_sense: bool = False


@dataclass(frozen=True, eq=False)
class SimResult:
    """Ground truth of one run."""

    world: OccupancyGrid
    starts: tuple[SubCell, ...]
    steps: int
    finished: bool  # every live robot went idle before max_steps
    paths: tuple[tuple[SubCell, ...], ...]
    visits: IntArray  # times each sub-cell was entered (starts count once)
    first_robot: IntArray  # robot that first covered each sub-cell, -1 if none
    first_step: IntArray  # step of that first visit, -1 if none
    trees: tuple[tuple[tuple[Cell, Cell], ...], ...]
    claims: tuple[tuple[int, int, Cell], ...]  # (step, robot, cell)
    conflicts: tuple[tuple[int, Cell, int, int], ...]  # (step, cell, new owner, live owner)
    deaths: dict[int, int]  # robot -> step it died
    done_steps: dict[int, int]  # robot -> last step it reported Done
    sense_turns: tuple[int, ...]
    bumps: tuple[int, ...]
    kinematics: KinematicParams = field(default=RV400)

    @property
    def moves(self) -> tuple[int, ...]:
        return tuple(len(p) - 1 for p in self.paths)

    @property
    def makespan(self) -> int:
        """Coverage time in moves: the most moves any robot made."""
        return max(self.moves, default=0)

    def seconds(self) -> tuple[float, ...]:
        """Per robot: eq. 8 driving time plus the sideways sensing turns."""
        quarter = self.kinematics.quarter_turn_time
        return tuple(path_time(p, self.kinematics) + t * quarter
                     for p, t in zip(self.paths, self.sense_turns, strict=True))

    @property
    def covered(self) -> BoolArray:
        return self.visits > 0


class LockstepSim:
    """k machines, one world. Build, then ``run()`` once."""

    def __init__(self, world: OccupancyGrid, starts: Sequence[SubCell],
                 config: SimConfig | None = None) -> None:
        self.world = world
        self.config = config or SimConfig()
        self.starts = tuple((int(r), int(c)) for r, c in starts)
        self._validate()
        cfg = self.config
        wait = (cfg.claim_wait if cfg.claim_wait is not None
                else max(1.0, 2.0 * max(cfg.delay[1], 1) - 1.0))
        self.machines = [OrmstcMachine(MachineConfig(
            robot=i, team=len(self.starts), start=(float(s[0]), float(s[1])),
            claim_wait=wait, sense_mode=cfg.sense_mode, priority=cfg.priority,
            watch_interval=cfg.watch_interval, seed=cfg.seed,
            announce_connections=cfg.announce_connections))
            for i, s in enumerate(self.starts)]
        self._rng = random.Random(cfg.seed)
        h, w = world.shape
        self._free = world.free.tolist()
        self._h, self._w = h, w
        # plain lists while running (numpy scalar indexing is slow); arrays in the result
        self._visits = [0] * (h * w)
        self._first_robot = [-1] * (h * w)
        self._first_step = [-1] * (h * w)
        self.body: dict[SubCell, int] = {s: i for i, s in enumerate(self.starts)}
        self.pos = list(self.starts)
        self.paths: list[list[SubCell]] = [[s] for s in self.starts]
        self.alive = [True] * len(self.starts)
        self.deaths: dict[int, int] = {}
        self.done_steps: dict[int, int] = {}
        self.trees: list[list[tuple[Cell, Cell]]] = [[] for _ in self.starts]
        self.claims: list[tuple[int, int, Cell]] = []
        self.conflicts: list[tuple[int, Cell, int, int]] = []
        self.owner: dict[Cell, list[int]] = defaultdict(list)
        # due step -> events in the order sent. Equal delays: one list every robot gets (a
        # machine ignores its own broadcasts and its own PeerDied, so one entry per broadcast
        # serves all recipients). Random delays: one list per recipient.
        k = len(self.starts)
        self._per_robot = self.config.delay[0] != self.config.delay[1]
        self._queue: dict[int, list[Event]] = defaultdict(list)
        self._queue_to: dict[int, list[list[Event]]] = defaultdict(
            lambda: [[] for _ in range(k)])
        self._due_count: dict[int, int] = defaultdict(int)  # recipient deliveries per step
        self._fifo: dict[tuple[int, int], int] = {}
        self._answer: list[MoveResult | None] = [None] * len(self.starts)  # due next step
        self._in_flight = 0
        self._live = len(self.starts)
        for i, s in enumerate(self.starts):
            self._visit(i, s, 0)

    def _validate(self) -> None:
        h, w = self.world.shape
        cells: dict[Cell, int] = {}
        for i, (r, c) in enumerate(self.starts):
            if not (0 <= r < h and 0 <= c < w) or not self.world.free[r, c]:
                raise RobotPlacementError(f"robot {i} starts at ({r}, {c}), not a free sub-cell")
            cell = (r // 2, c // 2)
            if cell in cells:
                raise RobotPlacementError(
                    f"robots {cells[cell]} and {i} start in the same cell {cell}; ORMSTC needs "
                    "one robot per cell")
            cells[cell] = i

    # ---- the loop ----

    def run(self) -> SimResult:
        # the loop allocates many short-lived containers and makes no reference cycles, so
        # the cyclic collector finds nothing and costs ~15% of a run (docs/ormstc.md,
        # benchmark): pause it for the run and restore it after
        enabled = gc.isenabled()
        gc.disable()
        try:
            return self._loop()
        finally:
            if enabled:
                gc.enable()

    def _loop(self) -> SimResult:
        k = len(self.starts)
        limit = self.config.max_steps or 60 * self.world.free.size + 1000
        failures: dict[int, list[int]] = defaultdict(list)
        for robot, at in self.config.failures:
            failures[at].append(robot)
        machines, alive, answers = self.machines, self.alive, self._answer
        step = 0
        finished = False
        while step < limit:
            for robot in failures.get(step, ()):
                self._kill(robot, step)
            shared = self._queue.pop(step, None)
            addressed = self._queue_to.pop(step, None)
            self._in_flight -= self._due_count.pop(step, 0)
            tick = Tick(float(step))
            for robot in range(k):
                if not alive[robot]:
                    continue
                machine = machines[robot]
                answer = answers[robot]
                events: list[Event] = [tick] if answer is None else [tick, answer]
                if shared:
                    events += shared
                elif addressed:
                    events += addressed[robot]
                if len(events) == 1:
                    wake = machine.wake_time()
                    if wake is not None and wake > step:
                        continue  # nothing new and nothing due: stepping would change nothing
                answers[robot] = None
                requests = machine.step(events)
                if len(requests) == 1 and requests[0].__class__ is Move:  # the usual answer
                    answers[robot] = (_MOVED if self._move(robot, requests[0].to, step)
                                      else _BUMPED)
                elif requests:
                    self._carry_out(robot, step, machine, requests)
            if self._in_flight == 0 and all(
                    m.idle for m, a in zip(machines, alive, strict=True) if a):
                finished = True
                break
            step += 1
        return self._result(step, finished)

    def _carry_out(self, robot: int, step: int, machine: OrmstcMachine,
                   requests: list[Request]) -> None:
        while requests:
            reply: Event | None = None
            for request in requests:
                kind = request.__class__
                if kind is Move:
                    ok = self._move(robot, request.to, step)  # type: ignore[union-attr]
                    self._answer[robot] = _MOVED if ok else _BUMPED
                elif kind is Broadcast:
                    self._broadcast(robot, step, request)  # type: ignore[arg-type]
                elif kind is Sense:  # answered within the step, from the ground truth
                    reply = self._sense(robot, request)  # type: ignore[arg-type]
                elif kind is IsAlive:
                    reply = AliveResult(request.robot,  # type: ignore[union-attr]
                                        self.alive[request.robot])  # type: ignore[union-attr]
                elif kind is Done:
                    self.done_steps[robot] = step
            requests = machine.step((reply,)) if reply is not None else []

    # ---- ground truth ----

    def cell_status(self, cell: Cell) -> CellStatus:
        """Ground truth for a machine's Sense request."""
        r, c = 2 * cell[0], 2 * cell[1]
        if r < 0 or c < 0 or r + 1 >= self._h or c + 1 >= self._w:
            return CellStatus.OBSTACLE
        free = self._free
        if not (free[r][c] and free[r + 1][c] and free[r][c + 1] and free[r + 1][c + 1]):
            return CellStatus.OBSTACLE
        body = self.body
        if (r, c) in body or (r + 1, c) in body or (r, c + 1) in body or (r + 1, c + 1) in body:
            return CellStatus.ROBOT
        return CellStatus.FREE

    def _sense(self, robot: int, request: Sense) -> SenseResult:
        answers = [(c, self.cell_status(c)) for c in request.cells]
        if not self.config.half_sense:
            return SenseResult(tuple(answers))
        here = self.pos[robot]
        target = request.cells[0]
        if target == (here[0] >> 1, here[1] >> 1):  # from inside: its own body aside
            body = self.body.pop(here)
            answers[0] = (target, self.cell_status(target))
            self.body[here] = body
        elif request.enter:
            dr, dc = target[0] - (here[0] >> 1), target[1] - (here[1] >> 1)
            near = ((here[0] + dr, here[1] + dc), (here[0] + 2 * dr, here[1] + 2 * dc))
            if all(0 <= r < self._h and 0 <= c < self._w and self._free[r][c]
                   and (r, c) not in self.body for r, c in near):
                answers[0] = (target, CellStatus.HALF)
        return SenseResult(tuple(answers))

    def is_alive(self, robot: int) -> bool:
        return self.alive[robot]

    def _move(self, robot: int, to: SubCell, step: int) -> bool:
        here = self.pos[robot]
        r, c = to
        if (r - here[0], c - here[1]) not in _STEPS:
            raise AssertionError(f"robot {robot} asked to jump from {here} to {to}")
        if not (0 <= r < self._h and 0 <= c < self._w and self._free[r][c]):
            raise AssertionError(f"robot {robot} drove into an obstacle at {to}")
        body = self.body
        if to in body:
            return False
        del body[here]
        body[to] = robot
        self.pos[robot] = to
        self.paths[robot].append(to)
        at = r * self._w + c  # _visit, inlined: once per move
        if self._visits[at] == 0:
            self._first_robot[at] = robot
            self._first_step[at] = step
        self._visits[at] += 1
        return True

    def _visit(self, robot: int, sub: SubCell, step: int) -> None:
        at = sub[0] * self._w + sub[1]
        if self._visits[at] == 0:
            self._first_robot[at] = robot
            self._first_step[at] = step
        self._visits[at] += 1

    def _broadcast(self, sender: int, step: int, request: Broadcast) -> None:
        message = request.message
        kind = type(message)
        if kind is TreeEdgeMsg:
            self._own(sender, message.child, step)  # type: ignore[union-attr]
            self.trees[sender].append((message.parent, message.child))  # type: ignore[union-attr]
        elif kind is ClaimMsg:
            self.claims.append((step, sender, message.cell))  # type: ignore[union-attr]
        elif kind is StartMsg:
            sub = message.sub  # type: ignore[union-attr]
            self._own(sender, (sub[0] // 2, sub[1] // 2), step)
        elif kind is RetractionMsg:  # a cell given up from inside: no edge into it after all
            self.trees[sender].remove((message.parent, message.child))  # type: ignore[union-attr]
        lo, hi = self.config.delay
        event = PeerMessage(sender, message)  # immutable: one object for every recipient
        alive = self.alive
        if lo == hi:  # equal delays keep every sender's messages in order by themselves
            peers = self._live - 1  # the sender is alive: it is acting
            if peers:
                due = step + max(lo, 1)
                self._queue[due].append(event)
                self._due_count[due] += peers
                self._in_flight += peers
            return
        fifo = self._fifo
        # random.randint(lo, hi) unrolled into the getrandbits draws it makes (the same
        # stream, so the same runs per seed): three Python frames less per recipient
        width = hi - lo + 1
        bits, draw = width.bit_length(), self._rng.getrandbits
        for peer in range(len(alive)):
            if peer == sender or not alive[peer]:
                continue
            r = draw(bits)
            while r >= width:
                r = draw(bits)
            due = max(step + max(lo + r, 1), fifo.get((sender, peer), 0))
            fifo[(sender, peer)] = due
            self._queue_to[due][peer].append(event)
            self._due_count[due] += 1
            self._in_flight += 1

    def _own(self, robot: int, cell: Cell, step: int) -> None:
        holders = self.owner[cell]
        for other in holders:
            if other != robot and self.alive[other]:
                self.conflicts.append((step, cell, robot, other))
        holders.append(robot)

    def _kill(self, robot: int, step: int) -> None:
        if not self.alive[robot]:
            return
        self.alive[robot] = False
        self._live -= 1
        self.deaths[robot] = step
        due = step + max(self.config.detect_delay, 1)
        event = PeerDied(robot)
        if self._per_robot:
            lists = self._queue_to[due]
            for peer in range(len(self.starts)):
                if peer != robot:
                    lists[peer].append(event)
        else:
            self._queue[due].append(event)  # the robot itself ignores it (and is dead)
        self._due_count[due] += len(self.starts) - 1
        self._in_flight += len(self.starts) - 1

    def _result(self, step: int, finished: bool) -> SimResult:
        return SimResult(
            world=self.world, starts=self.starts, steps=step, finished=finished,
            paths=tuple(tuple(p) for p in self.paths), visits=self._grid(self._visits),
            first_robot=self._grid(self._first_robot), first_step=self._grid(self._first_step),
            trees=tuple(tuple(t) for t in self.trees), claims=tuple(self.claims),
            conflicts=tuple(self.conflicts), deaths=dict(self.deaths),
            done_steps=dict(self.done_steps),
            sense_turns=tuple(m.sense_turns for m in self.machines),
            bumps=tuple(m.bumps for m in self.machines), kinematics=self.config.kinematics)

    def _grid(self, values: list[int]) -> IntArray:
        return np.array(values, dtype=np.int64).reshape(self._h, self._w)


def simulate(world: OccupancyGrid, starts: Sequence[SubCell],
             config: SimConfig | None = None) -> SimResult:
    """Run ORMSTC on ``world`` from ``starts`` and return the ground truth."""
    return LockstepSim(world, starts, config).run()
