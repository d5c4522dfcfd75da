"""planner/ormstc/passage.py: walking round a body in a passage, stepping aside, moving out.

Driven directly over a small robot: cell A = (0, 0) is the robot's own, cell B = (0, 1) a
passage (lost in a conflict) hung off A's east side. The walk round them (counter-clockwise
as drawn, rows going down) is (1, 1) -> (1, 2) -> (1, 3) -> (0, 3) -> (0, 2) -> (0, 1).
The whole runs, in the lockstep simulator, are in test_ormstc_conflicts.py, but for the
takeovers that stand beside a body for good (at the end).
"""

from __future__ import annotations

from collections.abc import Generator
from dataclasses import dataclass, field
from typing import TypeVar, cast

import pytest
from ormstc_oracles import check_the_rule_ends_it, forced_with_deaths, never_giving_up
from test_ormstc_sim import random_starts, random_world

from planner.ormstc import passage, watch
from planner.ormstc.robot import ANSWER, UNTIL, Robot
from planner.ormstc.types import Cell, MachineConfig, Move, MoveResult, Priority, SubCell
from planner.ormstc.walk import EAST, WEST, cell_of, side_of

A, B = (0, 0), (0, 1)
R = TypeVar("R")


@dataclass
class Walker:
    """What passage.py reads and writes of a robot."""

    pos: SubCell
    mine: set[Cell]
    ceded: dict[Cell, int]
    edges: dict[Cell, int]
    config: MachineConfig
    decided: dict[Cell, int] = field(default_factory=dict)
    passing: set[Cell] = field(default_factory=set)
    now: float = 0.0
    bumps: int = 0
    moves: list[SubCell] = field(default_factory=list)

    def moved(self, to: SubCell) -> None:
        self.pos = to
        self.moves.append(to)

    def backoff(self) -> float:
        return 1.0

    def has_edge(self, cell: Cell, side: int) -> bool:
        return bool(self.edges.get(cell, 0) >> side & 1)


def walker(pos: SubCell, *, ceded: bool = True, hold_up: float = 0.0) -> Walker:
    return Walker(pos=pos, mine={A, B}, ceded={B: 7} if ceded else {},
                  edges={A: 1 << EAST, B: 1 << WEST},
                  config=MachineConfig(robot=0, team=2, start=(1.0, 1.0), hold_up=hold_up))


def drive(flow: Generator[tuple[int, object], object, R], robot: Walker,
          taken: set[SubCell], free_after: int | None = None) -> tuple[R, list[SubCell]]:
    """Run a flow to its end: time passes to every wait; a move into ``taken`` bumps, until
    ``free_after`` moves have been asked (the body went on)."""
    asked: list[SubCell] = []
    answer: object = None
    for _ in range(1000):
        try:
            kind, arg = flow.send(answer)
        except StopIteration as stop:
            return stop.value, asked
        answer = None
        if kind == UNTIL:
            robot.now = max(robot.now, float(cast(float, arg)))
        elif kind == ANSWER:
            assert isinstance(arg, Move)
            asked.append(arg.to)
            answer = MoveResult(arg.to not in taken)
            if free_after is not None and len(asked) >= free_after:
                taken = set()
    raise AssertionError(f"the flow never ended; asked {asked[-10:]}")


def test_the_walk_ahead_runs_through_the_passage_to_the_first_sub_cell_past_it() -> None:
    robot = walker((1, 2))
    ahead, ends = passage.walk_ahead(cast(Robot, robot), (1, 3), root=A)
    assert ahead == [(1, 3), (0, 3), (0, 2), (0, 1)] and not ends
    assert robot.decided == {}, "looking ahead decides nothing"
    # a sub-cell of the root whose side is decided is where the walk ends
    robot.decided[A] = 1 << 0  # (0, 1) faces north
    assert passage.walk_ahead(cast(Robot, robot), (1, 3), root=A) == (ahead, True)


def test_the_way_round_lands_where_the_rest_of_the_stretch_is_shortest() -> None:
    robot = cast(Robot, walker((1, 2)))
    ahead = [(1, 3), (0, 3), (0, 2), (0, 1)]
    # (0, 3): 2 moves + 2 on; (0, 2): 1 + 1; (0, 1): 2 + 0 -> (0, 2), the earlier of the tie
    assert passage.way_round(robot, ahead, {(1, 3)}) == [(0, 2)]
    assert passage.way_round(robot, ahead, {(1, 3), (0, 2)}) == [(1, 1), (0, 1)]
    assert passage.way_round(robot, ahead, {(1, 3), (0, 2), (1, 1)}) is None


def test_a_loser_held_up_in_a_passage_walks_round_once_held_up_long_enough() -> None:
    for hold_up, tries in ((0.0, 2), (5.0, 5)):
        robot = walker((1, 2), hold_up=hold_up)
        (reached, over), asked = drive(passage.reach(cast(Robot, robot), (1, 3), A), robot,
                                       taken={(1, 3)})
        # the bump before reach() was the first: two more make DETOUR_AFTER; with a hold-up
        # of 5 the robot (backing off 1 a time) also waits until 5 have passed
        assert asked == [(1, 3)] * tries + [(0, 2)], (hold_up, asked)
        assert (reached, over) == ((0, 2), False) and robot.pos == (0, 2)
        # the sub-cells left out count as walked: their sides are decided
        assert robot.decided[B] == (1 << side_of((1, 3))) | (1 << side_of((0, 3)))
        assert robot.passing == set(), "cells are kept from being cut only while passing"


def test_a_body_that_moves_on_is_followed_not_walked_round() -> None:
    robot = walker((1, 2), hold_up=5.0)
    (reached, over), asked = drive(passage.reach(cast(Robot, robot), (1, 3), A), robot,
                                   taken={(1, 3)}, free_after=4)
    assert asked == [(1, 3)] * 5 and (reached, over) == ((1, 3), False)
    assert robot.decided == {} and robot.moves == [(1, 3)]


def test_a_robot_held_up_in_its_own_cell_steps_aside_and_comes_back() -> None:
    # the body ahead is in the robot's own cell A (no passage here): nothing is left out;
    # the only own sub-cell next to (1, 0) is (1, 1)
    robot = walker((1, 0), ceded=False)
    flow = passage.reach(cast(Robot, robot), (0, 0), A)
    (reached, over), asked = drive(flow, robot, taken={(0, 0)},
                                   free_after=passage.STEP_ASIDE_AFTER)
    tries = passage.STEP_ASIDE_AFTER - 1  # bumps in reach(); the first was before it
    assert asked == [(0, 0)] * tries + [(1, 1), (1, 0), (0, 0)], asked
    assert (reached, over) == ((0, 0), False) and robot.decided == {}


def test_a_robot_done_in_a_passage_moves_to_the_nearest_cell_it_still_owns() -> None:
    robot = walker((0, 3))
    value, asked = drive(passage.leave_passage(cast(Robot, robot)), robot, taken=set())
    assert value is None and asked == [(0, 2), (0, 1)] and cell_of(robot.pos) == A
    # held up on the way: it gives up after a few tries and stays (it is asked again later)
    robot = walker((0, 3))
    _value, asked = drive(passage.leave_passage(cast(Robot, robot)), robot, taken={(0, 2)})
    assert asked.count((0, 2)) == passage.DETOUR_AFTER and robot.pos == (0, 3)
    # nothing to do in a cell of its own
    robot = walker((0, 1))
    assert drive(passage.leave_passage(cast(Robot, robot)), robot, taken=set())[1] == []


def test_a_walk_to_a_takeover_says_when_a_body_for_good_stands_on_its_target() -> None:
    # robot in A at (1, 1), walking on to (1, 2): a body there that never moves
    robot = walker((1, 1), ceded=False, hold_up=1.0)
    reached, asked = drive(passage.walk_step(cast(Robot, robot), (1, 2), (1, 2)), robot,
                           taken={(1, 2)})
    assert reached is False and robot.pos == (1, 1)
    assert asked.count((1, 2)) == passage.STUCK_AFTER
    # a body that moves on is followed
    robot = walker((1, 1), ceded=False, hold_up=1.0)
    reached, asked = drive(passage.walk_step(cast(Robot, robot), (1, 2), (1, 2)), robot,
                           taken={(1, 2)}, free_after=4)
    assert reached is True and robot.pos == (1, 2)


# (half_sense, seed, cells a side, robots, density, priority, deaths): forced collisions
# (a claim window of one step) and deaths, bench_forced_collisions.py --wide --deaths
# [--half-sense]. A robot died on the sub-cell a survivor's takeover had to stand on (the
# one facing the link into the dead robot's cells); the survivor bumped into it for ever.
_DEAD_ON_THE_TAKEOVER_SUB_CELL = [
    (True, 185, 4, 4, 0.0, Priority.FEWEST, ((3, 22), (1, 0), (2, 74))),
    (True, 524, 5, 3, 0.15, Priority.FEWEST, ((0, 30), (1, 20))),
    (True, 670, 8, 5, 0.0, Priority.FEWEST, ((3, 66), (4, 68))),
    (False, 376, 7, 6, 0.15, Priority.ID, ((0, 114), (3, 83), (4, 43), (5, 77), (2, 14))),
    (False, 2917, 4, 6, 0.0, Priority.FEWEST, ((1, 18),)),
    (False, 4907, 4, 5, 0.0, Priority.ID, ((1, 44), (4, 8), (0, 26), (2, 69))),
]


@pytest.mark.parametrize(("half", "seed", "size", "k", "density", "priority", "deaths"),
                         _DEAD_ON_THE_TAKEOVER_SUB_CELL)
def test_a_takeover_decides_from_beside_a_body_for_good_and_walks_round_it(
        half: bool, seed: int, size: int, k: int, density: float, priority: Priority,
        deaths: tuple[tuple[int, int], ...], monkeypatch: pytest.MonkeyPatch) -> None:
    world = random_world(seed, size, size, density)
    # the rule taken away: a walk that keeps trying to reach its target never ends
    check_the_rule_ends_it(
        world, random_starts(world, k, seed),
        forced_with_deaths(seed, priority, deaths, half_sense=half),
        lambda: monkeypatch.setattr(watch, "walk_step", never_giving_up(watch.walk_step)))
