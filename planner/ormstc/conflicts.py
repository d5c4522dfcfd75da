"""Two live robots owning one cell: detected when it happens, resolved by robot id.

The claim window makes a double owner impossible while every message arrives within half
the window; nothing in the protocol guarantees that (a loaded machine, a router restart that
loses a claim or a tree edge). So a robot that hears a tree edge into a cell it owns itself,
from a robot not known dead, has found a *conflict* (Knowledge queues it). Both owners hear
the other's edge, and both resolve it the same way, from what both surely know — the two
ids: the higher id keeps the cell (the tie-break of both claim priorities; an edge carries
no cell count, so "fewest cells" cannot be decided alike on both sides).

The loser hands the cell over (its knowledge names the winner as the owner) and records a
connection to the winner, without breaking its own STC cycle:

- a leaf of its tree that it is neither standing in nor about to enter is cut off at once
  (the tree edge from its parent is removed; the parent's side stays decided);
- otherwise the cell stays in its tree as a *passage* (``ceded``): the robot grows nothing
  from it, walks through it while it must, and cuts it off as soon as it is a leaf the
  robot has left. A cell that already has children of the loser stays a passage: cutting
  it would split the loser's tree.

A passage is walked by two robots, so it can be covered twice; both walk round the cell in
the same rotational sense, so their bodies follow each other rather than meet head-on.
"""

from __future__ import annotations

from planner.ormstc.robot import Robot
from planner.ormstc.types import (
    Cell,
    CompletionMsg,
    DeadRobotMsg,
    Message,
    Move,
    StartMsg,
    TreeEdgeMsg,
    WithdrawalMsg,
)
from planner.ormstc.walk import cell_of, side_towards


def winner_of(robot: int, other: int) -> int:
    """Who keeps a cell both own: the higher id."""
    return max(robot, other)


def settle(m: Robot) -> None:
    """Resolve the conflicts heard since the last step; cut off passages now leaves."""
    know = m.know
    while know.conflicts:
        cell, other = know.conflicts.pop(0)
        if other in know.dead or (cell, other) in m.conflicts:
            continue  # a dead robot's late edge, or the same conflict heard again
        if cell not in m.mine or cell in m.ceded:
            know.own(cell, other)  # lost earlier in this batch: an ordinary owner now
            continue
        m.conflicts.add((cell, other))
        if winner_of(m.me, other) == m.me:
            continue  # the other robot gives it up; it is not recorded as an owner here
        _hand_over(m, cell, other)
    for cell in [c for c in m.ceded if _may_cut(m, c)]:
        _cut(m, cell, m.ceded.pop(cell))


def _hand_over(m: Robot, cell: Cell, winner: int) -> None:
    """``cell`` is ``winner``'s now, and so is deciding its neighbours; it stays a passage
    of the own tree until it can be cut off."""
    know = m.know
    holders = know.owners.setdefault(cell, [])
    if m.me in holders:
        holders.remove(m.me)
    know.own(cell, winner)
    m.ceded[cell] = winner
    table = m.connections
    for link in [link for link in table.links if link[0] == cell]:
        table.drop(link)
    know.changed = True  # a watching robot re-scans its connections


def _may_cut(m: Robot, cell: Cell) -> bool:
    parent = m.parent.get(cell)
    if parent is None or m.edges.get(cell, 0) != 1 << side_towards(cell, parent):
        return False  # the robot's root, or a cell with children: a passage for good
    if cell_of(m.pos) == cell or cell in m.passing:
        return False
    asked = m.asked
    return not (isinstance(asked, Move) and cell_of(asked.to) == cell)


def _cut(m: Robot, cell: Cell, winner: int) -> None:
    """Remove the leaf ``cell`` from the own tree; connect to its new owner."""
    parent = m.parent.pop(cell)
    m.edges[parent] = m.edges.get(parent, 0) & ~(1 << side_towards(parent, cell))
    m.edges.pop(cell, None)
    m.decided.pop(cell, None)
    m.mine.discard(cell)
    table = m.connections
    for link in [link for link in table.links if link[0] == cell]:
        table.drop(link)  # none normally: _hand_over dropped them and a passage adds none
    table.record(winner, (parent, cell))
    m.cut += 1


def restate(m: Robot) -> list[Message]:
    """What the peers must know of this robot and may have missed: its start, the tree
    edges of the cells it owns (passages excluded), the dead robots it freed, and whether
    it is finished. Hearing any of it twice changes nothing (Knowledge is idempotent)."""
    if m.me not in m.know.starts:
        return []  # not started: the StartMsg is still to come
    out: list[Message] = [StartMsg(m.me, m.home)]
    out += [TreeEdgeMsg(m.me, parent, child) for child, parent in m.parent.items()
            if child not in m.ceded]
    out += [DeadRobotMsg(m.me, dead) for dead in m.freed]
    if m.finished:
        out.append(CompletionMsg(m.me, len(m.mine)))
    elif m.withdrawn_for is not None:
        out.append(WithdrawalMsg(m.me, m.withdrawn_for))
    return out
