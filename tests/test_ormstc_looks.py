"""agent.ormstc.looks: sensing steps numbered for the wire, and glances after moves that
spare looks from beside. A stand-in body with simhw's ray cast and bump rule
(tests/test_ormstc_sensing.py) replaces simhw; the oracle for coverage is the lockstep
simulator."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, replace

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_ormstc_sensing import (
    NOBODY,
    StandIn,
    exact,
    lockstep_covered,
    neighbours,
    worlds,
)

from agent.ormstc.body import look
from agent.ormstc.looks import Looker, MarkedSteps, glance
from agent.ormstc.sensing import (
    BodyTest,
    SonarMap,
    ahead,
    beside,
    cell_of,
    direction_to,
    peer_may_be_in,
    shows_news,
    sub_cells,
)
from agent.ormstc.wire import from_wire, key_for, to_wire
from bus import keys
from planner.grid import coarsen
from planner.maps.worlds import builtin_world
from planner.ormstc.knowledge import Knowledge
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import (
    AliveResult,
    Broadcast,
    CellStatus,
    Event,
    IsAlive,
    MachineConfig,
    Message,
    Move,
    MoveResult,
    Priority,
    RetractionMsg,
    Sense,
    SenseMode,
    SubCell,
    Tick,
    TreeEdgeMsg,
)
from simhw.sensors import sonar_range
from simhw.types import Heading


def test_only_steps_that_moved_are_numbered() -> None:
    body = StandIn(np.zeros((4, 4), dtype=bool), (0, 0, 1))
    steps: list[tuple[int, SubCell]] = []
    marked = MarkedSteps(body, lambda seq, cell: steps.append((seq, cell)))
    assert asyncio.run(marked.forward())
    asyncio.run(marked.face(0))
    assert not asyncio.run(marked.forward())  # the world's edge: a bump, no step
    asyncio.run(marked.face(2))
    assert asyncio.run(marked.forward())
    assert steps == [] and marked.held == [(0, 1), (1, 1)]  # held until published
    marked.publish()
    assert steps == [(1, (0, 1)), (2, (1, 1))] and marked.pose == (1, 1, 2)
    assert asyncio.run(marked.forward())
    marked.publish(last_walked=True)  # the walk's own move: not a look step
    assert steps == [(1, (0, 1)), (2, (1, 1))] and marked.held == [] and marked.steps == 2


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
    look_steps: list[SubCell]  # the sub-cells of the published look steps
    given_up: int  # cells the machine grew into, entered and gave up (inside.py)
    said: list[Message]  # what the machine broadcast, in order


async def cover_alone(blocked: np.ndarray, start: SubCell, glances: bool,
                      stay: bool = False, inside: bool = False) -> Alone:
    """One robot's machine driven as agent.ormstc.driver does (``glances``, ``stay`` and
    ``inside``): looks through a Looker, a glance after every move, cells half seen entered
    to look (planner/ormstc/inside.py); without ``glances`` no glance, without ``stay`` every
    look steps back at once, without ``inside`` every look is from outside (earlier
    drivers)."""
    machine = OrmstcMachine(MachineConfig(robot=0, team=1, start=(float(start[0]),
                                          float(start[1])), sense_mode=SenseMode.ALL,
                                          claim_wait=1.0))
    body = StandIn(blocked, (*start, 0), visits={start: 1})
    published: list[SubCell] = []
    sonar, walk, now = SonarMap(), {start: 1}, 0.0
    looker = Looker(body, sonar, lambda seq, cell: published.append(cell))
    said: list[Message] = []
    answer: Event | None = None
    while not machine.done_sent:
        now += 1.0
        events: list[Event] = [Tick(now), *([answer] if answer is not None else [])]
        answer = None
        for request in machine.step(events):
            if isinstance(request, Sense):
                if not inside:
                    request = replace(request, enter=False)
                if stay:
                    out = len(looker.stepped_out)
                    answer = await looker.sense(request, SenseMode.ALL, NOBODY)
                    for sub in looker.stepped_out[out:]:
                        walk[sub] -= 1  # the step into a cell stepped out of was a look
                        if not walk[sub]:
                            del walk[sub]
                else:
                    answer = await look(looker.marked, sonar, request, SenseMode.ALL, NOBODY)
                    looker.marked.publish()
            elif isinstance(request, Move):
                assert body.pose is not None
                moved = await looker.settle(request.to)
                if not moved:
                    await body.face(direction_to((body.pose[0], body.pose[1]), request.to))
                    moved = await body.forward()
                answer = MoveResult(moved)
                if moved and not looker.walked(request.to):
                    walk[request.to] = walk.get(request.to, 0) + 1
                    if glances:
                        await glance(body, sonar, NOBODY)
            elif isinstance(request, IsAlive):
                answer = AliveResult(request.robot, True)
            elif isinstance(request, Broadcast):
                said.append(request.message)
        assert now < 200_000, "the robot never finished"
    assert looker.marked.steps == sonar.steps == len(published)
    assert looker.home is None and not looker.marked.held
    return Alone(walk, body, sonar, published, machine.given_up, said)


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


@settings(max_examples=25, deadline=None)
@given(worlds())
def test_staying_aside_changes_nothing_but_the_look_steps(
        case: tuple[np.ndarray, SubCell]) -> None:
    """Looks that leave the body beside: the same walk as the lockstep simulator's, every
    entry of a sub-cell beyond the walk's is a published look step (the report's account)."""
    blocked, start = case
    alone = asyncio.run(cover_alone(blocked, start, glances=True, stay=True))
    assert alone.body.bumps == 0
    assert set(alone.walk) == set(alone.body.visits) == lockstep_covered(blocked, start,
                                                                         SenseMode.ALL)
    assert all(n == (2 if sub == start else 1) for sub, n in alone.walk.items())
    for sub, entries in alone.body.visits.items():
        assert entries == alone.walk[sub] + alone.look_steps.count(sub), sub


def test_staying_aside_spares_look_steps_on_builtin_worlds() -> None:
    """The same walk and the same looks; a look whose step aside was the walk's next move
    costs one step (that move) instead of three. Alone on a cell-aligned world (office)
    every look is into a free cell the robot then grows into, so nothing is spared there;
    cave has obstacles in parts of cells."""
    for name in ("office", "cave"):
        world = builtin_world(name)
        r, c = (int(v) for v in np.argwhere(coarsen(world).free)[0])
        start = (2 * r, 2 * c)
        back = asyncio.run(cover_alone(~world.free, start, glances=True))
        stay = asyncio.run(cover_alone(~world.free, start, glances=True, stay=True))
        assert stay.walk == back.walk
        assert stay.sonar.beside_looks == back.sonar.beside_looks > 0
        assert back.sonar.steps == 2 * back.sonar.beside_looks
        assert stay.sonar.beside_looks <= stay.sonar.steps <= back.sonar.steps
        if name == "cave":
            assert stay.sonar.steps < back.sonar.steps
        assert sum(stay.body.visits.values()) == sum(stay.walk.values()) + stay.sonar.steps


@settings(max_examples=40, deadline=None)
@given(worlds())
def test_looks_from_inside_change_nothing_but_the_look_steps(
        case: tuple[np.ndarray, SubCell]) -> None:
    """Growing on the near half and looking from inside: the lockstep simulator's walk, and
    every entry of a sub-cell beyond it (into a cell given up and back, or on to the next
    sub-cell and back) a published look step."""
    blocked, start = case
    alone = asyncio.run(cover_alone(blocked, start, glances=True, stay=True, inside=True))
    assert alone.body.bumps == 0
    assert set(alone.walk) == lockstep_covered(blocked, start, SenseMode.ALL)
    assert all(n == (2 if sub == start else 1) for sub, n in alone.walk.items())
    for sub, entries in alone.body.visits.items():
        assert entries == alone.walk.get(sub, 0) + alone.look_steps.count(sub), sub


def test_a_cell_blocked_in_its_far_half_is_given_up() -> None:
    """Cell (1, 0) has an obstacle in its east column only: seen from (1, 0) looking south
    its near (west) column is free, so the robot grows, enters (2, 0), sees (2, 1) blocked
    and steps back; the lockstep simulator never enters the cell."""
    blocked = np.zeros((6, 6), dtype=bool)
    blocked[2, 1] = True
    alone = asyncio.run(cover_alone(blocked, (0, 0), glances=True, stay=True, inside=True))
    assert alone.given_up >= 1 and (2, 0) in alone.look_steps
    assert set(alone.walk) == lockstep_covered(blocked, (0, 0), SenseMode.ALL)
    assert not {(2, 0), (2, 1), (3, 0), (3, 1)} & set(alone.walk)
    # the edge into (1, 0) went out, and then its retraction, on the retraction's own key
    edges = [m for m in alone.said if isinstance(m, TreeEdgeMsg)]
    taken_back = [m for m in alone.said if isinstance(m, RetractionMsg)]
    assert [(m.parent, m.child) for m in taken_back] == [((0, 0), (1, 0))]
    assert alone.said.index(TreeEdgeMsg(0, (0, 0), (1, 0))) < alone.said.index(taken_back[0])
    assert all(e.child != (1, 0) for e in edges[edges.index(TreeEdgeMsg(0, (0, 0), (1, 0)))
                                                + 1:])
    wire = to_wire(taken_back[0], 1, 9)
    assert keys.kind_of(key_for("m", wire)) == "ormstc/retract"
    assert from_wire(wire) == taken_back[0]


def test_looks_from_inside_spare_look_steps_on_builtin_worlds() -> None:
    """The same walk as looking from beside (staying aside), far fewer look steps: a cell
    the robot grows into is seen from inside on the walk's own moves (planner/ormstc/inside.py).
    Figures in docs/ormstc.md ("Looking from inside")."""
    for name in ("room", "cave"):
        world = builtin_world(name)
        r, c = (int(v) for v in np.argwhere(coarsen(world).free)[0])
        start = (2 * r, 2 * c)
        beside_ = asyncio.run(cover_alone(~world.free, start, glances=True, stay=True))
        inside = asyncio.run(cover_alone(~world.free, start, glances=True, stay=True,
                                         inside=True))
        assert inside.walk == beside_.walk
        assert inside.sonar.beside_looks < beside_.sonar.beside_looks
        assert 2 * inside.sonar.steps < beside_.sonar.steps, name
        assert (inside.given_up > 0) == (name == "cave")  # room has no part-blocked cell


def _aside() -> tuple[StandIn, SonarMap, Looker, list[SubCell]]:
    """A body on the top-left sub-cell of cell (1, 1) of an empty room, having looked west:
    the ray shows row 2 of cell (1, 0), the step to (3, 2) row 3."""
    body = StandIn(np.zeros((8, 8), dtype=bool), (2, 2, 2))
    sonar, published = SonarMap(), []
    looker = Looker(body, sonar, lambda seq, cell: published.append(cell))
    result = asyncio.run(looker.sense(Sense(((1, 0),)), SenseMode.SINGLE, NOBODY))
    assert dict(result.statuses) == {(1, 0): CellStatus.FREE}
    assert body.pose is not None and body.pose[:2] == (3, 2) and looker.home == (2, 2)
    assert published == [] and sonar.beside_looks == 1
    return body, sonar, looker, published


def test_a_step_aside_that_the_walk_goes_on_from_is_no_look_step() -> None:
    body, sonar, looker, published = _aside()
    assert asyncio.run(looker.settle((3, 2)))  # the corner: the walk's next sub-cell
    assert published == [] and sonar.steps == 0 and looker.home is None
    assert body.visits == {(3, 2): 1}


def test_a_move_from_home_steps_back_first() -> None:
    body, sonar, looker, published = _aside()
    assert not asyncio.run(looker.settle((2, 1)))  # grown into the cell looked at
    assert body.pose is not None and body.pose[:2] == (2, 2)
    assert published == [(3, 2), (2, 2)] and sonar.steps == 2 and looker.home is None


def test_a_second_look_while_aside_comes_back_beside() -> None:
    body, sonar, looker, published = _aside()
    # south of (3, 2): the ray shows column 2 of cell (2, 1), column 3 needs a step to (3, 3)
    result = asyncio.run(looker.sense(Sense(((2, 1),)), SenseMode.SINGLE, NOBODY))
    assert dict(result.statuses) == {(2, 1): CellStatus.FREE}
    assert body.pose is not None and body.pose[:2] == (3, 2) and looker.home == (2, 2)
    assert published == [] and sonar.beside_looks == 2
    assert asyncio.run(looker.settle((3, 2)))
    assert published == [(3, 2), (3, 3)]  # the walk's entry of (3, 2) is the third step
    assert body.visits == {(3, 2): 2, (3, 3): 1} and sonar.steps == 2


@settings(max_examples=100, deadline=None)
@given(worlds(), st.sampled_from(SenseMode), st.booleans())
def test_a_look_that_stays_aside_is_exact_and_one_step_from_home(
        case: tuple[np.ndarray, SubCell], mode: SenseMode, one_sonar: bool) -> None:
    """From every pose in the start cell and towards every neighbour: the statuses a Looker
    reports are exact, and the body is home or on the sub-cell beside it, one held step."""
    blocked, start = case
    here = cell_of(start)
    for pos in sub_cells(here):
        for heading in range(4):
            for target in neighbours(here):
                body = StandIn(blocked, (*pos, heading), one_sonar=one_sonar)
                looker = Looker(body, SonarMap(), lambda seq, cell: None)
                others = tuple(n for n in neighbours(here) if n != target)
                result = asyncio.run(looker.sense(Sense((target, *others)), mode, NOBODY))
                got = dict(result.statuses)
                assert target in got
                assert all(status is exact(blocked, cell) for cell, status in got.items())
                assert body.pose is not None and body.bumps == 0
                at = (body.pose[0], body.pose[1])
                if looker.home is None:
                    assert at == pos and not looker.marked.held
                else:
                    assert looker.home == pos and looker.marked.held == [at]
                    assert at == beside(pos, direction_to(here, target))


# ---- rays told to peers (SonarRays) ----------------------------------------------------------

def _room_with_a_peer_ray() -> tuple[StandIn, SonarMap]:
    """An empty room; a peer read west along row 3 from (3, 6): cell (1, 0)'s lower half,
    which the robot at (2, 2) cannot see from there, is in the memory it was told."""
    blocked = np.zeros((8, 8), dtype=bool)
    peer = SonarMap()
    peer.record((3, 6), 3, sonar_range(blocked, (3, 6), Heading(3), peer.max_range), NOBODY)
    mine = SonarMap()
    mine.hear(peer.told())
    assert not peer.rays and {(3, 1), (3, 0)} <= mine.shared and not mine.free
    return StandIn(blocked, (2, 2, 2)), mine


def test_a_peers_ray_spares_a_look_from_beside() -> None:
    body, sonar = _room_with_a_peer_ray()
    looker = Looker(body, sonar, lambda seq, cell: None)
    result = asyncio.run(looker.sense(Sense(((1, 0),)), SenseMode.SINGLE, NOBODY))
    assert dict(result.statuses) == {(1, 0): CellStatus.FREE}
    assert sonar.beside_looks == 0 and body.forwards == 0


def test_a_peers_ray_is_not_trusted_where_a_body_may_be() -> None:
    body, sonar = _room_with_a_peer_ray()
    looker = Looker(body, sonar, lambda seq, cell: None)
    anybody: BodyTest = lambda _cell: True  # noqa: E731 - someone owns or claims the cell
    result = asyncio.run(looker.sense(Sense(((1, 0),)), SenseMode.SINGLE, anybody))
    assert dict(result.statuses) == {(1, 0): CellStatus.FREE}
    assert sonar.beside_looks == 1  # looked itself: the peer's ray may predate a body


def test_rays_out_of_shape_are_ignored() -> None:
    sonar = SonarMap()
    sonar.hear([(0, 0, 4, 3), (0, 0, 1, 0), (0, 0, 1, sonar.max_range + 1), (0, 0, -1, 2)])
    assert not sonar.shared
    sonar.hear([(0, 0, 1, 2)])
    assert sonar.shared == {(0, 1), (0, 2)}


@settings(max_examples=100, deadline=None)
@given(worlds(), st.lists(st.tuples(st.integers(0, 11), st.integers(0, 11), st.integers(0, 3)),
                          max_size=30))
def test_looks_stay_exact_with_rays_told_by_peers(
        case: tuple[np.ndarray, SubCell], peer_rays: list[tuple[int, int, int]]) -> None:
    """Peers' rays cast by simhw's ray cast from free sub-cells anywhere: whatever they add
    to a robot's memory, every status it reports from every pose of its cell is exact."""
    blocked, start = case
    h, w = blocked.shape
    peer = SonarMap()
    for r, c, d in peer_rays:
        if r < h and c < w and not blocked[r, c]:
            peer.record((r, c), d, sonar_range(blocked, (r, c), Heading(d), peer.max_range),
                        NOBODY)
    told = peer.told()
    here = cell_of(start)
    for pos in sub_cells(here):
        for target in neighbours(here):
            sonar = SonarMap()
            sonar.hear(told)
            body = StandIn(blocked, (*pos, 0))
            result = asyncio.run(Looker(body, sonar, lambda seq, cell: None).sense(
                Sense((target,)), SenseMode.ALL, NOBODY))
            assert dict(result.statuses)[target] is exact(blocked, target), (pos, target)


def test_a_peer_may_be_in_an_own_cell_only_when_it_claimed_owns_or_stands_there() -> None:
    """What makes a hit inside an own cell a body rather than an obstacle (look_inside)."""
    know = Knowledge(1, 3, Priority.ID)
    mine, claimed, shared, elsewhere = (0, 0), (0, 1), (1, 1), (2, 2)
    know.own(mine, 1)
    know.own(claimed, 1)
    know.own(shared, 1)
    know.claims.hear(claimed, 2, 0)
    know.own(shared, 0)  # a conflict: robot 0's edge into a cell robot 1 owns
    assert not peer_may_be_in(mine, 1, know, ())
    assert peer_may_be_in(claimed, 1, know, ()) and peer_may_be_in(shared, 1, know, ())
    assert peer_may_be_in(mine, 1, know, [elsewhere, mine])  # a peer's last pose
    assert not peer_may_be_in(mine, 1, None, ()) and peer_may_be_in(mine, 1, None, [mine])
