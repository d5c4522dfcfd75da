"""Alg. 2 lines 21-36 for an Robot: announce completion, watch, take over.

Back on its start the robot broadcasts completion, then watches: every ``watch_interval`` it
asks whether each robot it has a connection with is alive, and it reacts at once to news of
deaths, completions and withdrawals. A connection into a cell no live robot holds is a
target: the robot withdraws its completion, walks round its own tree to the nearest target
(line 29) and runs the DFS from there.
"""

from __future__ import annotations

import math
from collections.abc import Generator

from planner.ormstc.connections import Link
from planner.ormstc.passage import cover_from_beside, leave_passage, walk_step
from planner.ormstc.robot import WAKE, Action, Flow, Robot
from planner.ormstc.types import CompletionMsg, Done, SubCell, WithdrawalMsg
from planner.ormstc.walk import (
    cell_of,
    predecessor,
    side_towards,
    sub_facing,
    successor,
    walk_index,
)


def watch(m: Robot) -> Flow:
    """Lines 21-36, forever: the machine stays here once its first DFS is over."""
    know, table = m.know, m.connections
    next_poll = m.now
    while True:
        know.changed = False
        targets, retry_at = table.targets(know, m.mine, m.now, mission_over(m))
        if not targets:
            if cell_of(m.pos) in m.ceded:
                yield from leave_passage(m)  # not stand where the winner's walk goes
            if not m.finished:
                m.finished = True
                know.completed.add(m.me)
                m.send(CompletionMsg(m.me, len(m.mine)))
            m.idle = retry_at == math.inf
            if m.idle and mission_over(m) and not m.done_sent:
                m.done_sent = True
                m.outbox.append(Done(m.now))
            if m.now >= next_poll:
                next_poll = m.now + m.config.watch_interval
                for robot in sorted(table.holders() - know.dead):
                    yield from m.ask_alive(robot)
                continue
            yield (WAKE, min(next_poll, retry_at))
            continue
        m.idle = False
        m.done_sent = False
        if m.finished:
            m.finished = False
            know.completed.discard(m.me)
            m.withdrawn_for = table.links[targets[0]]
            m.send(WithdrawalMsg(m.me, m.withdrawn_for))
        for link in targets:
            if table.links[link] in know.dead:
                m.release(table.links[link])
        yield from take_over(m, closest(m, targets))


def mission_over(m: Robot) -> bool:
    return m.finished and m.know.peers_settled()


def closest(m: Robot, targets: list[Link]) -> Link:
    """The target reached soonest walking either way round the own tree (line 29)."""
    n = 4 * len(m.mine)
    index = walk_index(m.pos, m.has_edge, n)

    def distance(link: Link) -> int:
        ahead = index.get(sub_facing(link[0], side_towards(*link)), 0)
        return min(ahead, n - ahead)

    return min(targets, key=distance)


def take_over(m: Robot, link: Link) -> Flow:
    """Lines 30-36: walk to my side of the connection and grow into the freed cell."""
    mine, theirs = link
    side = side_towards(mine, theirs)
    reached = yield from walk_to(m, sub_facing(mine, side))
    m.connections.drop(link)
    if mine not in m.mine:
        return None  # given up in a conflict on the way (planner/ormstc/conflicts.py)
    m.decided[mine] = m.decided.get(mine, 0) & ~(1 << side)
    yield from m.decide(mine, side)  # from beside when a body for good stands there
    if m.has_edge(mine, side):
        yield from (m.cover(mine) if reached else cover_from_beside(m, mine, side))
    return None


def walk_to(m: Robot, target: SubCell) -> Generator[Action, object, bool]:
    """Along the own tree, the shorter way round, to ``target``; False if a body for good
    stands on it (passage.walk_step)."""
    n = 4 * len(m.mine)
    ahead = walk_index(m.pos, m.has_edge, n).get(target, 0)
    step = successor if ahead <= n - ahead else predecessor
    while m.pos != target and cell_of(target) in m.mine:
        reached = yield from walk_step(m, step(m.pos, m.has_edge), target)
        if not reached:
            return False
    return True
