"""Loss detection and repair of ORMSTC messages (planner/ormstc/streams.py) and the claim rule
that makes a lost claim safe (MachineConfig.await_horizon).

- PeerStreams: in-order delivery, duplicates, gaps found from later messages and from a
  heartbeat's ``said``, horizons; Resender: what a peer's acknowledgement shows lacking.
- A hand-driven machine does not decide a claim before its peer's horizon has passed the end
  of the window, and a rival claim repaired meanwhile makes it lose.
- A model check in the style of tests/test_ormstc_claims.py: two claims on one cell, every
  schedule, every per-message delay up to D and every claim or tree edge either delivered or
  lost and repaired later: with the horizon rule no schedule has two winners; the plain
  window rule (claim_wait = 2D - 1, safe without loss) has some.
"""

from __future__ import annotations

import itertools

from planner.ormstc.claims import ClaimBook
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.streams import NEVER, PeerStreams, Resender
from planner.ormstc.types import (
    Broadcast,
    CellStatus,
    ClaimMsg,
    Event,
    MachineConfig,
    Move,
    MoveResult,
    PeerHorizon,
    PeerMessage,
    Priority,
    Request,
    Sense,
    SenseResult,
    StartMsg,
    Tick,
    TreeEdgeMsg,
)


def test_a_gap_holds_back_what_follows_until_it_is_filled() -> None:
    streams: PeerStreams[str] = PeerStreams()
    assert streams.receive(1, 1, 1, "a", now=1.0) == ["a"]
    assert streams.horizon(1) == 1.0
    assert streams.receive(1, 1, 3, "c", now=2.0) == []  # 2 lost or overtaken
    assert streams.gaps == 1 and streams.missing(1) == [2]
    assert streams.horizon(1) == 1.0, "nothing after the gap counts"
    assert streams.receive(1, 1, 2, "b", now=3.0) == ["b", "c"]
    assert streams.horizon(1) == 3.0 and streams.missing(1) == []
    assert streams.receive(1, 1, 3, "c", now=4.0) == [] and streams.duplicates == 1
    assert streams.heard() == ((1, 1, 3),)


def test_a_heartbeat_shows_a_lost_last_message_and_moves_the_horizon() -> None:
    streams: PeerStreams[str] = PeerStreams()
    assert streams.horizon(2) == NEVER
    streams.digest(2, 1, 0, now=0.5)  # nothing said yet: the horizon is the beat
    assert streams.horizon(2) == 0.5
    streams.receive(2, 1, 1, "a", now=1.0)
    streams.digest(2, 1, 2, now=1.5)  # said 2, only 1 came: the last one was lost
    assert streams.missing(2) == [2] and streams.gaps == 1
    assert streams.horizon(2) == 1.0
    streams.digest(2, 1, 2, now=2.0)
    assert streams.horizon(2) == 1.0
    assert streams.receive(2, 1, 2, "b", now=2.5) == ["b"]
    assert streams.horizon(2) == 2.5  # the message itself is the latest digest covered
    streams.digest(2, 1, 2, now=3.0)
    assert streams.horizon(2) == 3.0


def test_a_new_life_restarts_the_numbering_and_fences_the_old() -> None:
    streams: PeerStreams[str] = PeerStreams()
    streams.receive(1, 1, 1, "a", now=0.0)
    streams.receive(1, 1, 2, "b", now=0.0)
    assert streams.receive(1, 2, 1, "new", now=1.0) == ["new"]
    assert streams.stale(1, 1) and not streams.stale(1, 2)
    assert streams.receive(1, 1, 3, "old", now=2.0) == []
    assert streams.heard() == ((1, 2, 1),)


def test_the_sender_says_again_what_an_acknowledgement_lacks_not_what_is_in_flight() -> None:
    resender = Resender(life=1, grace=0.2)
    for seq, at in ((1, 0.0), (2, 0.1), (3, 0.9)):
        resender.said(seq, at)
    assert resender.lacking(1, 3, now=1.0) == []  # everything taken
    assert resender.lacking(2, 0, now=1.0) == []  # another life's acknowledgement
    assert resender.lacking(1, 1, now=1.0) == [2]  # 3 is only 0.1 s old: still in flight
    assert resender.lacking(1, 1, now=1.1) == [3]  # 2 was just said again
    assert resender.lacking(1, 1, now=1.25) == [2]
    assert resender.lacking(1, 1, now=1.5) == [2, 3]
    assert resender.resent == 5


# ---- the machine waits for its peer's horizon ----

PEER_FAR = (100, 100)


class Hand:
    """One machine with await_horizon in a free room, its peer far away; answers every Move
    and Sense at once and records what it broadcasts."""

    def __init__(self) -> None:
        self.machine = OrmstcMachine(MachineConfig(
            robot=0, team=2, start=(0.0, 0.0), claim_wait=1.0, await_horizon=True))
        self.said: list[object] = []
        self.now = 0.0
        self.answer: Event | None = None
        self.step([PeerMessage(1, StartMsg(1, PEER_FAR))])

    def step(self, events: list[Event]) -> None:
        todo: list[Event] = [Tick(self.now), *events]
        while True:
            requests: list[Request] = self.machine.step(todo)
            todo = []
            for request in requests:
                if isinstance(request, Broadcast):
                    self.said.append(request.message)
                elif isinstance(request, Move):
                    todo.append(MoveResult(True))
                elif isinstance(request, Sense):
                    todo.append(SenseResult(tuple((c, CellStatus.FREE) for c in request.cells)))
            if not todo:
                return
            todo.insert(0, Tick(self.now))

    def at(self, now: float, *events: Event) -> None:
        self.now = now
        self.step(list(events))

    def edges(self) -> list[TreeEdgeMsg]:
        return [m for m in self.said if isinstance(m, TreeEdgeMsg)]


def test_a_claim_is_decided_only_once_the_peers_horizon_passed_its_window() -> None:
    hand = Hand()
    claims = [m for m in hand.said if isinstance(m, ClaimMsg)]
    assert len(claims) == 1 and not hand.edges()
    hand.at(1.0, PeerHorizon(1, 0.5))  # the window is over; the peer is only known to 0.5
    hand.at(3.0)
    assert not hand.edges(), "decided without knowing what the peer said before the window"
    hand.at(3.5, PeerHorizon(1, 3.2))
    assert [e.child for e in hand.edges()] == [claims[0].cell]
    assert hand.machine.horizon_waits == 1


def test_a_rival_claim_repaired_before_the_horizon_wins() -> None:
    hand = Hand()
    claim = next(m for m in hand.said if isinstance(m, ClaimMsg))
    hand.at(1.5)  # the rival's claim was lost: nothing heard, no decision
    assert not hand.edges()
    hand.at(2.0, PeerMessage(1, ClaimMsg(1, claim.cell, 0)), PeerHorizon(1, 2.0))
    assert claim.cell not in {e.child for e in hand.edges()}, "robot 1 has the higher id"
    assert (1, ((0, 0), claim.cell)) in [(r, link) for link, r in
                                         hand.machine.connections.links.items()]


def test_a_dead_or_departed_peer_is_not_waited_for() -> None:
    hand = Hand()
    hand.at(1.0, PeerHorizon(1, float("inf")))
    assert hand.edges()


# ---- model check: two claims, message loss ----

def _play(times: tuple[int, int], delay: dict[tuple[str, int], int],
          repair: dict[tuple[str, int], int], hb: tuple[int, int], wait: int,
          horizon: bool) -> int:
    """Winners of two claims on one cell (robot i claims at times[i]; ids 0 < 1).

    Claim and edge messages of robot i arrive at the peer ``delay`` after sending, or, when
    lost (``repair`` > 0), that much later still (a resend). Robot i's heartbeat leaves at
    every step with the number of messages said so far and takes ``hb[i]`` steps. With
    ``horizon`` a robot decides at the first step >= its claim + wait at which a heartbeat of
    its peer received at or after claim + wait is covered by what it holds of the peer.
    """
    horizon_end = max(times) + wait + 8 * max(delay.values()) + max(repair.values()) + 8
    sent: dict[int, list[tuple[str, int]]] = {0: [], 1: []}  # messages in seq order
    decided: dict[int, bool] = {}
    arrivals: dict[tuple[str, int], int] = {}

    def arrive(kind: str, robot: int, at: int) -> None:
        arrivals[(kind, robot)] = at + delay[(kind, robot)] + repair[(kind, robot)]

    for t in range(horizon_end):
        for i in (0, 1):
            if t == times[i]:
                sent[i].append(("claim", t))
                arrive("claim", i, t)
        deciders = []
        for i in (0, 1):
            if i in decided or t < times[i] + wait:
                continue
            j = 1 - i
            if horizon:
                end = times[i] + wait

                def held(seq: int, j: int = j, t: int = t) -> bool:
                    kind = sent[j][seq - 1][0]
                    return arrivals[(kind, j)] <= t

                def said_at(s: int, j: int = j) -> int:
                    return sum(1 for _, at in sent[j] if at <= s)

                covered = any(s + hb[j] >= end and s + hb[j] <= t
                              and all(held(q) for q in range(1, said_at(s) + 1))
                              for s in range(t + 1))
                if not covered:
                    continue
            deciders.append(i)
        for i in deciders:
            j = 1 - i
            book = ClaimBook(Priority.ID)
            book.hear((0, 0), i, 0)
            if arrivals.get(("claim", j), horizon_end) <= t:
                book.hear((0, 0), j, 0)
            owner = j if arrivals.get(("edge", j), horizon_end) <= t else None
            decided[i] = book.decide((0, 0), i, owner, set()).won
        for i in deciders:
            if decided[i]:
                sent[i].append(("edge", t))
                arrive("edge", i, t)
    return sum(decided.values())


def _double_wins(max_delay: int, horizon: bool) -> int:
    wait = 2 * max_delay - 1
    keys = [("claim", 0), ("claim", 1), ("edge", 0), ("edge", 1)]
    found = 0
    for t1 in range(3 * max_delay + 2):
        for ds in itertools.product(range(1, max_delay + 1), repeat=4):
            for rs in itertools.product((0, 1, 3 * max_delay), repeat=4):
                for hb in itertools.product(range(1, max_delay + 1), repeat=2):
                    winners = _play((0, t1), dict(zip(keys, ds, strict=True)),
                                    dict(zip(keys, rs, strict=True)), hb, wait, horizon)
                    found += winners > 1
    return found


def test_with_loss_the_horizon_rule_never_gives_two_owners() -> None:
    assert _double_wins(1, horizon=True) == 0
    assert _double_wins(2, horizon=True) == 0


def test_with_loss_the_plain_window_can_give_two_owners() -> None:
    assert _double_wins(2, horizon=False) > 0
