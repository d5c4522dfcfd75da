"""Two live owners of one cell are detected and resolved (planner/ormstc/conflicts.py), and a
machine's restatement (what peers re-learn after a router restart) is safe to hear twice.

The conflicts are forced: one machine driven by hand is told of a peer's tree edge into a cell
it owns; and the lockstep simulator runs with a claim window below the proven bound under
random delays (which makes tree edges collide, tests/test_ormstc_sim.py): every run must
still finish complete, every collision must be detected by the robots, and at the end no
cell may be owned (not merely walked) by two robots.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import replace

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from ormstc_oracles import missed
from test_ormstc_sim import random_starts, random_world

from planner.ormstc import passage, watch
from planner.ormstc.conflicts import restate, winner_of
from planner.ormstc.knowledge import Knowledge
from planner.ormstc.lockstep import LockstepSim, SimConfig, SimResult
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.types import (
    AliveResult,
    Cell,
    CellStatus,
    CompletionMsg,
    Done,
    Event,
    IsAlive,
    MachineConfig,
    Move,
    MoveResult,
    PeerMessage,
    Priority,
    Sense,
    SenseResult,
    StartMsg,
    SubCell,
    Tick,
    TreeEdgeMsg,
)
from planner.ormstc.walk import cell_of

FAR: SubCell = (200, 200)  # the peer's start: far from everything the machine sees


class Room:
    """Ground truth for one hand-driven machine: ``size`` x ``size`` free cells."""

    def __init__(self, size: int) -> None:
        self.size = size

    def cell_status(self, cell: Cell) -> CellStatus:
        inside = all(0 <= x < self.size for x in cell)
        return CellStatus.FREE if inside else CellStatus.OBSTACLE

    def is_alive(self, robot: int) -> bool:
        return True


class Driver:
    """Steps one machine, answering every Move with success, one tick per step."""

    def __init__(self, robot: int, peer: int) -> None:
        self.machine = OrmstcMachine(
            MachineConfig(robot=robot, team=2, start=(0.0, 0.0), claim_wait=1.0))
        self.room = Room(3)
        self.now = 0.0
        self.visits: list[SubCell] = []
        self.done = False
        self.pending: list[Event] = [PeerMessage(peer, StartMsg(peer, FAR))]

    def step(self, extra: Iterable[Event] = ()) -> None:
        self.now += 1
        events: list[Event] = [Tick(self.now), *self.pending, *extra]
        self.pending = []
        requests = self.machine.step(events)
        while requests:
            reply: Event | None = None  # sensing and liveness are answered within the step
            for request in requests:
                if isinstance(request, Move):
                    self.visits.append(request.to)
                    self.pending.append(MoveResult(True))
                elif isinstance(request, Sense):
                    reply = SenseResult(tuple((c, self.room.cell_status(c))
                                              for c in request.cells))
                elif isinstance(request, IsAlive):
                    reply = AliveResult(request.robot, self.room.is_alive(request.robot))
                elif isinstance(request, Done):
                    self.done = True
            requests = self.machine.step((reply,)) if reply is not None else []

    def run_until(self, moves: int) -> None:
        while self.machine.moves < moves:
            self.step()


def free_leaf(m: OrmstcMachine) -> Cell | None:
    """A leaf of the machine's tree it neither stands in nor is about to enter."""
    here = cell_of(m.pos)
    asked = cell_of(m.asked.to) if isinstance(m.asked, Move) else None
    parents = set(m.parent.values())
    return next((c for c in m.parent if c not in parents and c not in (here, asked)), None)


def walk_to_a_free_leaf(driver: Driver) -> Cell:
    """Step until the tree has a leaf the robot has left (it walks back from the DFS tip)."""
    for _ in range(200):
        leaf = free_leaf(driver.machine)
        if leaf is not None:
            return leaf
        driver.step()
    raise AssertionError("no leaf left behind")


def test_the_lower_id_cuts_off_a_leaf_and_connects_to_the_winner() -> None:
    loser = Driver(robot=0, peer=1)
    m = loser.machine
    leaf = walk_to_a_free_leaf(loser)
    parent = m.parent[leaf]
    loser.step([PeerMessage(1, TreeEdgeMsg(1, (leaf[0], -1), leaf))])
    assert (leaf, 1) in m.conflicts and m.cut == 1
    assert leaf not in m.mine and leaf not in m.parent and leaf not in m.edges
    assert m.know.live_owner(leaf) == 1
    assert m.connections.links[(parent, leaf)] == 1
    assert all(not (isinstance(msg, TreeEdgeMsg) and msg.child == leaf) for msg in restate(m))
    cut_at = len(loser.visits)
    for _ in range(2000):
        if loser.done:
            break
        loser.step([PeerMessage(1, CompletionMsg(1, 1))] if m.finished else [])
    assert loser.done, "the loser never finished after the cut"
    assert cell_of(loser.visits[-1]) == cell_of(m.home)
    assert all(cell_of(sub) != leaf for sub in loser.visits[cut_at:]), "walked the cut cell"
    assert len(m.mine) == 8, "every other cell of the 3 x 3 room is still its own"


def test_the_higher_id_keeps_the_cell_and_ignores_the_losers_edge() -> None:
    keeper = Driver(robot=1, peer=0)
    m = keeper.machine
    leaf = walk_to_a_free_leaf(keeper)
    edge = PeerMessage(0, TreeEdgeMsg(0, (leaf[0], -1), leaf))
    keeper.step([edge])
    keeper.step([edge])  # heard again (a restatement): still one conflict
    assert m.conflicts == {(leaf, 0)} and m.cut == 0 and not m.ceded
    assert leaf in m.mine and m.know.live_owner(leaf) == 1
    assert winner_of(0, 1) == winner_of(1, 0) == 1


def test_a_cell_being_entered_becomes_a_passage_then_is_cut_off() -> None:
    loser = Driver(robot=0, peer=1)
    loser.run_until(6)
    m = loser.machine
    while not (isinstance(m.asked, Move) and cell_of(m.asked.to) not in
               (cell_of(m.pos), *m.parent.values()) and cell_of(m.asked.to) in m.parent):
        loser.step()  # until it is about to enter a cell it just grew into
    entering = cell_of(m.asked.to)
    loser.step([PeerMessage(1, TreeEdgeMsg(1, (entering[0], -1), entering))])
    assert entering in m.ceded and m.cut == 0, "cut while the robot was entering it"
    for _ in range(200):
        if entering not in m.ceded:
            break
        loser.step()
    assert m.cut == 1 and entering not in m.mine, "the passage was never cut off"
    assert not any(m.parent.get(c) == entering for c in m.mine), "it grew from a passage"


def test_restating_twice_changes_nothing() -> None:
    speaker = Driver(robot=0, peer=1)
    speaker.run_until(30)
    said = restate(speaker.machine)
    assert isinstance(said[0], StartMsg)
    assert sum(isinstance(msg, TreeEdgeMsg) for msg in said) == len(speaker.machine.mine) - 1
    once, twice = (Knowledge(1, 2, Priority.ID) for _ in range(2))
    for msg in said:
        once.hear(msg)
    for msg in [*said, *said]:
        twice.hear(msg)
    assert once.owners == twice.owners and once.starts == twice.starts
    assert once.completed == twice.completed and not twice.conflicts


def check_resolved(sim: LockstepSim, result: SimResult) -> None:
    """Finished, complete, one owner per cell, and every collision found by a robot."""
    assert result.finished
    assert not missed(result).any()
    owned: dict[Cell, int] = {}
    for m in sim.machines:
        for cell in m.mine.difference(m.ceded):
            assert cell not in owned, f"cell {cell} owned by robots {owned[cell], m.me}"
            owned[cell] = m.me
    # a third robot's edge into a cell already given up collides, for the simulator, with
    # the robot that gave it up: so compare cells
    found = {cell for m in sim.machines for cell, _other in m.conflicts}
    assert {cell for _step, cell, _robot, _other in result.conflicts} <= found


def test_collisions_happen_with_a_short_window_and_are_all_resolved() -> None:
    # The claim window is what keeps claims apart: the same worlds and delays with a window
    # of one step must collide more often than with the default (which, measured, never
    # collides on these), so the resolution checks below see real collisions.
    collided = {"short": 0, "default": 0}
    for seed in range(20):
        world = random_world(seed, 6, 6, 0.0)
        for window, config in (("short", SimConfig(seed=seed, delay=(1, 6), claim_wait=1)),
                               ("default", SimConfig(seed=seed, delay=(1, 6)))):
            sim = LockstepSim(world, random_starts(world, 6, seed), config)
            result = sim.run()
            check_resolved(sim, result)
            collided[window] += bool(result.conflicts)
    assert collided["short"] > collided["default"], collided


# Derandomized, so CI runs the same sample every time. Random draws found two ways bodies
# never parted in a passage (a ring of four bodies in one passage cell; a finished winner
# parked on the sub-cell a loser's walk needs, and more): 12 of 36 000 forced-collision runs
# on 4 x 4 worlds before planner/ormstc/passage.py, pinned below.
# half_sense: cells grown into on half a look and looked at from inside (planner/ormstc/
# inside.py), as the agents do
@pytest.mark.parametrize("half_sense", [False, True])
@settings(max_examples=60, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), size=st.integers(4, 8), k=st.integers(2, 6),
       density=st.sampled_from([0.0, 0.15]), priority=st.sampled_from(list(Priority)))
def test_forced_collisions_are_detected_and_the_mission_stays_complete(
        half_sense: bool, seed: int, size: int, k: int, density: float,
        priority: Priority) -> None:
    world = random_world(seed, size, size, density)
    starts = random_starts(world, k, seed)
    sim = LockstepSim(world, starts, SimConfig(seed=seed, delay=(1, 6), claim_wait=1,
                                               priority=priority, half_sense=half_sense))
    check_resolved(sim, sim.run())


# (seed, robots, obstacle density, priority): every run of 36 000 (seeds 0-2999, 4 x 4 worlds,
# forced collisions) that never finished before planner/ormstc/passage.py
_STUCK_IN_A_PASSAGE = [
    (835, 6, 0.15, Priority.FEWEST),  # four bodies in a ring in one passage cell
    (317, 5, 0.15, Priority.ID),  # a ring, then a loser and the winner head-on in it
    (317, 5, 0.15, Priority.FEWEST),
    (1051, 5, 0.0, Priority.ID),  # a finished winner parked on the loser's next sub-cell
    (1054, 6, 0.0, Priority.ID),
    (1054, 6, 0.0, Priority.FEWEST),
    (1894, 4, 0.0, Priority.ID),  # a loser that finished parked in its passage
    (2232, 6, 0.0, Priority.ID),  # four in one passage cell: only the winner can step out
    (2405, 6, 0.0, Priority.ID),
    (2405, 6, 0.0, Priority.FEWEST),
    (2804, 5, 0.0, Priority.ID),
    (2804, 5, 0.0, Priority.FEWEST),
]


def _stay(_m: object) -> Iterator[object]:
    yield from ()


@pytest.mark.parametrize(("seed", "k", "density", "priority"), _STUCK_IN_A_PASSAGE)
def test_bodies_held_up_in_a_passage_get_out_and_the_mission_completes(
        seed: int, k: int, density: float, priority: Priority) -> None:
    world = random_world(seed, 4, 4, density)
    config = SimConfig(seed=seed, delay=(1, 6), claim_wait=1, priority=priority)
    sim = LockstepSim(world, random_starts(world, k, seed), config)
    result = sim.run()
    check_resolved(sim, result)
    # the same run without passage.py's rules is one that never ends
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(passage, "DETOUR_AFTER", 10**9)
        patch.setattr(passage, "STUCK_AFTER", 10**9)
        patch.setattr(watch, "leave_passage", _stay)
        stuck = LockstepSim(world, random_starts(world, k, seed),
                            replace(config, max_steps=result.steps + 2_000)).run()
    assert not stuck.finished


def test_a_cell_handed_over_during_a_claim_wait_grows_nothing() -> None:
    loser = Driver(robot=0, peer=1)
    m = loser.machine
    for _ in range(200):  # until it waits on a claim made from a cell it grew into
        loser.step()
        if m.know.claims.pending and cell_of(m.pos) in m.parent:
            break
    here = cell_of(m.pos)
    claimed = next(iter(m.know.claims.pending))
    loser.step([PeerMessage(1, TreeEdgeMsg(1, (here[0], -1), here))])
    assert here in m.ceded
    for _ in range(5):
        loser.step()  # the claim window (1 tick) ends
    assert claimed not in m.mine, "grew from a cell handed over during the claim"
    assert all(link[0] != here for link in m.connections.links)


# Forced collisions and deaths (benchmarks/bench_forced_collisions.py --wide --deaths): a loser
# died in its passage, and the winner's walk needs the sub-cell its body stands on; seed,
# cells a side, robots, priority, (robot, step it dies)
_DEAD_BODY_IN_THE_WAY = [
    (1113, 4, 3, Priority.ID, ((0, 20),)),
    (86, 4, 5, Priority.ID, ((3, 12), (0, 52), (2, 58))),
    (3876, 4, 3, Priority.FEWEST, ((1, 9),)),  # its side undecided: decided from beside
    (1034, 4, 3, Priority.ID, ((0, 48), (2, 29))),  # on the way to a takeover
]


@pytest.mark.parametrize(("seed", "size", "k", "priority", "deaths"), _DEAD_BODY_IN_THE_WAY)
def test_a_dead_body_on_the_walk_in_an_own_cell_is_walked_round(
        seed: int, size: int, k: int, priority: Priority,
        deaths: tuple[tuple[int, int], ...]) -> None:
    world = random_world(seed, size, size, 0.0)
    config = SimConfig(seed=seed, delay=(1, 6), claim_wait=1, priority=priority,
                       failures=deaths)
    sim = LockstepSim(world, random_starts(world, k, seed), config)
    result = sim.run()
    assert result.finished and not missed(result).any()
    assert max(result.bumps) >= passage.STUCK_AFTER, "nobody was held up that long"
    with pytest.MonkeyPatch.context() as patch:  # without the last resort: never ends
        patch.setattr(passage, "STUCK_AFTER", 10**9)
        stuck = LockstepSim(world, random_starts(world, k, seed),
                            replace(config, max_steps=result.steps + 2_000)).run()
    assert not stuck.finished
