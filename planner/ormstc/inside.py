"""Looking at a cell from inside: grow into a cell half seen, enter it, see the rest.

A thin sonar (agent/ormstc/sensing.py) sees one half of a neighbouring cell from where the
robot stands: the half the walk enters when it grows into that cell. The other half used
to be seen from the sub-cell beside, two look steps for nearly every cell a robot grew into
(docs/ormstc.md, "Look steps in the ratio"). Here the robot claims and grows into the cell
on its near half alone (``CellStatus.HALF``), enters that half — the walk's own next move —
and looks at the rest from inside: one side sonar sees the far sub-cell next to the entry,
and the step on to the second near sub-cell (the walk's move after that) shows the last
one. A cell that turns out to hold an obstacle (one that fills only part of it) or a dead
robot's body (one that owned or claimed the cell is known dead, and no live robot else
owns it: nobody can cover that cell) is given up: the robot steps back and cuts the
edge, as if it had seen it from outside. Any other body is not a reason: it is a live
rival's that grew into the same cell when messages came late (a conflict, conflicts.py,
which the ids resolve; the rival may cede the cell to this robot's edge, so giving it up
could leave it to nobody). The robot then steps back, looks from outside as before, and
keeps the cell unless that look shows an obstacle. A robot that cannot step back (a robot
died on the sub-cell it came from: held up for good, passage.walk_step) keeps the cell and
walks on from inside, where passage.reach walks round what is in the way.

Safety is that of an ordinary grow: the tree edge is broadcast when the claim is won, as
always, so the claim window's argument is unchanged (a later claim hears the edge), and the
body only stands in a cell its robot owns. A cell given up stays owned in the peers' books:
nobody else grows into it, so nobody else bumps into what is in it. The robot says so with a
``RetractionMsg``, which only monitors (and the lockstep's record of the trees) act on: they
stop drawing a tree edge into a blocked cell. The lockstep simulator senses whole cells and
answers ``HALF`` only with ``SimConfig.half_sense``, so its default runs are unchanged; the agents,
tests/test_ormstc_looks.py (the driver's code, one robot) and tests/test_ormstc_inside.py
(the lockstep with ``half_sense``: forced collisions, deaths) drive this path.
"""

from __future__ import annotations

from planner.ormstc.passage import walk_step
from planner.ormstc.robot import ANSWER, Flow, Robot
from planner.ormstc.types import Cell, CellStatus, Move, MoveResult, RetractionMsg, Sense
from planner.ormstc.walk import DELTA, neighbour


def enter_to_look(m: Robot, cell: Cell, side: int) -> Flow:
    """After growing from ``cell`` into its neighbour on ``side`` on the near half alone:
    enter, look at the rest, and give the neighbour up again if it holds an obstacle or a
    dead robot's body (module doc).

    The robot stands on ``cell``'s sub-cell facing ``side`` (the caller checks). On return
    it stands in the neighbour's entry sub-cell (free) or back where it was (given up).
    """
    child = neighbour(cell, side)
    here = m.pos
    entry = (here[0] + DELTA[side][0], here[1] + DELTA[side][1])
    result = yield (ANSWER, Move(entry))
    if isinstance(result, MoveResult) and result.ok:
        m.moved(entry)
        result = yield (ANSWER, Sense((child,)))  # the cell the body stands in
        status = m.sensed(child, result)
        if status is CellStatus.FREE:
            return None
        if not (yield from walk_step(m, here, here)):
            # a robot died where it came from: it cannot step back, so it keeps the cell and
            # the walk goes on from inside (passage.reach walks round what is in the way)
            return None
    else:
        m.bumps += 1
        status = CellStatus.ROBOT
    if status is not CellStatus.OBSTACLE and not _dead_body(m, child):
        # a body that is not a dead robot's: a rival's that grew into the cell too when
        # messages came late (a conflict, which the ids resolve; giving the cell up could
        # leave it to nobody, as the rival may cede it to this robot's edge). Look from
        # outside as before; only an obstacle undoes the grow, else the walk enters as usual
        result = yield (ANSWER, Sense((child,)))
        status = m.sensed(child, result)
        if status is not CellStatus.OBSTACLE:
            return None
    # an obstacle, or a dead robot's body: nobody can cover the cell
    give_up(m, cell, side)
    return None


def _dead_body(m: Robot, cell: Cell) -> bool:
    """Whether a body in ``cell`` may be a dead robot's: a robot known dead owned or claimed
    it, and no live robot but this one owns it."""
    know = m.know
    holders = know.owners.get(cell, ())
    if any(r != m.me and r not in know.dead for r in holders):
        return False  # a live rival's edge came: its body, most likely
    # a live robot's claim alone is weaker evidence than a dead owner's or claimant's: the
    # claim may have lost, while a dead robot's body stays where it died
    return any(r in know.dead for r in holders) or know.claims.claimed_by_any(cell, know.dead)


def give_up(m: Robot, cell: Cell, side: int) -> None:
    """Undo the grow from ``cell`` into its neighbour on ``side`` (machine._grow); the side
    stays decided, so the walk turns to the next sub-cell as for a blocked cell."""
    child = neighbour(cell, side)
    m.mine.discard(child)
    m.ceded.pop(child, None)  # lost in a conflict meanwhile: its winner's anyway
    m.parent.pop(child, None)
    m.edges[cell] = m.edges.get(cell, 0) & ~(1 << side)
    m.edges.pop(child, None)
    m.decided.pop(child, None)
    holders = m.know.owners.get(child)
    if holders is not None and m.me in holders:
        holders.remove(m.me)
        if not holders:
            del m.know.owners[child]
    m.given_up += 1
    m.send(RetractionMsg(m.me, cell, child))

