"""The claim protocol: unit behaviour, and safety of the settle window under message delays.

The safety test is a brute-force model check of the rule in planner.ormstc.claims: every
schedule of two or three claims on one cell, claim times and per-message delays up to D,
is played out (deliveries due at the decision instant count as heard, as in the lockstep
simulator); with claim_wait = 2D - 1 no schedule has two winners, and with one step less
some schedule has: the bound is tight.
"""

from __future__ import annotations

import itertools

from planner.ormstc.claims import ClaimBook, priority_key
from planner.ormstc.types import Priority


def test_highest_id_wins_and_loser_learns_the_winner() -> None:
    book = ClaimBook(Priority.ID)
    book.hear((1, 1), 2, covered=5)
    book.hear((1, 1), 7, covered=50)
    lost = book.decide((1, 1), 2, None, set())
    assert not lost.won and lost.winner == 7
    assert book.decide((1, 1), 7, None, set()).won


def test_fewest_covered_wins_then_id_breaks_ties() -> None:
    book = ClaimBook(Priority.FEWEST)
    book.hear((0, 0), 9, covered=10)
    book.hear((0, 0), 1, covered=3)
    assert book.leader((0, 0), set()) == 1
    assert priority_key(Priority.FEWEST, 4, 3) > priority_key(Priority.FEWEST, 1, 3)


def test_dead_claimants_and_settled_cells_block_nobody() -> None:
    book = ClaimBook(Priority.ID)
    book.hear((0, 0), 9, covered=0)
    book.hear((0, 0), 1, covered=0)
    assert book.decide((0, 0), 1, None, {9}).won
    book.hear((2, 2), 9, covered=0)
    book.settle((2, 2))
    assert book.leader((2, 2), set()) is None


def test_an_owner_beats_any_claim() -> None:
    book = ClaimBook(Priority.ID)
    book.hear((0, 0), 9, covered=0)
    outcome = book.decide((0, 0), 9, owner=3, dead=set())
    assert not outcome.won and outcome.winner == 3


def _winners(times: tuple[int, ...], delays: dict[tuple[int, int], int], wait: int,
             ids: tuple[int, ...]) -> list[int]:
    """Play out claims at ``times``; a winner broadcasts its tree edge at its decision time.

    A robot decides at t + wait with every message delivered by then (delivery <= decision).
    Deciding in time order makes edges sent earlier visible to later deciders.
    """
    n = len(times)
    order = sorted(range(n), key=lambda i: (times[i] + wait, i))
    edge_sent: dict[int, int] = {}
    winners = []
    for i in order:
        decide_at = times[i] + wait
        book = ClaimBook(Priority.ID)
        book.hear((0, 0), ids[i], 0)
        for j in range(n):
            if j != i and times[j] + delays[(j, i)] <= decide_at:
                book.hear((0, 0), ids[j], 0)
        owner = next((ids[j] for j, sent in edge_sent.items()
                      if sent + delays[(j, i)] <= decide_at), None)
        if book.decide((0, 0), ids[i], owner, set()).won:
            winners.append(ids[i])
            edge_sent[i] = decide_at
    return winners


def _exists_double_win(robots: int, max_delay: int, wait: int) -> bool:
    ids = tuple(range(robots))
    pairs = [(a, b) for a in range(robots) for b in range(robots) if a != b]
    for times in itertools.product(range(3 * max_delay + 2), repeat=robots):
        if min(times) != 0:
            continue
        for ds in itertools.product(range(1, max_delay + 1), repeat=len(pairs)):
            if len(_winners(times, dict(zip(pairs, ds, strict=True)), wait, ids)) > 1:
                return True
    return False


def test_window_of_two_d_minus_one_never_gives_two_owners() -> None:
    for max_delay in (1, 2, 3):
        assert not _exists_double_win(2, max_delay, 2 * max_delay - 1)
    assert not _exists_double_win(3, 2, 3)


def test_a_shorter_window_can_give_two_owners() -> None:
    for max_delay in (2, 3):
        assert _exists_double_win(2, max_delay, 2 * max_delay - 2)
