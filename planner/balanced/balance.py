"""Balancing by chains of boundary transfers that keep every region connected.

A *transfer* moves load across one region boundary: a whole cell (4 sub-cells) changes
owner, or a cell is split (2 sub-cells) into two leaves hung off whole cells on opposite
sides of it. A largest region passes one unit along a chain of neighbouring regions to one
that is smaller by more than the unit (breadth-first search over the region graph, shortest
chain first); every middle region gives one and gets one, so only the ends change. A donor
never gives a pinned cell (a start or an anchor) or an articulation cell of its whole cells,
so regions stay connected. When no chain helps, a region hands a neighbour a cell together
with whatever that cell alone connects (relieve.py), or two neighbours are re-split
(reshape.py); split transfers come last because they pin cells for good. Every move lowers
the sum of squared loads, so the loop ends; a cap bounds it anyway.
"""

from __future__ import annotations

import itertools
from collections import deque
from typing import NamedTuple

from planner.balanced.relieve import relieve
from planner.balanced.reshape import reshape_pairs
from planner.balanced.seeds import near_half
from planner.balanced.state import RING_REMOVABLE, SHARED, PartitionState
from planner.balanced.types import LeafCell

WHOLE, SPLIT = 4, 2  # sub-cells moved by one transfer of each kind
_RETRIES = 4  # chains tried per donor when one fails on execution
LOCAL_TEST_SIZE = 64  # regions larger than this try the local cut test first
RESHAPES_PER_ROBOT = 2  # bound the costliest move (see reshape.py): how often,
RESHAPE_PAIRS = 8  # and how many pairs each time


class _Move(NamedTuple):  # a tuple: built thousands of times per plan
    cell: int
    keep: int  # whole cell of the donor that anchors the donor's half (split only)
    anchor: int  # whole cell of the receiver that anchors its half (split only)


def balance(state: PartitionState, max_chains: int) -> int:
    """Run moves until none improves the largest region; returns how many ran."""
    done = 0
    reshapes = 0
    # No partition beats the average; regions hold an even number of sub-cells except where
    # robots share a start cell, so the average rounded up to even is where to stop.
    ideal = -(-sum(state.load) // state.k)
    ideal += ideal % 2
    while done < max_chains:
        top = max(state.load)
        if top <= ideal:
            break
        biggest = [r for r, load in enumerate(state.load) if load == top]
        # Whole cells first; splits pin cells for good, so they come last.
        if any(_improve(state, r, WHOLE) for r in biggest) or relieve(state):
            done += 1
            continue
        if reshapes < RESHAPES_PER_ROBOT * state.k and reshape_pairs(state, RESHAPE_PAIRS):
            reshapes += 1
            done += 1
            continue
        if not any(_improve(state, r, SPLIT) for r in biggest):
            break
        done += 1
    return done


def _improve(state: PartitionState, donor: int, unit: int) -> bool:
    blocked: set[tuple[int, int]] = set()
    for _ in range(_RETRIES):
        chain = _find_chain(state, donor, unit, blocked)
        if chain is None:
            return False
        failed = _execute(state, chain, unit)
        if failed is None:
            # Run the same chain again while it still pays: on large maps one search then
            # moves many cells (each run still lowers the sum of squared loads).
            while state.load[donor] - state.load[chain[-1]] > 2 * unit \
                    and state.load[donor] == max(state.load) \
                    and _execute(state, chain, unit) is None:
                pass
            return True
        blocked.add(failed)
    return False


def _moves(state: PartitionState, giver: int, taker: int | None, unit: int) -> list[_Move]:
    """Every transfer of ``unit`` from ``giver`` to ``taker`` (to any region when None)."""
    whole = state.whole[giver]
    if len(whole) < 2:
        return []
    if not _exact(state, giver):
        return _moves_of_large(state, giver, taker, unit)
    label, neighbours, pins, bordering = (state.label, state.neighbours, state.pins,
                                          state.bordering)
    out: list[_Move] = []
    for u in whole:
        if not bordering[u] or u in pins \
                or (taker is not None and taker not in [label[v] for v in neighbours[u]]):
            continue
        found = _moves_of(state, giver, taker, unit, u)
        if found and not state.is_cut(giver, u):  # only cells with a move need the test
            out.extend(found)
    return out


def _exact(state: PartitionState, giver: int) -> bool:
    """Whether moves out of ``giver`` skip exactly its cut cells (else see _moves_of_large)."""
    return state.has_cut_cells(giver) or len(state.whole[giver]) <= LOCAL_TEST_SIZE


def _moves_of_large(state: PartitionState, giver: int, taker: int | None,
                    unit: int) -> list[_Move]:
    """_moves for a large region that changed since its cut cells were last computed.

    Exact cut cells cost a pass over the region, so the constant-time local test decides
    instead, and only if it clears no cell with a move are the exact cells paid for (a cell
    on a loop may be removable). Computing them caches them, which makes the region exact
    (_exact) until it changes again.
    """
    out: list[_Move] = []
    unsure: list[int] = []
    bordering = state.bordering
    for u in state.whole[giver]:
        if not bordering[u] or state.pinned(u):
            continue
        found = _moves_of(state, giver, taker, unit, u)
        if not found:
            continue  # an inner cell: no removability test needed
        if not state.locally_removable(giver, u):
            unsure.append(u)
            continue
        out.extend(found)
    if not out and unsure:
        cut = state.cut_cells(giver)
        for u in unsure:
            if u not in cut:
                out.extend(_moves_of(state, giver, taker, unit, u))
    return out


def _moves_of(state: PartitionState, giver: int, taker: int | None, unit: int,
              u: int) -> list[_Move]:
    label, w = state.label, state.width
    out: list[_Move] = []
    for v in state.neighbours[u]:
        y = label[v]
        if y < 0 or y == giver or (taker is not None and y != taker):
            continue
        if unit == WHOLE:
            out.append(_Move(u, -1, v))
            continue
        keep = 2 * u - v  # the cell on the far side of u from v
        same_line = keep // w == u // w or keep % w == u % w
        if 0 <= keep < len(label) and same_line and label[keep] == giver:
            out.append(_Move(u, keep, v))
    return out


def _find_chain(state: PartitionState, donor: int, unit: int,
                blocked: set[tuple[int, int]]) -> list[int] | None:
    """Shortest chain of regions from ``donor`` to one that can take ``unit`` and gain.

    A search that fails with no hop left out proves that no region it reached can reach a
    taker at or below its limit; while the partition is unchanged (PartitionState.version,
    which a rolled-back chain restores) later searches with that unit and a limit no higher
    skip those regions.
    Many largest regions tie on large k and their searches overlap: this makes the repeats
    cost a lookup instead of a pass over the region graph.
    """
    limit = state.load[donor] - unit - 1
    if state.lowest_load() > limit:
        return None  # no region could take it: spare the search its region scans
    dead = _dead_regions(state, unit, limit)
    if donor in dead:
        return None
    parent = {donor: donor}
    queue = deque([donor])
    while queue:
        x = queue.popleft()
        for y in _takers(state, x, unit):
            if y in parent or y in dead or (x, y) in blocked:
                continue
            parent[y] = x
            if state.load[y] <= limit:
                chain = [y]
                while chain[-1] != donor:
                    chain.append(parent[chain[-1]])
                return chain[::-1]
            queue.append(y)
    if not blocked:  # with hops left out, the regions reached may reach a taker after all
        dead.update(parent)
    return None


def _dead_regions(state: PartitionState, unit: int, limit: int) -> set[int]:
    """Regions known (this state version) to reach no region of load <= ``limit``."""
    key, found = state.dead_ends.get(unit, (None, set()))
    if key is None or key[0] != state.version or key[1] < limit:
        found = set()
    state.dead_ends[unit] = ((state.version, limit), found)
    return found


def _takers(state: PartitionState, giver: int, unit: int) -> list[int]:
    """Regions ``giver`` can pass ``unit`` to now (cached until the partition changes).

    Failed chain searches repeat for every largest region and retry; the cache makes the
    repeats cheap.
    """
    hit = state.takers.get((giver, unit))
    if hit is not None and hit[0] == state.region_version[giver]:
        return hit[1]
    found = _taker_scan(state, giver, unit)
    state.takers[(giver, unit)] = (state.region_version[giver], found)
    return found


def _taker_scan(state: PartitionState, giver: int, unit: int) -> list[int]:
    """The owners of the anchors of _moves(state, giver, None, unit), sorted.

    Without building the moves, and a cell that would add no new taker needs no cut test
    (PartitionState.is_cut): this runs thousands of times per plan.
    """
    whole = state.whole[giver]
    if len(whole) < 2 or not _exact(state, giver):
        return sorted({state.label[m.anchor] for m in _moves(state, giver, None, unit)})
    label, neighbours, pins = state.label, state.neighbours, state.pins
    found: set[int] = set()
    # Cells the local test cannot clear wait until the others are done: most add no taker
    # by then, and the region's cut cells (a pass over it, most of a scan's cost at
    # k = 300) are computed only if one still would. The same set either way; the cut
    # cells cached or not decide nothing for a region _exact takes without them.
    unsure: list[tuple[int, list[int]]] = []
    cut = state.cached_cut_cells(giver)  # nothing in the first loop computes it
    ring, bordering = state.ring, state.bordering
    for u in whole:
        if not bordering[u] or u in pins:
            continue
        if unit == WHOLE:
            fresh = [y for v in neighbours[u]
                     if (y := label[v]) >= 0 and y != giver and y not in found]
        else:
            fresh = [y for y in _takers_of(state, giver, unit, u) if y not in found]
        if not fresh:
            continue
        if cut is not None:
            if u not in cut:
                found.update(fresh)
            continue
        mask = 0  # PartitionState.locally_removable, inlined: this is the inner loop
        for bit, v in ring[u]:
            if label[v] == giver:
                mask |= bit
        if RING_REMOVABLE[mask]:
            found.update(fresh)
        else:
            unsure.append((u, fresh))
    for u, fresh in unsure:
        if any(y not in found for y in fresh) and not state.is_cut(giver, u):
            found.update(fresh)
    return sorted(found)


def _takers_of(state: PartitionState, giver: int, unit: int, u: int) -> set[int]:
    """The regions of the anchors of _moves_of(state, giver, None, unit, u)."""
    label, w = state.label, state.width
    out: set[int] = set()
    for v in state.neighbours[u]:
        y = label[v]
        if y < 0 or y == giver or y in out:
            continue
        if unit == SPLIT:
            keep = 2 * u - v
            same_line = keep // w == u // w or keep % w == u % w
            if not (0 <= keep < len(label) and same_line and label[keep] == giver):
                continue
        out.add(y)
    return out


def _execute(state: PartitionState, chain: list[int], unit: int) -> tuple[int, int] | None:
    """Transfer along ``chain`` from its far end back; None, or the hop that failed."""
    state.begin()
    for giver, taker in reversed(list(itertools.pairwise(chain))):
        if unit == WHOLE and len(state.whole[giver]) >= 2 and _exact(state, giver):
            cell = _best_whole_cell(state, giver, taker)
            if cell < 0:
                state.rollback()
                return (giver, taker)
            state.release(giver, cell)
            state.claim(taker, cell)
            continue
        moves = _moves(state, giver, taker, unit)
        if not moves:
            state.rollback()
            return (giver, taker)
        move = max(moves, key=lambda m: _contact(state, m.cell, taker)
                   - _contact(state, m.cell, giver))
        if unit == WHOLE:
            state.release(giver, move.cell)
            state.claim(taker, move.cell)
        else:
            _split(state, giver, taker, move)
    state.commit()
    return None


def _best_whole_cell(state: PartitionState, giver: int, taker: int) -> int:
    """The cell _execute's max over _moves(state, giver, taker, WHOLE) picks (-1: none).

    One pass: the moves of a cell differ only in their anchor, so the first cell of the best
    contact wins, as there. A cell that cannot beat the best so far skips its cut test:
    callers come here only for a region _exact takes, whose cut cells are cached (the test
    is a lookup) or not needed (64 cells or fewer), so skipping a test changes nothing.
    """
    label, neighbours, pins, bordering = (state.label, state.neighbours, state.pins,
                                          state.bordering)
    best, best_gain = -1, 0
    for u in state.whole[giver]:
        if not bordering[u] or u in pins:
            continue
        gain, touches = 0, False
        for v in neighbours[u]:
            y = label[v]
            if y == taker:
                gain += 1
                touches = True
            elif y == giver:
                gain -= 1
        if not touches or (best >= 0 and gain <= best_gain) or state.is_cut(giver, u):
            continue
        best, best_gain = u, gain
    return best


def _contact(state: PartitionState, u: int, region: int) -> int:
    """Neighbours of ``u`` in ``region``.

    Giving cells that touch the taker most and the giver least keeps both compact; a region
    eroded into a one-cell-wide strip could pass nothing on (all its cells would be cuts).
    """
    return sum(1 for v in state.neighbours[u] if state.label[v] == region)


def _split(state: PartitionState, giver: int, taker: int, move: _Move) -> None:
    cell = state.cell(move.cell)
    state.release(giver, move.cell, SHARED)
    for robot, anchor in ((giver, move.keep), (taker, move.anchor)):
        a = state.cell(anchor)
        side = (a[0] - cell[0], a[1] - cell[1])
        state.add_leaf(robot, LeafCell(cell=cell, anchor=a, subs=near_half(cell, side)))
        state.pin(anchor)
