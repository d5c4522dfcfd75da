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
    Sense,
    SenseMode,
    SenseResult,
    StartMsg,
    SubCell,
    Tick,
    TreeEdgeMsg,
)
from planner.types import BoolArray, IntArray, OccupancyGrid


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
            announce_connections=cfg.announce_connections)) for i, s in enumerate(self.starts)]
        self._rng = random.Random(cfg.seed)
        h, w = world.shape
        self._free = world.free.tolist()
        self._h, self._w = h, w
        self.visits = np.zeros((h, w), dtype=np.int64)
        self.first_robot = np.full((h, w), -1, dtype=np.int64)
        self.first_step = np.full((h, w), -1, dtype=np.int64)
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
        self._queue: dict[int, list[tuple[int, Event]]] = defaultdict(list)
        self._fifo: dict[tuple[int, int], int] = {}
        self._inbox: list[list[Event]] = [[] for _ in self.starts]
        self._in_flight = 0
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
        k = len(self.starts)
        limit = self.config.max_steps or 60 * self.world.free.size + 1000
        failures: dict[int, list[int]] = defaultdict(list)
        for robot, at in self.config.failures:
            failures[at].append(robot)
        step = 0
        finished = False
        while step < limit:
            for robot in failures.get(step, ()):
                self._kill(robot, step)
            queued = self._queue.pop(step, ())
            for robot, event in queued:
                self._in_flight -= 1
                if self.alive[robot]:
                    self._inbox[robot].append(event)
            tick = Tick(float(step))
            for robot in range(k):
                if self.alive[robot]:
                    self._act(robot, step, tick)
            if self._in_flight == 0 and all(
                    m.idle for m, a in zip(self.machines, self.alive, strict=True) if a):
                finished = True
                break
            step += 1
        return self._result(step, finished)

    def _act(self, robot: int, step: int, tick: Tick) -> None:
        machine = self.machines[robot]
        events = self._inbox[robot]
        if not events:
            wake = machine.wake_time()
            if wake is not None and wake > step:
                return  # nothing new and nothing due: stepping would change nothing
        self._inbox[robot] = []
        events.insert(0, tick)
        requests = machine.step(events)
        while requests:
            answer: Event | None = None
            for request in requests:
                kind = type(request)
                if kind is Broadcast:
                    self._broadcast(robot, step, request)  # type: ignore[arg-type]
                elif kind is Move:
                    ok = self._move(robot, request.to, step)  # type: ignore[union-attr]
                    self._inbox[robot].append(MoveResult(ok))
                elif kind is Sense:
                    answer = SenseResult(tuple((c, self._status(c))
                                               for c in request.cells))  # type: ignore[union-attr]
                elif kind is IsAlive:
                    answer = AliveResult(request.robot,  # type: ignore[union-attr]
                                         self.alive[request.robot])  # type: ignore[union-attr]
                elif kind is Done:
                    self.done_steps[robot] = step
            requests = machine.step((answer,)) if answer is not None else []

    # ---- ground truth ----

    def _status(self, cell: Cell) -> CellStatus:
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

    def _move(self, robot: int, to: SubCell, step: int) -> bool:
        here = self.pos[robot]
        if abs(to[0] - here[0]) + abs(to[1] - here[1]) != 1:
            raise AssertionError(f"robot {robot} asked to jump from {here} to {to}")
        r, c = to
        if not (0 <= r < self._h and 0 <= c < self._w) or not self._free[r][c]:
            raise AssertionError(f"robot {robot} drove into an obstacle at {to}")
        if to in self.body:
            return False
        del self.body[here]
        self.body[to] = robot
        self.pos[robot] = to
        self.paths[robot].append(to)
        self._visit(robot, to, step)
        return True

    def _visit(self, robot: int, sub: SubCell, step: int) -> None:
        if self.visits[sub] == 0:
            self.first_robot[sub] = robot
            self.first_step[sub] = step
        self.visits[sub] += 1

    def _broadcast(self, sender: int, step: int, request: Broadcast) -> None:
        message = request.message
        if isinstance(message, TreeEdgeMsg):
            self._own(sender, message.child, step)
            self.trees[sender].append((message.parent, message.child))
        elif isinstance(message, StartMsg):
            self._own(sender, (message.sub[0] // 2, message.sub[1] // 2), step)
        elif isinstance(message, ClaimMsg):
            self.claims.append((step, sender, message.cell))
        lo, hi = self.config.delay
        event = PeerMessage(sender, message)
        queue, fifo, alive = self._queue, self._fifo, self.alive
        if lo == hi:  # equal delays keep every sender's messages in order by themselves
            bucket = queue[step + max(lo, 1)]
            for peer in range(len(alive)):
                if peer != sender and alive[peer]:
                    bucket.append((peer, event))
                    self._in_flight += 1
            return
        for peer in range(len(alive)):
            if peer == sender or not alive[peer]:
                continue
            due = max(step + max(self._rng.randint(lo, hi), 1), fifo.get((sender, peer), 0))
            fifo[(sender, peer)] = due
            queue[due].append((peer, event))
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
        self.deaths[robot] = step
        due = step + max(self.config.detect_delay, 1)
        for peer in range(len(self.starts)):
            if peer != robot:
                self._queue[due].append((peer, PeerDied(robot)))
                self._in_flight += 1

    def _result(self, step: int, finished: bool) -> SimResult:
        return SimResult(
            world=self.world, starts=self.starts, steps=step, finished=finished,
            paths=tuple(tuple(p) for p in self.paths), visits=self.visits,
            first_robot=self.first_robot, first_step=self.first_step,
            trees=tuple(tuple(t) for t in self.trees), claims=tuple(self.claims),
            conflicts=tuple(self.conflicts), deaths=dict(self.deaths),
            done_steps=dict(self.done_steps),
            sense_turns=tuple(m.sense_turns for m in self.machines),
            bumps=tuple(m.bumps for m in self.machines), kinematics=self.config.kinematics)


def simulate(world: OccupancyGrid, starts: Sequence[SubCell],
             config: SimConfig | None = None) -> SimResult:
    """Run ORMSTC on ``world`` from ``starts`` and return the ground truth."""
    return LockstepSim(world, starts, config).run()
