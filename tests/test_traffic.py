"""Deconfliction of crossing walks (planner.offline.traffic) in the lockstep model: robots
meeting head-on in a corridor swap, a robot parked on another's route makes way, and on
generated instances with deaths under ``recovery="rebalance"`` no two bodies ever share a
sub-cell (nor does one enter a sub-cell another is leaving) and every run completes."""

from __future__ import annotations

import random
from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_rebalance import ALGOS, generated, make, random_deaths

from agent.offline.bodies import Bodies
from planner.algorithms import algorithm
from planner.cycle import stc_cycle
from planner.offline.lockstep import TakeoverResult, replay
from planner.offline.machine import Finished, MoveTo, RobotAction, TakeoverDecision
from planner.offline.traffic import LOOK, Go, Hold, Peer, Traffic
from planner.trees import build_tree
from planner.types import Cycle, IntArray, Plan, RobotPlan, SubCell


def corridor(cells: int) -> Cycle:
    """A corridor two sub-cells wide and ``2 * cells`` long (one row of coarse cells)."""
    return stc_cycle(build_tree(np.ones((1, cells), dtype=bool), "dfs", seed=None))


class Scripted:
    """A machine that walks a fixed list of sub-cells and then is done (parked)."""

    def __init__(self, cycle: Cycle, start: SubCell, walk: list[SubCell]) -> None:
        self.cycle = cycle
        self.position = cycle.position(start)
        self._pending = deque(cycle.position(s) for s in walk)

    def on_covered(self, key: int) -> None:
        pass

    def on_dead(self, robot: int) -> None:
        pass

    def on_moved(self) -> int:
        self.position = self._pending.popleft()
        return self.position

    def next_action(self) -> RobotAction:
        if self._pending:
            return MoveTo(self._pending[0], self.cycle.at(self._pending[0]))
        return Finished()

    def pop_decisions(self) -> list[TakeoverDecision]:
        return []

    @property
    def pending_route(self) -> tuple[int, ...]:
        return tuple(self._pending)

    def on_replan(self, route: tuple[int, ...]) -> None:
        self._pending = deque(route)


def check_bodies(timeline: IntArray) -> None:
    """Never two bodies on one sub-cell, never a body into one another held a step before."""
    for t in range(timeline.shape[0]):
        row = timeline[t][timeline[t] >= 0].tolist()
        assert len(set(row)) == len(row), (t, timeline[t])
        if t == 0:
            continue
        for i, place in enumerate(timeline[t].tolist()):
            if place >= 0 and place != timeline[t - 1][i]:
                before = {int(timeline[t - 1][j]) for j in range(timeline.shape[1])
                          if j != i and timeline[t][j] >= 0}
                assert place not in before, (t, i, place)


def run(cycle: Cycle, scripts: list[tuple[SubCell, list[SubCell]]]) -> TakeoverResult:
    machines = [Scripted(cycle, start, walk) for start, walk in scripts]
    ids = list(range(len(scripts)))
    replayed = replay(machines, ids, [m.position for m in machines], {}, 0, cycle.n, cycle.at,
                      bodies=cycle)
    return replayed.result(lambda values, fill: values)


def row(r: int, cols: range) -> list[SubCell]:
    return [(r, c) for c in cols]


def test_two_robots_meeting_head_on_in_a_corridor_swap() -> None:
    cycle = corridor(4)  # sub-cells (0..1, 0..7)
    # robot 0 walks the top row left to right, robot 1 the same row right to left
    result = run(cycle, [((0, 0), row(0, range(1, 8))), ((0, 7), row(0, range(6, -1, -1)))])
    check_bodies(result.timeline)
    assert result.walks[0][-1] == (0, 7) and result.walks[1][-1] == (0, 0)
    # robot 1 (the higher id) stepped aside into the bottom row and back: two detours
    assert [c.detours for c in result.traffic] == [0, 2]
    assert result.traffic[0].waits == 1
    assert any(r == 1 for r, _ in result.walks[1])


def test_a_parked_robot_on_the_route_makes_way() -> None:
    cycle = corridor(4)
    # robot 0 walks the top row; robot 1 has nothing to walk and stands in the middle of it
    result = run(cycle, [((0, 0), row(0, range(1, 8))), ((0, 4), [])])
    check_bodies(result.timeline)
    assert result.walks[0][-1] == (0, 7)
    assert result.walks[1] == ((0, 4), (1, 4))  # one step aside, it stays there
    assert result.traffic[1].detours == 1


def test_three_robots_in_one_corridor_all_arrive() -> None:
    cycle = corridor(5)  # (0..1, 0..9)
    result = run(cycle, [((0, 0), row(0, range(1, 10))), ((0, 9), row(0, range(8, -1, -1))),
                         ((1, 5), [(1, c) for c in range(4, -1, -1)])])
    check_bodies(result.timeline)
    assert [w[-1] for w in result.walks] == [(0, 9), (0, 0), (1, 0)]


def test_the_yielder_is_the_one_every_robot_of_the_ring_names() -> None:
    cycle = corridor(2)
    a, b = cycle.position((0, 1)), cycle.position((0, 2))
    low, high = Traffic(0, cycle, a), Traffic(1, cycle, b)
    # head-on: each one's next place is where the other stands
    assert isinstance(low.decide(b, [Peer(1, b, (a,))]), Hold)
    step = high.decide(a, [Peer(0, a, (b,))])
    assert isinstance(step, Go) and not step.on_plan
    assert cycle.at(step.target) in {(1, 2), (0, 3)}  # beside it, off the other's way


@pytest.mark.slow  # 20-60 s: 25 seeded fleets of up to 13 robots with re-plans (CI only)
@settings(deadline=None, max_examples=25)
@given(seed=st.integers(0, 10_000), algo=st.sampled_from(ALGOS), crowd=st.booleans())
def test_seeded_instances_with_deaths_never_share_a_sub_cell_and_complete(
        seed: int, algo: str, crowd: bool) -> None:
    rng = random.Random(seed)
    k = rng.randrange(2, 14 if crowd else 8)
    area = generated(seed, k)
    plan = make(algo, area, seed)
    deaths = random_deaths(plan, rng, rng.randrange(0, k))
    delay = rng.randrange(0, 4)
    result = algorithm(algo).load_lockstep()(plan, deaths, detection_delay=delay)
    assert result.complete and int(result.covered.sum()) == area.n
    check_bodies(result.timeline)
    assert len(result.traffic) == plan.k


def test_bodies_follow_progress_along_the_route_and_aside() -> None:
    cycle = corridor(4)
    plan_walk = [cycle.position(s) for s in row(0, range(0, 8))]
    bodies = Bodies(cycle, robot=9)
    bodies.on_replan({0: tuple(plan_walk[1:])}, {0: (plan_walk[0], 0.0)})
    assert bodies.walks == {}  # a robot it never heard of is not invented
    bodies = Bodies.of_plan(make("opt", generated(1, 3), 1), robot=0)
    other = next(iter(bodies.walks))
    walk = bodies.walks[other]
    first = walk.route[0]
    assert bodies.on_progress(other, 1, first)
    assert not bodies.on_progress(other, 1, first)  # the same report again is no news
    peer = next(p for p in bodies.peers(()) if p.robot == other)
    assert peer.position == first and peer.ahead[:1] == walk.route[1:2]
    assert bodies.peers({other}) == [p for p in bodies.peers(()) if p.robot != other]


def lossy_walks(cycle: Cycle, scripts: list[tuple[SubCell, list[SubCell]]],
                lost: set[tuple[int, int]], *, beats: int = 0, rng: random.Random | None = None,
                p_lost: float = 0.0, rounds: int = 200) -> tuple[list[int], list[int]]:
    """The fleet's deconfliction without the bus: each robot decides from its own Bodies,
    fed with the others' Progress except the ``lost`` (robot, seq) ones (and, every
    ``beats`` rounds, the others' heartbeat poses); with ``rng``, each Progress and pose is
    also lost for each receiver with probability ``p_lost``. Every round all decide, then a
    Go into a sub-cell held at the start of the round (or entered earlier in it) bumps, as
    simhw refuses it, and the bump is told to the robot's Bodies (as the offline runner
    does). Returns each robot's last place and bumps; asserts that no two bodies ever share
    a sub-cell and that every robot walked its whole script."""
    plan = Plan("opt", cycle, tuple(
        RobotPlan(r, start, cycle.position(start), (), (start, *walk))
        for r, (start, walk) in enumerate(scripts)))
    k = len(scripts)
    knows = [Bodies.of_plan(plan, r) for r in range(k)]
    lanes = [Traffic(r, cycle, cycle.position(start)) for r, (start, _) in enumerate(scripts)]
    pending = [deque(cycle.position(s) for s in walk) for _, walk in scripts]
    seqs = [0] * k

    def told(r: int) -> list[int]:
        return [o for o in range(k) if o != r and (rng is None or rng.random() >= p_lost)]

    for now in range(rounds):
        if not any(pending):
            break
        steps = [lanes[r].decide(pending[r][0] if pending[r] else None,
                                 knows[r].peers(())) for r in range(k)]
        held = {lane.at for lane in lanes}
        for r, step in enumerate(steps):
            if not isinstance(step, Go):
                continue
            if step.target == lanes[r].at:
                pending[r].popleft()
                continue
            if step.target in held:
                lanes[r].bumped()
                knows[r].on_bump(step.target, ())
                continue
            held.add(step.target)
            if step.on_plan:
                pending[r].popleft()
            lanes[r].moved(step)
            seqs[r] += 1
            for other in told(r) if (r, seqs[r]) not in lost else ():
                knows[other].on_progress(r, seqs[r], step.target, now)
        places = [lane.at for lane in lanes]
        assert len(set(places)) == k, places
        for r in range(k) if beats and now % beats == 0 else ():
            for other in told(r):
                knows[other].on_pose(r, places[r], now)
    assert not any(pending), [cycle.at(p[0]) for p in pending if p]
    return [lane.at for lane in lanes], [lane.counts.bumps for lane in lanes]


@pytest.mark.parametrize("lost", [{(0, 3)}, {(1, 3)}, {(0, 3), (1, 3)}])
def test_robots_meeting_head_on_unheard_of_pass_after_their_bumps(
        lost: set[tuple[int, int]]) -> None:
    """Chaos seed 23, trial 49: the Progress of the move that brought a robot face to face
    with another was lost, so the other took the sub-cell for free and bumped into it, again
    and again (or waited for a ring the bumping robot did not see). A bump now places the
    unheard-of body where it was bumped into, and the ring opens."""
    cycle = corridor(4)
    # robot 0 walks the top row left to right, robot 1 right to left; their third moves
    # bring them face to face at (0, 3) / (0, 4)
    ends, bumps = lossy_walks(cycle, [((0, 0), row(0, range(1, 8))),
                                      ((0, 7), row(0, range(6, -1, -1)))], lost)
    assert [cycle.at(e) for e in ends] == [(0, 7), (0, 0)]
    assert all(b <= 1 for b in bumps) and sum(bumps) >= 1


def test_a_replan_places_a_body_where_it_reported_it_stood() -> None:
    """A Progress lost just before a robot stopped to report left its body a step behind in
    the others' knowledge; the re-plan's report tells where it stands."""
    bodies = Bodies.of_plan(make("opt", generated(1, 3), 1), robot=0)
    other = next(iter(bodies.walks))
    first, second, *rest = bodies.walks[other].route[:5]
    assert bodies.on_progress(other, 1, first, 1.0)  # its second move's Progress is lost
    bodies.on_replan({other: tuple(rest)}, {other: (second, 2.0)})
    peer = next(p for p in bodies.peers(()) if p.robot == other)
    assert (peer.position, peer.ahead) == (second, tuple(rest))


def test_a_peer_that_walked_far_along_its_new_route_before_this_re_plan_landed_stays_there(
        ) -> None:
    """Chaos seed 61, trials 465 and 483: every survivor solves the same re-plan, but one
    finished 0.6 s before the other and walked a dozen places of its new route, heard as
    Progress before the slower one applied the re-plan. The slower one put it back where its
    report said it stood (only the first 2 x LOOK places of the new route were searched), so
    its next places were unknown: no ring was seen when the two met head-on, and both waited
    for good. It is now placed along its new route however far it got."""
    cycle = corridor(16)  # sub-cells (0..1, 0..31)
    walk = [cycle.position(s) for s in row(0, range(32))]
    plan = Plan("opt", cycle, (RobotPlan(0, (1, 0), cycle.position((1, 0)), (), ((1, 0),)),
                               RobotPlan(1, (0, 0), walk[0], (), tuple(cycle.at(w) for w in walk))))
    bodies = Bodies.of_plan(plan, robot=0)
    other = 1
    # its re-plan: from where it reported it stood, walk back the way it came
    base = walk[28]
    new = tuple(walk[27::-1])
    walked = 3 * LOOK
    for seq, place in enumerate(new[:walked], start=1):
        assert bodies.on_progress(other, seq, place, 10.0 + seq)
    bodies.on_replan({other: new}, {other: (base, 10.0)})
    peer = next(p for p in bodies.peers(()) if p.robot == other)
    assert (peer.position, peer.ahead) == (new[walked - 1], new[walked:walked + LOOK])
    # and its next Progress is read along the new route
    assert bodies.on_progress(other, walked + 1, new[walked], 11.0 + walked)
    peer = next(p for p in bodies.peers(()) if p.robot == other)
    assert (peer.position, peer.ahead) == (new[walked], new[walked + 1:walked + 1 + LOOK])


def test_a_peer_that_walked_on_and_stepped_aside_before_this_re_plan_landed_is_expected_back(
        ) -> None:
    """The likely cause of a CI rehearsal's stall (2026-12-05): a survivor walked part of its
    new route, then stepped aside for a robot, all before a slower survivor applied the
    re-plan. Its latest place was off its new route, so it was put back where it reported,
    and its next heartbeat placed it off its route with next places unknown: a robot it
    waited on then waited on it, for good. It is now placed aside, expected back where it
    left its route."""
    cycle = corridor(16)  # sub-cells (0..1, 0..31)
    top = [cycle.position(s) for s in row(0, range(32))]
    plan = Plan("opt", cycle, (RobotPlan(0, (1, 31), cycle.position((1, 31)), (), ((1, 31),)),
                               RobotPlan(1, (0, 0), top[0], (), tuple(cycle.at(w) for w in top))))
    bodies = Bodies.of_plan(plan, robot=0)
    other = 1
    base, new = top[20], tuple(top[19::-1])  # its re-plan: back along the top row
    assert bodies.on_progress(other, 20, base, 20.0)  # then it stopped and reported
    walked = 6
    for seq, place in enumerate(new[:walked], start=21):
        assert bodies.on_progress(other, seq, place, float(seq))
    aside = cycle.position((1, cycle.at(new[walked - 1])[1]))  # below its latest place
    assert bodies.on_progress(other, 21 + walked, aside, 21.0 + walked)
    bodies.on_replan({other: new}, {other: (base, 20.5)})
    peer = next(p for p in bodies.peers(()) if p.robot == other)
    assert peer.position == aside and peer.returning and not peer.lost
    assert peer.ahead == (new[walked - 1], *new[walked:walked + LOOK - 1])
    assert not bodies.on_pose(other, aside, 30.0)  # its heartbeat agrees: nothing changes
    # the report's own time: nothing heard of since, so it stands where it reported
    bodies = Bodies.of_plan(plan, robot=0)
    assert bodies.on_progress(other, 20, base, 20.0)
    bodies.on_replan({other: new}, {other: (base, 20.0)})
    peer = next(p for p in bodies.peers(()) if p.robot == other)
    assert (peer.position, peer.ahead) == (base, new[:LOOK])


def test_a_robot_waited_on_by_a_body_whose_next_places_are_lost_opens_the_ring() -> None:
    """Robot 1 wants the sub-cell robot 0 stands on, and robot 0 (in truth waiting for robot
    1's) is known only by its place: its next places are lost. Taking it for parked, robot 1
    waited for it while robot 0, seeing the ring, waited for robot 1, the higher id, to step
    aside. A blocker whose next places are lost counts as a ring: the same yielder."""
    cycle = corridor(4)
    a, b = cycle.position((0, 3)), cycle.position((0, 4))
    lane = Traffic(1, cycle, b)
    lost = Peer(0, a, lost=True)
    step = lane.decide(a, [lost])
    assert isinstance(step, Go) and not step.on_plan and step.target not in (a, b)
    lane.moved(step)
    # aside, it waits there while the body stands as it was (else the two take turns)
    assert lane.decide(a, [lost]) == Hold(0)
    # robot 0 took the place it waited for: robot 1 walks back once that one has moved on
    assert lane.decide(a, [Peer(0, b)]) == Hold(0)
    assert lane.decide(a, [Peer(0, cycle.position((1, 7)))]) == Go(b, on_plan=False)
    # robot 0 sees the ring and names robot 1 too: it holds
    assert Traffic(0, cycle, a).decide(b, [Peer(1, b, (a,))]) == Hold(1)
    # a body known to be parked there is waited for, as before (it makes way itself)
    assert Traffic(1, cycle, b).decide(a, [Peer(0, a)]) == Hold(0)


def test_a_body_heard_of_again_after_many_lost_messages_is_placed_along_its_route() -> None:
    """More Progress messages than the search window lost in a row (a link down for a few
    seconds): the next place heard of, a heartbeat's pose or a Progress, lies past the
    window. It used to move the body but not its progress along the route, so its next
    places were unknown (or read from long ago) until a re-plan."""
    cycle = corridor(16)  # sub-cells (0..1, 0..31)
    walk = [cycle.position(s) for s in row(0, range(32))]
    plan = Plan("opt", cycle, (RobotPlan(0, (1, 0), cycle.position((1, 0)), (), ((1, 0),)),
                               RobotPlan(1, (0, 0), walk[0], (), tuple(cycle.at(w) for w in walk))))
    bodies = Bodies.of_plan(plan, robot=0)
    assert bodies.on_progress(1, 1, walk[1], 1.0)
    far = 1 + 3 * LOOK  # Progress 2 .. far - 1 lost
    assert bodies.on_pose(1, walk[far], 2.0)
    peer = next(p for p in bodies.peers(()) if p.robot == 1)
    assert (peer.position, peer.ahead) == (walk[far], tuple(walk[far + 1:far + 1 + LOOK]))
    assert bodies.on_progress(1, far + 1, walk[far + 1], 3.0)  # and on from there
    peer = next(p for p in bodies.peers(()) if p.robot == 1)
    assert (peer.position, peer.ahead) == (walk[far + 1], tuple(walk[far + 2:far + 2 + LOOK]))


def test_a_step_aside_beyond_the_window_is_not_read_as_progress() -> None:
    """A body beside the place where it left its route stepped aside, even where its route
    passes that sub-cell much later: its progress stays, and it is expected back."""
    cycle = corridor(16)
    there = [cycle.position(s) for s in row(0, range(32))]
    back = [cycle.position(s) for s in row(1, range(31, -1, -1))]
    walk = there + back  # along the top row and back along the bottom one
    plan = Plan("opt", cycle, (RobotPlan(0, (1, 31), cycle.position((1, 31)), (), ((1, 31),)),
                               RobotPlan(1, (0, 0), walk[0], (),
                                         tuple(cycle.at(w) for w in walk))))
    bodies = Bodies.of_plan(plan, robot=0)
    assert bodies.on_progress(1, 1, walk[1], 1.0)
    aside = cycle.position((1, 1))  # below walk[1]; the route comes there 61 places later
    assert bodies.on_pose(1, aside, 2.0)
    assert bodies.walks[1].done == 1
    peer = next(p for p in bodies.peers(()) if p.robot == 1)
    assert peer.position == aside and peer.ahead[:1] == (walk[1],)


def test_a_robot_that_stepped_aside_unheard_of_is_seen_by_its_heartbeat() -> None:
    """Robot 1 opens the head-on ring by stepping aside (its fourth move), and that Progress
    is lost: robot 0 would wait for good for the body it still thinks in its way, while
    robot 1 waits aside for robot 0 to pass. Robot 1's heartbeat pose tells where it is."""
    cycle = corridor(4)
    ends, _ = lossy_walks(cycle, [((0, 0), row(0, range(1, 8))),
                                  ((0, 7), row(0, range(6, -1, -1)))], {(1, 4)}, beats=1)
    assert [cycle.at(e) for e in ends] == [(0, 7), (0, 0)]


def test_a_heartbeat_older_than_the_place_known_changes_nothing() -> None:
    bodies = Bodies.of_plan(make("opt", generated(1, 3), 1), robot=0)
    other = next(iter(bodies.walks))
    start, first, second = bodies.walks[other].base, *bodies.walks[other].route[:2]
    assert bodies.on_progress(other, 1, first, 2.0)
    assert not bodies.on_pose(other, start, 1.0)  # a delayed heartbeat from before the move
    assert not bodies.on_pose(other, first, 2.5)  # where it is known to stand already
    assert bodies.on_pose(other, second, 3.0)  # its second move's Progress was lost
    bodies.on_progress(other, 2, second, 3.0)  # ... and arrives late: nothing moves on
    peer = next(p for p in bodies.peers(()) if p.robot == other)
    assert peer.position == second and peer.ahead[:1] == bodies.walks[other].route[2:3]


@pytest.mark.parametrize("case", ["head-on", "three", "parked"])
def test_walks_complete_when_progress_and_heartbeats_are_lost(case: str) -> None:
    """A third of all Progress messages and heartbeat poses lost (each for each receiver),
    heartbeats every third step: every walk completes, no sub-cell ever held by two. (Without
    the heartbeats' poses, robots that met or stepped aside or parked unheard of blocked each
    other for good in 20-37 of these 60 seeds per case; without the bumps' evidence too, in
    28-37.)"""
    long = corridor(5)
    scripts = {
        "head-on": [((0, 0), row(0, range(1, 10))), ((0, 9), row(0, range(8, -1, -1)))],
        "three": [((0, 0), row(0, range(1, 10))), ((0, 9), row(0, range(8, -1, -1))),
                  ((1, 5), [(1, c) for c in range(4, -1, -1)])],
        "parked": [((0, 0), row(0, range(1, 10))), ((0, 4), [])],
    }[case]
    for seed in range(60):
        lossy_walks(long, scripts, set(), beats=3, rng=random.Random(seed), p_lost=0.3)
