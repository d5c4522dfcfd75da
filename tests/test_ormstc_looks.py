"""agent.ormstc.looks: sensing steps numbered for the wire, and glances after moves that
spare looks from beside. A stand-in body with simhw's ray cast and bump rule
(tests/test_ormstc_sensing.py) replaces simhw; the oracle for coverage is the lockstep
simulator."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass

import numpy as np
from hypothesis import given, settings
from test_ormstc_sensing import NOBODY, StandIn, lockstep_covered, worlds

from agent.ormstc.body import look
from agent.ormstc.looks import MarkedSteps, glance
from agent.ormstc.sensing import SonarMap, ahead, direction_to, shows_news
from planner.grid import coarsen
from planner.maps.worlds import builtin_world
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import (
    AliveResult,
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


def test_only_steps_that_moved_are_numbered() -> None:
    body = StandIn(np.zeros((4, 4), dtype=bool), (0, 0, 1))
    steps: list[tuple[int, SubCell]] = []
    marked = MarkedSteps(body, lambda seq, cell: steps.append((seq, cell)))
    assert asyncio.run(marked.forward())
    asyncio.run(marked.face(0))
    assert not asyncio.run(marked.forward())  # the world's edge: a bump, no step
    asyncio.run(marked.face(2))
    assert asyncio.run(marked.forward())
    assert steps == [(1, (0, 1)), (2, (1, 1))] and marked.pose == (1, 1, 2)


def test_a_ray_shows_news_until_it_has_been_read() -> None:
    blocked = np.zeros((2, 12), dtype=bool)
    blocked[0, 5] = True
    body = StandIn(blocked, (0, 0, 1))
    sonar = SonarMap()
    assert shows_news(sonar, (0, 0), 1) and shows_news(sonar, (0, 0), 2)
    assert asyncio.run(glance(body, sonar, NOBODY)) == 3  # front (E), left (N), right (S)
    assert {ahead((0, 0), 1, i) for i in range(1, 5)} <= sonar.free
    assert (0, 5) in sonar.static and (-1, 0) in sonar.static  # the pillar, the edge
    assert not any(shows_news(sonar, (0, 0), d) for d in (0, 1))
    readings = body.readings
    assert asyncio.run(glance(body, sonar, NOBODY)) == 0 and body.readings == readings
    # a hit where a body may stand is not remembered as an obstacle: still news there
    other = SonarMap()
    asyncio.run(glance(StandIn(blocked, (0, 0, 1)), other, lambda cell: True))
    assert (0, 5) not in other.static and shows_news(other, (0, 0), 1)


@dataclass
class Alone:
    walk: dict[SubCell, int]
    body: StandIn
    sonar: SonarMap


async def cover_alone(blocked: np.ndarray, start: SubCell, glances: bool) -> Alone:
    """One robot's machine driven as agent.ormstc.driver does: looks through MarkedSteps,
    and with ``glances`` a glance after every move."""
    machine = OrmstcMachine(MachineConfig(robot=0, team=1, start=(float(start[0]),
                                          float(start[1])), sense_mode=SenseMode.ALL,
                                          claim_wait=1.0))
    body = StandIn(blocked, (*start, 0), visits={start: 1})
    marked = MarkedSteps(body, lambda seq, cell: None)
    sonar, walk, now = SonarMap(), {start: 1}, 0.0
    answer: Event | None = None
    while not machine.done_sent:
        now += 1.0
        events: list[Event] = [Tick(now), *([answer] if answer is not None else [])]
        answer = None
        for request in machine.step(events):
            if isinstance(request, Sense):
                answer = await look(marked, sonar, request, SenseMode.ALL, NOBODY)
            elif isinstance(request, Move):
                assert body.pose is not None
                await body.face(direction_to((body.pose[0], body.pose[1]), request.to))
                moved = await body.forward()
                answer = MoveResult(moved)
                if moved:
                    walk[request.to] = walk.get(request.to, 0) + 1
                    if glances:
                        await glance(body, sonar, NOBODY)
            elif isinstance(request, IsAlive):
                answer = AliveResult(request.robot, True)
        assert now < 200_000, "the robot never finished"
    assert marked.steps == sonar.steps
    return Alone(walk, body, sonar)


@settings(max_examples=25, deadline=None)
@given(worlds())
def test_glances_change_nothing_but_the_looks(case: tuple[np.ndarray, SubCell]) -> None:
    blocked, start = case
    alone = asyncio.run(cover_alone(blocked, start, glances=True))
    assert alone.body.bumps == 0
    assert set(alone.walk) == set(alone.body.visits) == lockstep_covered(blocked, start,
                                                                         SenseMode.ALL)
    assert all(n == (2 if sub == start else 1) for sub, n in alone.walk.items())
    assert sum(alone.body.visits.values()) == sum(alone.walk.values()) + alone.sonar.steps


def test_glances_spare_looks_on_office() -> None:
    world = builtin_world("office")
    r, c = (int(v) for v in np.argwhere(coarsen(world).free)[0])
    start = (2 * r, 2 * c)
    plain = asyncio.run(cover_alone(~world.free, start, glances=False))
    glancing = asyncio.run(cover_alone(~world.free, start, glances=True))
    assert plain.walk == glancing.walk
    assert glancing.sonar.beside_looks < plain.sonar.beside_looks
    assert glancing.sonar.glance_readings > 0 and plain.sonar.glance_readings == 0
