"""The relieve move: a region hands a neighbour a cell with whatever that cell alone holds.

Chains (balance.py) pass one cell at a time and never a cut cell, so a one-cell-wide strip
cannot shed load through them; giving an articulation cell together with the part of the
region it cuts off (when that part holds no pinned cell) can. Taken only when it lowers the
sum of squared loads, so the balancing loop still terminates.
"""

from __future__ import annotations

import numpy as np

from planner.balanced.pieces import RegionPieces
from planner.balanced.reshape import WHOLE
from planner.balanced.state import PartitionState

BATCH_FROM = 48  # robots above which relieve makes many disjoint hand-overs per scan


def relieve(state: PartitionState) -> bool:
    """Best single hand-over of a boundary cell, with what it alone holds to its region.

    Giving an articulation cell also gives the part of the region it cuts off (when that
    part holds no pinned cell): this is how a region sheds a one-cell-wide strip that the
    chains cannot pass a single cell through. Taken only when it lowers the sum of squared
    loads, so the balancing loop still terminates. With more than BATCH_FROM robots, the
    best hand-over of every giver is found in the one scan and as many as touch disjoint
    regions are made (best first): a hand-over depends only on its two regions, so each
    still lowers the sum, and a scan of the whole boundary no longer buys a single cell.
    """
    if state.k > BATCH_FROM:
        return _relieve_many(state)
    best: tuple[int, int, int, list[int]] | None = None
    offers = _Offers(state)
    low = min(state.load)
    for giver in sorted(offers.givers, key=lambda r: (-state.load[r], r)):
        spread = state.load[giver] - low
        if best is not None and spread * spread <= 4 * best[0]:
            break  # gain = amount * gap <= (spread / 2) ** 2, and givers come largest first
        if len(state.whole[giver]) < 2:
            continue
        cut = _cut_cells(state, giver)
        reach = state.load[giver] - offers.lowest_taker[giver]
        if best is not None and reach * reach <= 4 * best[0]:
            continue  # the bound above with this giver's own takers (k = 1000: most givers)
        found = _best_offer(state, offers, giver, cut, 0 if best is None else best[0])
        if found is not None:
            best = (found[0], giver, found[1], found[2])
    if best is None:
        return False
    _, giver, taker, piece = best
    _hand_over(state, giver, taker, piece)
    return True


def _relieve_many(state: PartitionState) -> bool:
    offers = _Offers(state)
    found = []
    for giver in offers.givers:
        if len(state.whole[giver]) < 2:
            continue
        offer = _best_offer(state, offers, giver, _cut_cells(state, giver), 0)
        if offer is not None:
            found.append((-offer[0], giver, offer[1], offer[2]))
    used: set[int] = set()
    for _, giver, taker, piece in sorted(found, key=lambda f: (f[0], f[1])):
        if giver in used or taker in used:
            continue
        used.update((giver, taker))
        _hand_over(state, giver, taker, piece)
    return bool(used)


def _best_offer(state: PartitionState, offers: _Offers, giver: int, cut: set[int],
                floor: int) -> tuple[int, int, list[int]] | None:
    """(gain, taker, piece) of ``giver``'s best hand-over with a gain above ``floor``."""
    load = state.load
    best: tuple[int, int, int] | None = None
    last, size, amount = -1, 0, 0
    for u, y in offers.of(giver):  # by cell, then taker: the first of equal gains wins
        if u != last:
            last = u
            size = 0 if state.pinned(u) else _pieces(state, giver).size(u) if u in cut else 1
            amount = WHOLE * size
        if not size:
            continue
        gap = load[giver] - load[y] - amount
        gain = amount * gap
        if gap > 0 and gain > floor and (best is None or gain > best[0]):
            best = (gain, y, u)
    if best is None:
        return None
    gain, taker, u = best
    return gain, taker, _pieces(state, giver).cells(u) if u in cut else [u]


def _hand_over(state: PartitionState, giver: int, taker: int, piece: list[int]) -> None:
    for u in piece:
        state.release(giver, u)
        state.claim(taker, u)


class _Offers:
    """Giver -> (whole cell, neighbouring region smaller by more than a cell) pairs.

    One vectorised pass over all neighbouring cell pairs (numpy) instead of a Python scan of
    every region's cells: the relieve move runs hundreds of times on a stalled partition.
    The per-giver dictionaries are built only for the givers relieve gets to (it stops
    after the largest few).
    """

    def __init__(self, state: PartitionState) -> None:
        label = np.asarray(state.label, dtype=np.int64)
        load = np.asarray(state.load, dtype=np.int64)
        own = label[state.edge_src]
        other = label[state.edge_dst]
        mask = (own >= 0) & (other >= 0) & (own != other)
        mask[mask] &= load[other[mask]] + WHOLE < load[own[mask]]
        own = own[mask]
        # sorted by giver, cell, taker, so that of() slices instead of masking all pairs and
        # building dictionaries: with k = 1000 it runs 10^5 times a plan
        cell, other = state.edge_src[mask], other[mask]
        order = np.lexsort((other, cell, own))
        self._cell = cell[order]
        self._other = other[order]
        own = own[order]
        givers, first = np.unique(own, return_index=True)
        self.givers: list[int] = givers.tolist()
        ends = [*first[1:].tolist(), len(own)] if len(own) else []
        lowest = np.minimum.reduceat(load[self._other], first) if len(own) else first
        self.lowest_taker: dict[int, int] = dict(zip(self.givers, lowest.tolist(), strict=True))
        self._span = dict(zip(self.givers, zip(first.tolist(), ends, strict=True), strict=True))

    def of(self, giver: int) -> list[tuple[int, int]]:
        """(cell, taker) pairs of ``giver``, sorted (a pair may repeat)."""
        lo, hi = self._span.get(giver, (0, 0))
        return list(zip(self._cell[lo:hi].tolist(), self._other[lo:hi].tolist(), strict=True))


def _cut_cells(state: PartitionState, robot: int) -> set[int]:
    """The region's cut cells: cached, or from the search that finds its pieces (the same
    cells PartitionState.cut_cells would find, in one pass instead of two)."""
    cut = state.cached_cut_cells(robot)
    if cut is None:
        cut = _pieces(state, robot).cut
        state.remember_cut_cells(robot, cut)
    return cut


def _pieces(state: PartitionState, robot: int) -> RegionPieces:
    """The pieces of ``robot``'s region (cached until the region or its pins change)."""
    known = state.pieces.get(robot)
    if known is None:
        known = RegionPieces(state.whole[robot], state.neighbours, state.pinned)
        state.pieces[robot] = known
    return known
