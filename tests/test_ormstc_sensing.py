"""The ORMSTC driver's thin-sonar sensing on worlds whose obstacles fill only part of a cell.

Oracles: the exact cell status of planner.ormstc.lockstep (a cell is an obstacle if any of its four
sub-cells is blocked or off the map), with the readings cast by simhw's own ``sonar_range``;
and, for whole missions of one robot, the sub-cells the lockstep simulator covers from the
same start. A stand-in body (no processes) answers ``agent.ormstc.body.look``.

``.venv/bin/python tests/test_ormstc_sensing.py`` prints what looking costs on a few worlds
(docs/ormstc.md, "Sensing with a thin sonar").
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agent.ormstc.body import look
from agent.ormstc.sensing import (
    HEADING_DELTA,
    BodyTest,
    SonarMap,
    ahead,
    beside,
    cell_of,
    direction_of,
    direction_to,
    judge,
    near_distance,
    sub_cells,
)
from bus.messages import Sensor
from planner.grid import coarsen
from planner.ormstc.lockstep import SimConfig, simulate
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import (
    AliveResult,
    Cell,
    CellStatus,
    Event,
    IsAlive,
    MachineConfig,
    Move,
    MoveResult,
    Sense,
    SenseMode,
    SubCell,
    Tick,
)
from planner.types import OccupancyGrid
from simhw.sensors import sonar_range
from simhw.types import Heading

NOBODY: BodyTest = lambda _cell: False  # noqa: E731 - only static obstacles in these worlds


def exact(blocked: np.ndarray, cell: Cell) -> CellStatus:
    """The lockstep's rule: any blocked or off-map sub-cell makes the cell an obstacle."""
    h, w = blocked.shape
    hit = any(not (0 <= r < h and 0 <= c < w) or blocked[r, c] for r, c in sub_cells(cell))
    return CellStatus.OBSTACLE if hit else CellStatus.FREE


def neighbours(cell: Cell) -> list[Cell]:
    return [(cell[0] + dr, cell[1] + dc) for dr, dc in HEADING_DELTA]


@dataclass
class StandIn:
    """A body on a blocked mask: simhw's ray cast and bump rule, counting what it did."""

    blocked: np.ndarray
    pose: tuple[int, int, int] | None
    one_sonar: bool = False
    forwards: int = 0
    bumps: int = 0
    turns: int = 0
    readings: int = 0
    commands: int = 0  # sense commands: one per sonar when simhw takes one at a time
    visits: dict[SubCell, int] = field(default_factory=dict)

    async def face(self, heading: int) -> None:
        assert self.pose is not None
        turns = (heading - self.pose[2]) % 4
        self.turns += 2 if turns == 2 else min(turns, 1)
        self.pose = (self.pose[0], self.pose[1], heading)

    async def forward(self) -> bool:
        assert self.pose is not None
        r, c = ahead((self.pose[0], self.pose[1]), self.pose[2], 1)
        h, w = self.blocked.shape
        if not (0 <= r < h and 0 <= c < w) or self.blocked[r, c]:
            self.bumps += 1
            return False
        self.forwards += 1
        self.pose = (r, c, self.pose[2])
        self.visits[(r, c)] = self.visits.get((r, c), 0) + 1
        return True

    async def sonar(self, sensors: tuple[Sensor, ...]) -> dict[str, int | None]:
        assert self.pose is not None
        self.readings += len(sensors)
        self.commands += len(sensors) if self.one_sonar else 1
        pos = (self.pose[0], self.pose[1])
        return {s: sonar_range(self.blocked, pos, Heading(direction_of(self.pose[2], s)), 8)
                for s in sensors}


@st.composite
def worlds(draw: st.DrawFn) -> tuple[np.ndarray, SubCell]:
    """A random mask of single blocked sub-cells and a start sub-cell in a free cell."""
    h, w = 2 * draw(st.integers(3, 6)), 2 * draw(st.integers(3, 6))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    blocked = rng.random((h, w)) < draw(st.floats(0.0, 0.2))
    cell = (draw(st.integers(0, h // 2 - 1)), draw(st.integers(0, w // 2 - 1)))
    for r, c in sub_cells(cell):
        blocked[r, c] = False
    return blocked, draw(st.sampled_from(sub_cells(cell)))


# ---- geometry ----------------------------------------------------------------------------

def test_beside_looks_along_the_other_half() -> None:
    for pos in [(r, c) for r in (4, 5) for c in (6, 7)]:
        for d in range(4):
            side = beside(pos, d)
            assert cell_of(side) == cell_of(pos) and side != pos
            assert abs(side[0] - pos[0]) + abs(side[1] - pos[1]) == 1
            assert near_distance(side, d) == near_distance(pos, d)
            near = near_distance(pos, d)
            seen = {ahead(p, d, near + i) for p in (pos, side) for i in (0, 1)}
            target = (cell_of(pos)[0] + HEADING_DELTA[d][0], cell_of(pos)[1] + HEADING_DELTA[d][1])
            assert seen == set(sub_cells(target))


@settings(max_examples=300, deadline=None)
@given(worlds(), st.integers(0, 3))
def test_one_ray_never_calls_a_cell_free(case: tuple[np.ndarray, SubCell], d: int) -> None:
    """From one ray: a hit in its half is an obstacle, otherwise the cell is not known yet."""
    blocked, pos = case
    sonar = SonarMap()
    reading = sonar_range(blocked, pos, Heading(d), sonar.max_range)
    sonar.record(pos, d, reading, NOBODY)
    target = (cell_of(pos)[0] + HEADING_DELTA[d][0], cell_of(pos)[1] + HEADING_DELTA[d][1])
    status = judge(target, pos, d, reading, sonar, NOBODY)
    near = near_distance(pos, d)
    half = [ahead(pos, d, near + i) for i in (0, 1)]
    h, w = blocked.shape
    half_hit = any(not (0 <= r < h and 0 <= c < w) or blocked[r, c] for r, c in half)
    assert status is (CellStatus.OBSTACLE if half_hit else None)
    # a cell where a body may stand is never called an obstacle: bodies move
    anybody: BodyTest = lambda _cell: True  # noqa: E731
    assert judge(target, pos, d, reading, SonarMap(), anybody) is not CellStatus.OBSTACLE


@settings(max_examples=150, deadline=None)
@given(worlds(), st.sampled_from(SenseMode), st.booleans(), st.booleans())
def test_look_gives_the_exact_status_from_every_pose(case: tuple[np.ndarray, SubCell],
                                                      mode: SenseMode, one_sonar: bool,
                                                      shared: bool) -> None:
    """Every pose and heading in the start cell, every neighbour as target: what ``look``
    reports equals the exact status, the target is always reported, the body comes back.
    ``shared``: one SonarMap for all looks (memory from earlier rays must stay right)."""
    blocked, start = case
    here = cell_of(start)
    memory = SonarMap()
    for pos in sub_cells(here):
        for heading in range(4):
            for target in neighbours(here):
                body = StandIn(blocked, (*pos, heading), one_sonar=one_sonar)
                sonar = memory if shared else SonarMap()
                others = tuple(n for n in neighbours(here) if n != target)
                result = asyncio.run(look(body, sonar, Sense((target, *others)), mode, NOBODY))
                got = dict(result.statuses)
                assert target in got
                for cell, status in got.items():
                    assert status is exact(blocked, cell), (pos, heading, cell)
                assert body.pose is not None and (body.pose[0], body.pose[1]) == pos
                assert body.bumps == 0


@settings(max_examples=100, deadline=None)
@given(worlds(), st.integers(0, 3))
def test_a_body_in_the_unseen_half_is_not_free(case: tuple[np.ndarray, SubCell],
                                               d: int) -> None:
    """A peer's body in the half the first ray misses: the look from beside finds it."""
    blocked, pos = case
    here = cell_of(pos)
    target = (here[0] + HEADING_DELTA[d][0], here[1] + HEADING_DELTA[d][1])
    near = near_distance(pos, d)
    body_at = ahead(beside(pos, d), d, near)
    h, w = blocked.shape
    if not (0 <= body_at[0] < h and 0 <= body_at[1] < w):
        return
    world = blocked.copy()
    world[body_at] = True  # the peer, as simhw's sonar sees it
    body = StandIn(world, (*pos, d))
    holds: BodyTest = lambda cell: cell == target  # noqa: E731 - the peer owns the cell
    result = asyncio.run(look(body, SonarMap(), Sense((target,)), SenseMode.SINGLE, holds))
    assert dict(result.statuses)[target] is CellStatus.ROBOT


# ---- whole missions of one robot ----------------------------------------------------------

@dataclass(frozen=True)
class Mission:
    walk: dict[SubCell, int]  # entries by the machine's moves (the start counts once)
    body: StandIn
    sonar: SonarMap
    senses: int
    moves: int


async def run_alone(blocked: np.ndarray, start: SubCell, mode: SenseMode,
                    one_sonar: bool = False) -> Mission:
    """One robot's machine driven through ``look`` and the stand-in, to its Done."""
    machine = OrmstcMachine(MachineConfig(robot=0, team=1, start=(float(start[0]),
                                          float(start[1])), sense_mode=mode, claim_wait=1.0))
    body = StandIn(blocked, (*start, 0), one_sonar=one_sonar, visits={start: 1})
    sonar = SonarMap()
    walk = {start: 1}
    senses, now = 0, 0.0
    answer: Event | None = None
    for _ in range(200_000):
        if machine.done_sent:
            break
        now += 1.0
        events: list[Event] = [Tick(now)]
        if answer is not None:
            events.append(answer)
        answer = None
        for request in machine.step(events):
            if isinstance(request, Sense):
                senses += 1
                # looks from beside only: tests/test_ormstc_looks.py drives the looks from
                # inside (planner/ormstc/inside.py), which need agent.ormstc.looks.Looker
                answer = await look(body, sonar, replace(request, enter=False), mode, NOBODY)
            elif isinstance(request, Move):
                assert body.pose is not None
                await body.face(direction_to((body.pose[0], body.pose[1]), request.to))
                moved = await body.forward()
                answer = MoveResult(moved)
                if moved:
                    walk[request.to] = walk.get(request.to, 0) + 1
            elif isinstance(request, IsAlive):
                answer = AliveResult(request.robot, True)
    assert machine.done_sent, "the robot never finished"
    return Mission(walk, body, sonar, senses, machine.moves)


def lockstep_covered(blocked: np.ndarray, start: SubCell, mode: SenseMode) -> set[SubCell]:
    result = simulate(OccupancyGrid(~blocked), [start], SimConfig(sense_mode=mode))
    return {(int(r), int(c)) for r, c in np.argwhere(result.visits > 0)}


@settings(max_examples=25, deadline=None)
@given(worlds(), st.sampled_from(SenseMode), st.booleans())
def test_one_robot_covers_what_lockstep_covers_without_bumping(
        case: tuple[np.ndarray, SubCell], mode: SenseMode, one_sonar: bool) -> None:
    blocked, start = case
    mission = asyncio.run(run_alone(blocked, start, mode, one_sonar))
    check_mission(mission, lockstep_covered(blocked, start, mode), start)


def check_mission(mission: Mission, covered: set[SubCell], start: SubCell) -> None:
    """No bump, the lockstep simulator's covered set, and no redundancy but the looks."""
    body = mission.body
    assert body.bumps == 0
    assert set(body.visits) == set(mission.walk) == covered
    # STC: the walk enters every covered sub-cell once, the start twice (the robot comes home)
    assert all(n == (2 if sub == start else 1) for sub, n in mission.walk.items())
    # the only other entries are the steps aside and back of the looks from beside
    assert sum(body.visits.values()) == sum(mission.walk.values()) + mission.sonar.steps
    assert mission.sonar.steps == 2 * mission.sonar.beside_looks


def pillar_room() -> np.ndarray:
    """12 x 12 sub-cells, a 1 x 1 pillar in each quarter at a different corner of its cell."""
    blocked = np.zeros((12, 12), dtype=bool)
    for r, c in ((2, 3), (3, 8), (8, 2), (9, 9)):
        blocked[r, c] = True
    return blocked


@pytest.mark.parametrize("mode", list(SenseMode))
def test_pillar_room_alone(mode: SenseMode) -> None:
    blocked = pillar_room()
    mission = asyncio.run(run_alone(blocked, (0, 0), mode))
    check_mission(mission, lockstep_covered(blocked, (0, 0), mode), (0, 0))
    assert len(mission.walk) == 4 * int(coarsen(OccupancyGrid(~blocked)).free.sum())


def _cost_table() -> None:
    from planner.maps.worlds import builtin_world
    from simhw.kinematics import Kinematics

    cases = [("pillar room 12x12", pillar_room(), (0, 0))]
    for name in ("cave", "example"):
        world = builtin_world(name)
        cells = coarsen(world).free
        r, c = (int(v) for v in np.argwhere(cells)[0])
        cases.append((name, ~world.free, (2 * r, 2 * c)))
    kin = Kinematics()
    print("| world | mode | sonar | moves | Sense requests | sense commands | readings "
          "| looks from beside | steps aside and back | turns for looking | bumps "
          "| s looking / s of the moves |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for name, blocked, start in cases:
        for mode, one in ((SenseMode.ALL, False), (SenseMode.ALL, True),
                          (SenseMode.SINGLE, True)):
            m = asyncio.run(run_alone(blocked, start, mode, one))
            looking = (m.sonar.steps * kin.forward_s() + m.sonar.turns * kin.turn_s()
                       + m.body.commands * kin.sense_s)
            print(f"| {name} | {mode.value} | {'one' if one else 'all'} | {m.moves} | "
                  f"{m.senses} | {m.body.commands} | {m.sonar.readings} | {m.sonar.beside_looks} | "
                  f"{m.sonar.steps} | {m.sonar.turns} | {m.body.bumps} | "
                  f"{looking:.0f} / {m.moves * kin.forward_s():.0f} |")


if __name__ == "__main__":
    _cost_table()
