"""Bodies that hold each other up: a robot walks round them, steps aside, or moves out.

A passage (conflicts.py) is a cell the robot lost in a conflict and still walks, because it
stands in it or has children behind it. Its winner walks it too, and so may other robots
that lost it, so bodies meet there. Forced collisions in the lockstep simulator found runs
that never ended (12 of 36 000 on 4 x 4 worlds; none with these rules): four bodies in the
four sub-cells of one passage, each waiting for the next one's sub-cell; a loser and the
winner head-on in it; and a robot that finished in a cell another robot's walk needs,
standing there for good.
Four rules, all in the robot's own cells ("a body only stands in a cell its robot owns or
claims" holds throughout):

- **Walk round a passage.** Nothing in a passage is the loser's to cover or decide, so
  when its move into a passage's sub-cell bumps ``DETOUR_AFTER`` times in a row, the loser
  looks at its walk from that sub-cell on through the passages (no decisions there: the
  walk only follows its own tree edges) and takes a shortest way over its own cells,
  round the sub-cells it bumped into, to the sub-cell of that stretch from which it gets
  to the stretch's end (the first sub-cell past the passages, or the walk's end) in the
  fewest moves. The walk goes on from there as if it had walked the sub-cells it left out.
- **Step aside.** A robot held up ``STEP_ASIDE_AFTER`` times in a row in its own cells
  steps to a sub-cell of its own next to it (when there is one), backs off, and comes
  back: the body in its way may be waiting for the sub-cell it stands on.
- **Walk round a body for good in the way** (last resort). A robot held up
  ``STUCK_AFTER`` times in all (and four hold-ups) on a sub-cell of its own decides that
  sub-cell's side from where it stands, if it is still undecided, and leaves the sub-cell
  out as it would a passage's. A robot that died there (a loser in its passage, seen with
  forced collisions and deaths) never moves again, and the sub-cell under a body cannot be
  covered anyway.
  The same holds on the way to a takeover (``walk_step``), where nothing is left out.
  When the body for good stands on the sub-cell the takeover must stand on (a robot died
  facing the link: forced collisions with deaths), the robot decides the link's side from
  beside and covers what it grew into by a way round that sub-cell
  (``cover_from_beside``), as ``reach`` does in a walk.
- **Move out of a passage when done.** A robot that has nothing left to do and stands in a
  passage (its start cell was lost, perhaps after it finished) moves to the nearest
  sub-cell of a cell it still owns, if it has one, rather than stand where the winner's
  walk goes.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Generator, Iterable

from planner.geometry import sub_cells_of
from planner.ormstc.robot import ANSWER, UNTIL, Action, Flow, Robot
from planner.ormstc.types import Cell, Move, MoveResult, SubCell
from planner.ormstc.walk import DELTA, cell_of, neighbour, side_of, sub_facing, successor

# Both need the robot held up for ``MachineConfig.hold_up`` too (twice that to step aside):
# an agent backs off for tens of ms after a bump, and a body ahead may take seconds to move.
DETOUR_AFTER = 3  # bumps in a row into one sub-cell before a way round it is looked for
STEP_ASIDE_AFTER = 6  # bumps in a row, in the robot's own cells, before it steps aside
STUCK_AFTER = 12  # bumps in all before a body in the robot's own cell is walked round
AHEAD = 64  # walk sub-cells looked at from the blocked one (a passage is a few cells)


def walk_ahead(m: Robot, blocked: SubCell, root: Cell) -> tuple[list[SubCell], bool]:
    """The walk's sub-cells from ``blocked`` on while they are in passages, and whether the
    last one ends the walk (re-entering ``root`` on a decided side, as ``cover`` tests).

    The last sub-cell is the first one past ``blocked`` outside the passages, the walk's
    end, or the ``AHEAD``-th. Passages decide nothing, so the walk there follows the tree
    edges alone; ``blocked`` itself may be in the robot's own cell when standing on it
    would decide nothing (``reach``'s last resort).
    """
    bits: dict[Cell, int] = {}
    ahead: list[SubCell] = []
    sub = blocked
    for _ in range(AHEAD):
        cell, side = cell_of(sub), side_of(sub)
        decided = bits.get(cell, m.decided.get(cell, 0))
        ahead.append(sub)
        if cell == root and decided >> side & 1:
            return ahead, True
        if cell not in m.ceded and sub != blocked:
            return ahead, False  # the first sub-cell past the passages (and the blocked one)
        bits[cell] = decided | 1 << side
        sub = successor(sub, m.has_edge)
    return ahead, False


def way_round(m: Robot, goals: list[SubCell], avoid: set[SubCell], *,
              nearest: bool = False) -> list[SubCell] | None:
    """A shortest way from the robot's sub-cell over its own cells, round ``avoid``, to one
    of ``goals`` (a list of sub-cells, the goal last; None if it reaches none).

    ``goals`` is a stretch of the walk: the goal is the one that brings the robot to the
    stretch's end in the fewest moves (the way there, then the walk on), the earliest on a
    tie; with ``nearest``, simply the nearest.
    """
    came: dict[SubCell, SubCell | None] = {m.pos: None}
    dist = {m.pos: 0}
    queue = deque([m.pos])
    while queue:
        here = queue.popleft()
        for dr, dc in DELTA:
            there = (here[0] + dr, here[1] + dc)
            if there not in came and there not in avoid and cell_of(there) in m.mine:
                came[there] = here
                dist[there] = dist[here] + 1
                queue.append(there)
    last = len(goals) - 1
    costs = [(dist[goal] + (0 if nearest else last - index), index)
             for index, goal in enumerate(goals) if goal in dist and goal not in avoid]
    if not costs:
        return None
    best = goals[min(costs)[1]]
    if best == m.pos:
        return None
    route: list[SubCell] = []
    node: SubCell | None = best
    while node is not None and node != m.pos:
        route.append(node)
        node = came[node]
    return route[::-1]


def _left_out(m: Robot, skipped: Iterable[SubCell]) -> None:
    """Decide the sides of sub-cells left out, as walking them would have."""
    for sub in skipped:
        cell = cell_of(sub)
        m.decided[cell] = m.decided.get(cell, 0) | 1 << side_of(sub)


def reach(m: Robot, nxt: SubCell, root: Cell) -> Generator[Action, object, tuple[SubCell, bool]]:
    """After a bump: move on to ``nxt``, stepping aside now and then, or round it when it
    is a passage's and stays taken (or, the last resort, is taken for good and needs no
    decision). Returns ``(sub-cell reached, walk over)``; the first move is tried after a
    back-off."""
    avoid: set[SubCell] = set()
    route, ahead, ends = [nxt], [nxt], False
    fails, asides, since = 1, 0, m.now  # the first bump was just before
    bumped, began = 1, m.now
    hold_up = m.config.hold_up
    try:
        while True:
            yield (UNTIL, m.now + m.backoff())
            while route:
                step = route[0]
                result = yield (ANSWER, Move(step))
                if not (isinstance(result, MoveResult) and result.ok):
                    break
                m.moved(step)
                route.pop(0)
                fails, since = 0, m.now
            else:
                goal = m.pos  # nxt, or a sub-cell of the latest stretch looked at
                _left_out(m, ahead[:ahead.index(goal)] if goal in ahead else ())
                return goal, ends and goal == ahead[-1]
            m.bumps += 1
            fails += 1
            bumped += 1
            held = m.now - since
            if fails < DETOUR_AFTER or held < hold_up:
                continue
            stepping = fails >= STEP_ASIDE_AFTER and held >= 2 * hold_up
            stuck = bumped >= STUCK_AFTER and m.now - began >= 4 * hold_up
            if stuck and not _no_decision_at(m, nxt):
                # decide its side from here, as standing on it would have (the machine's
                # decisions do not depend on where the body is)
                yield from m.decide(cell_of(nxt), side_of(nxt))
            if cell_of(nxt) not in m.ceded and not stuck:
                aside = _aside(m, route[0], asides) if stepping else None
                if aside is not None:
                    route, fails, asides, since = [aside, m.pos, *route], 0, asides + 1, m.now
                continue
            avoid.add(route[0])
            ahead, ends = walk_ahead(m, nxt, root)
            m.passing = {cell_of(sub) for sub in ahead}
            if ends and ahead == [nxt]:
                return m.pos, True  # the walk's last step is the one held up
            found = way_round(m, ahead, avoid)
            if found is None and len(avoid) > 1:
                # bodies move on: a sub-cell bumped into earlier may be free by now
                avoid = {route[0]}
                found = way_round(m, ahead, avoid)
            if found is None and stepping:
                aside = _aside(m, route[0], asides)
                found = None if aside is None else [aside, m.pos, *route]
                asides += 1
            if found is not None:
                route, fails, since = found, 0, m.now
    finally:
        m.passing = set()


def _no_decision_at(m: Robot, sub: SubCell) -> bool:
    """Whether standing on ``sub`` would decide nothing: its side is decided already, or
    faces a cell of the robot's own or a known obstacle (then the bit is set here)."""
    cell, side = cell_of(sub), side_of(sub)
    bits = m.decided.get(cell, 0)
    if bits >> side & 1:
        return True
    other = neighbour(cell, side)
    return other in m.mine or other in m.know.obstacle


def _aside(m: Robot, blocked: SubCell, turn: int) -> SubCell | None:
    """A sub-cell of the robot's own cells next to it, other than ``blocked``: out of the
    cell it stands in first (stepping within a crowded cell frees nothing), the choice
    turning with ``turn`` so that a robot that cannot step one way tries the next."""
    r, c = m.pos
    here = cell_of(m.pos)
    free = [(r + dr, c + dc) for dr, dc in DELTA
            if (r + dr, c + dc) != blocked and cell_of((r + dr, c + dc)) in m.mine]
    out = [sub for sub in free if cell_of(sub) != here]
    choices = out or free
    return choices[turn % len(choices)] if choices else None


def walk_step(m: Robot, to: SubCell, target: SubCell) -> Generator[Action, object, bool]:
    """One step of a walk over the robot's own cells to ``target`` (watch.walk_to, on the
    way to a takeover): a body for good in the way (held up ``STUCK_AFTER`` times and four
    hold-ups) is walked round by a shortest way to ``target``; the cells on the way are
    walked already, so nothing is left out. False when the body for good stands on
    ``target`` itself (a robot died there): no way round leads onto it."""
    route, bumped, began = [to], 0, m.now
    while route:
        result = yield (ANSWER, Move(route[0]))
        if isinstance(result, MoveResult) and result.ok:
            m.moved(route.pop(0))
            continue
        m.bumps += 1
        bumped += 1
        if bumped >= STUCK_AFTER and m.now - began >= 4 * m.config.hold_up:
            if route[0] == target:
                return False
            found = way_round(m, [target], {route[0]}, nearest=True)
            if found is not None:
                route, bumped, began = found, 0, m.now
        yield (UNTIL, m.now + m.backoff())
    return True


def cover_from_beside(m: Robot, cell: Cell, side: int) -> Flow:
    """Cover what the robot just grew into from ``cell`` on ``side`` (a takeover) when the
    sub-cell facing it holds a body for good: the walk from that sub-cell on, round it by
    a shortest way over the robot's own cells to the walk's first sub-cell it can reach
    (``way_round`` weighs the way there against the walk left), then on as ``cover``."""
    facing = sub_facing(cell, side)
    ahead: list[SubCell] = []  # the walk from ``facing`` on until it is back in ``cell``
    sub = successor(facing, m.has_edge)
    while cell_of(sub) != cell and len(ahead) < AHEAD:
        ahead.append(sub)
        sub = successor(sub, m.has_edge)
    avoid = {facing}
    while m.pos not in ahead:
        found = way_round(m, ahead, avoid)
        if found is None:
            return None  # walled in by bodies: what it grew into cannot be reached
        if not (yield from walk_step(m, found[0], found[-1])):
            avoid.add(found[-1])  # a body for good on that one too
    _left_out(m, ahead[:ahead.index(m.pos)])
    yield from m.cover(cell)  # on from here, as from ``facing``, until back in ``cell``
    return None


def leave_passage(m: Robot) -> Flow:
    """Out of a passage to the nearest sub-cell of a cell still owned (for a robot done)."""
    if cell_of(m.pos) not in m.ceded:
        return None
    owned = [sub for cell in sorted(m.mine) if cell not in m.ceded
             for sub in sub_cells_of(cell)]
    for step in way_round(m, owned, set(), nearest=True) or ():
        for _attempt in range(DETOUR_AFTER):
            result = yield (ANSWER, Move(step))
            if isinstance(result, MoveResult) and result.ok:
                m.moved(step)
                break
            m.bumps += 1
            yield (UNTIL, m.now + m.backoff())
        else:
            return None  # held up: stay, and try again when next idle
    return None
