"""Trail repair: robots die mid-mission and the survivors still cover the tree, connected.

Lockstep runs with injected failures (planner.treecover.failures: robot r is lost on its way
into step t), the removal of a robot from the state, the refill rule (Lemma 4.1 restored in
one step) and the gather / re-plan fallback.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from treecover_helpers import ALGOS, random_trees

from planner.errors import PlannerError
from planner.treecover.failures import run_with_failures
from planner.treecover.repair import gather_moves, holes, refill_moves
from planner.treecover.sim import run_coverage
from planner.treecover.state import CoverageState
from planner.treecover.team import TeamReplica
from planner.treecover.trees import from_parents, perfect_tree
from planner.treecover.types import Move, Splits


@st.composite
def missions_with_failures(draw: st.DrawFn, same_step: bool):  # type: ignore[no-untyped-def]
    """A tree, a team, an algorithm and up to k - 1 deaths within the undisturbed run."""
    tree = draw(random_trees())
    robots = draw(st.integers(1, 30))
    algo = draw(st.sampled_from(ALGOS))
    horizon = run_coverage(tree, robots, algo).time
    most = robots - 1 if same_step else min(robots - 1, horizon + 1)
    victims = draw(st.lists(st.integers(0, robots - 1), max_size=most, unique=True))
    if same_step:
        steps = [draw(st.integers(0, horizon)) for _ in victims]
    else:  # one death per step boundary: each hole is closed before the next death
        steps = draw(st.lists(st.integers(0, horizon), min_size=len(victims),
                              max_size=len(victims), unique=True))
    return tree, robots, algo, dict(zip(victims, steps, strict=True))


@settings(max_examples=150, deadline=None)
@given(missions_with_failures(same_step=False))
def test_deaths_at_distinct_steps_keep_the_team_connected_and_finish(mission) -> None:  # type: ignore[no-untyped-def]
    tree, robots, algo, failures = mission
    run = run_with_failures(tree, robots, algo, failures)
    result = run.result
    # Lemma 4.1 after every step but the death steps (a lost robot may have been walking to
    # the one node joining the team), the repair steps included
    assert result.connected
    assert run.cut_at_death <= len(failures)
    assert np.all(result.visit_time >= 0)  # every node visited
    assert tree.height <= result.explore_time <= result.time  # a dead robot needs no way back
    assert result.occupied[-1:] in ((), (1,))  # the survivors end together (on the root)


@settings(max_examples=80, deadline=None)
@given(missions_with_failures(same_step=True))
def test_simultaneous_deaths_still_visit_every_node(mission) -> None:  # type: ignore[no-untyped-def]
    # two robots dying on adjacent trail nodes at once leave a gap one step cannot close, so
    # connectivity is not claimed here; completion is
    tree, robots, algo, failures = mission
    result = run_with_failures(tree, robots, algo, failures).result
    assert np.all(result.visit_time >= 0)


@pytest.mark.parametrize("algo", ALGOS)
def test_without_failures_it_is_the_lockstep_run(algo: str) -> None:
    tree = perfect_tree(3, 4)
    plain, failing = run_coverage(tree, 8, algo), run_with_failures(tree, 8, algo, {}).result
    assert failing.time == plain.time and failing.occupied == plain.occupied
    late = run_with_failures(tree, 8, algo, {3: plain.time + 5}).result  # after the end
    assert late.time == plain.time


@pytest.mark.parametrize("algo", ALGOS)
def test_a_death_costs_steps_but_not_coverage(algo: str) -> None:
    tree = perfect_tree(2, 5)
    plain = run_coverage(tree, 11, algo)
    times = [run_with_failures(tree, 11, algo, {robot: 10}).result for robot in range(11)]
    assert all(r.connected and np.all(r.visit_time >= 0) for r in times)
    assert min(r.time for r in times) >= plain.time
    assert max(r.time for r in times) > plain.time  # some robot's loss is felt


def test_bad_failures_are_user_errors() -> None:
    tree = perfect_tree(2, 2)
    with pytest.raises(PlannerError, match="survive"):
        run_with_failures(tree, 2, "cocta", {0: 1, 1: 2})
    with pytest.raises(PlannerError, match=r"robots 0\.\.1"):
        run_with_failures(tree, 2, "cocta", {2: 1})


# --- the state and the repair rule ---------------------------------------------------------

PATH = from_parents(np.array([-1, 0, 1, 2, 3]))  # 0 - 1 - 2 - 3 - 4
FORK = perfect_tree(2, 2)  # 0 - {1, 2}; 1 - {3, 4}; 2 - {5, 6}


def state_with(tree, robots_at: dict[int, int]) -> CoverageState:  # type: ignore[no-untyped-def]
    """A state whose robots stand as given, walked there from the root one edge a step."""
    state = CoverageState(tree, sum(robots_at.values()))
    targets = [node for node, count in sorted(robots_at.items()) for _ in range(count)]
    positions = [0] * len(targets)
    while positions != targets:
        moves = []
        for i, (here, goal) in enumerate(zip(positions, targets, strict=True)):
            if here != goal:
                path = [goal]
                while state.parent[path[-1]] != here:
                    path.append(state.parent[path[-1]])
                moves.append(Move(here, path[-1], 1))
                positions[i] = path[-1]
        state.apply(moves)
    return state


def test_a_robot_lost_entering_a_new_node_leaves_it_unvisited() -> None:
    replica = TeamReplica(FORK, 3, "ncocta", Splits((2,)))
    replica.advance()  # the root keeps one robot and sends one into each child
    assert sorted(replica.positions) == [0, 1, 2]
    entering_1 = replica.positions.index(1)
    replica.remove([entering_1])
    assert replica.state.visit_time[1] == -1 and replica.state.remaining == FORK.n - 2
    assert replica.state.unexplored[0] == FORK.n - 2 and replica.state.unexplored[1] == 3
    assert replica.state.not_finished(0) == brute_not_finished(replica.state, 0)
    while not replica.done():
        replica.advance()
    assert all(t >= 0 for t in replica.state.visit_time)  # the survivors visit it later


def brute_not_finished(state: CoverageState, v: int) -> int:
    """Nodes of T_v with an unexplored node at or below them or a robot strictly below."""
    def below(w: int) -> list[int]:
        out = [w]
        for u in state.children[w]:
            out += below(u)
        return out
    count = 0
    for w in below(v):
        sub = below(w)
        if any(state.visit_time[u] < 0 for u in sub) or any(u in state.at for u in sub[1:]):
            count += 1
    return count


def test_remove_lowers_the_counts_on_the_path_to_the_root() -> None:
    state = state_with(FORK, {0: 1, 1: 1, 3: 2})
    state.remove(3)
    assert state.robots == 3 and state.at == {0: 1, 1: 1, 3: 1}
    assert [state.sub[v] for v in (0, 1, 3, 2)] == [3, 2, 1, 0]
    state.remove(1)
    assert state.at == {0: 1, 3: 1} and state.sub[1] == 1 and state.sub[0] == 2
    with pytest.raises(ValueError, match="no robot"):
        state.remove(4)


def test_a_dead_robot_alone_on_a_trail_node_is_replaced_from_below() -> None:
    state = state_with(PATH, {0: 1, 1: 1, 2: 1, 3: 1, 4: 1})
    state.remove(1)
    assert holes(state) == [1] and not state.connected()
    moves = refill_moves(state)
    assert moves == [Move(2, 1, 1), Move(3, 2, 1), Move(4, 3, 1)]  # the chain climbs
    state.apply(moves)
    assert state.connected() and state.at == {0: 1, 1: 1, 2: 1, 3: 1}


def test_the_pull_stops_at_a_node_that_keeps_a_robot_and_a_spare_parent_comes_down() -> None:
    state = state_with(PATH, {0: 1, 1: 1, 2: 2, 3: 1})
    state.remove(1)
    assert refill_moves(state) == [Move(2, 1, 1)]
    spare = state_with(FORK, {0: 2, 1: 1, 3: 1, 4: 1})
    spare.remove(1)
    assert holes(spare) == [1]
    assert refill_moves(spare) == [Move(0, 1, 1)]


def test_a_dead_top_robot_is_replaced_only_when_it_joined_two_branches() -> None:
    state = state_with(FORK, {1: 1, 3: 1, 4: 1})
    state.remove(1)
    moves = refill_moves(state)
    assert len(moves) == 1 and moves[0].dst == 1
    state.apply(moves)
    assert state.connected()
    leaf_side = state_with(PATH, {2: 1, 3: 1})
    leaf_side.remove(2)
    assert holes(leaf_side) == [] and refill_moves(leaf_side) == []


def test_gathering_keeps_the_team_connected_and_ends_on_the_top_node() -> None:
    state = state_with(FORK, {0: 1, 1: 1, 2: 1, 3: 2, 6: 1})
    while moves := gather_moves(state):
        state.apply(moves)
        assert state.connected()
    assert state.at == {0: 6}


def test_survivors_that_stall_gather_and_replan_down_to_one_search() -> None:
    tree = from_parents(np.array([-1, 0, 0, 1, 2]))
    replica = TeamReplica(tree, 3, "cocta")
    failures = {2: 1, 0: 5}  # the last survivor cannot keep split (1,)'s trail
    while True:
        replica.remove([r for r, s in failures.items() if s == replica.step])
        if replica.done():
            break
        replica.advance()
        assert replica.state.connected()
    assert replica.replans and replica.replans[-1][1] == Splits(())
    assert replica.alive == [False, True, False] and replica.removed == {2: 1, 0: 5}
    assert all(t >= 0 for t in replica.state.visit_time)
