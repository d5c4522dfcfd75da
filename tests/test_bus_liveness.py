"""FailureDetector with an injected clock: timeouts, token grace, fencing, connectivity."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bus.detector import FailureDetector
from bus.messages import DeathNotice, Heartbeat


def hb(robot: int, incarnation: int = 1, seq: int = 0) -> Heartbeat:
    return Heartbeat(robot=robot, incarnation=incarnation, seq=seq, pose=None,
                     state="running", sim_time=0.0)


def test_silence_longer_than_timeout_is_death_reported_once() -> None:
    fd = FailureDetector(timeout=1.0, detector=9)
    fd.on_heartbeat(hb(1), now=10.0)
    fd.on_heartbeat(hb(2), now=10.5)
    fd.on_heartbeat(hb(2), now=10.9)  # robot 2 is heard: the silence is robot 1's alone
    assert fd.expire(11.0) == []  # exactly the timeout: not yet
    notices = fd.expire(11.01)
    assert notices == [DeathNotice(1, 1, 9, "heartbeat", 11.01)]
    assert fd.expire(20.0) == [DeathNotice(2, 1, 9, "heartbeat", 20.0)]
    assert fd.expire(30.0) == []
    assert fd.alive() == {}


def test_heartbeats_keep_a_robot_alive() -> None:
    fd = FailureDetector(timeout=1.0)
    for step in range(50):
        fd.on_heartbeat(hb(1, seq=step), now=step * 0.5)
        assert fd.expire(step * 0.5 + 0.9) == []
    assert fd.alive() == {1: 1}


def test_token_deletion_is_death_after_grace() -> None:
    fd = FailureDetector(timeout=5.0, token_grace=0.1)
    fd.on_token(3, 2, now=0.0)
    fd.on_heartbeat(hb(3, 2), now=1.0)
    fd.on_token_deleted(3, 2, now=1.0)
    assert fd.expire(1.05) == []
    assert [(n.robot, n.incarnation, n.reason) for n in fd.expire(1.1)] == [(3, 2, "token")]


def test_token_back_within_grace_cancels_suspicion() -> None:
    fd = FailureDetector(timeout=5.0, token_grace=0.1)
    fd.on_token(3, 2, now=0.0)
    fd.on_token_deleted(3, 2, now=1.0)
    fd.on_token(3, 2, now=1.05)
    assert fd.expire(2.0) == []


def test_deletion_of_another_incarnation_does_not_kill_the_current_one() -> None:
    fd = FailureDetector(timeout=5.0, token_grace=0.1)
    fd.on_token(3, 2, now=0.0)
    fd.on_token_deleted(3, 1, now=0.5)
    assert fd.expire(1.0) == []


def test_stale_incarnation_is_fenced_and_new_life_accepted() -> None:
    fd = FailureDetector(timeout=1.0)
    fd.on_heartbeat(hb(4, 1), now=0.0)
    assert fd.expire(2.0)[0].incarnation == 1
    # The old life wakes up (e.g. after SIGSTOP): it stays dead.
    assert not fd.on_heartbeat(hb(4, 1), now=2.1)
    assert fd.alive() == {}
    assert fd.is_dead(4, 1)
    # A restarted process (higher incarnation) is a new life.
    assert fd.on_heartbeat(hb(4, 2), now=2.2)
    assert fd.alive() == {4: 2}
    assert not fd.is_dead(4, 2)
    # Late heartbeats of the older life never replace the newer one.
    assert not fd.on_heartbeat(hb(4, 1), now=2.3)
    assert fd.alive() == {4: 2}


def test_a_restarted_robot_s_older_life_is_refused_even_if_never_declared_dead() -> None:
    fd = FailureDetector(timeout=1.0)
    assert fd.on_heartbeat(hb(4, 1), now=0.0)
    assert fd.on_heartbeat(hb(4, 2), now=0.1)  # restarted before anyone saw it die
    assert not fd.on_heartbeat(hb(4, 1), now=0.2)  # a late beat of the first life
    assert fd.alive() == {4: 2} and not fd.is_dead(4, 1)


def test_a_heartbeat_still_on_its_way_does_not_cancel_a_lost_token() -> None:
    # Only the token coming back cancels the suspicion: a beat sent before the process
    # died can arrive after its token was deleted.
    fd = FailureDetector(timeout=5.0, token_grace=0.1)
    fd.on_token(3, 2, now=0.0)
    fd.on_token_deleted(3, 2, now=1.0)
    assert fd.on_heartbeat(hb(3, 2), now=1.05)
    assert [(n.robot, n.reason) for n in fd.expire(1.2)] == [(3, "token")]


def test_death_notices_from_others_are_adopted_once() -> None:
    fd = FailureDetector(timeout=1.0, detector=0)
    fd.on_heartbeat(hb(5, 3), now=0.0)
    notice = DeathNotice(robot=5, incarnation=3, detected_by=1, reason="token", detected_at=0.2)
    assert fd.on_death_notice(notice)
    assert not fd.on_death_notice(notice)  # duplicate
    assert not fd.on_death_notice(DeathNotice(5, 2, 1, "heartbeat", 0.3))  # older life
    assert fd.alive() == {}
    assert fd.expire(10.0) == []  # already known: not reported again
    assert fd.deaths() == [notice]


def test_disconnection_suspends_expiry_and_reconnection_restarts_timeouts() -> None:
    fd = FailureDetector(timeout=1.0, token_grace=0.1)
    for robot in (1, 2):
        fd.on_token(robot, 1, now=0.0)
        fd.on_heartbeat(hb(robot), now=0.0)
    fd.set_connected(False, now=0.5)
    # Our router went away: everybody's token disappears locally, heartbeats stop.
    for robot in (1, 2):
        fd.on_token_deleted(robot, 1, now=0.5)
    assert fd.expire(5.0) == []
    fd.set_connected(True, now=6.0)
    fd.on_token(1, 1, now=6.2)  # robot 1 is re-announced; robot 2 died during the outage
    fd.on_heartbeat(hb(1), now=6.9)
    assert fd.expire(7.0) == []
    assert [(n.robot, n.reason) for n in fd.expire(7.01)] == [(2, "heartbeat")]
    assert fd.alive() == {1: 1}


def test_deletion_raced_before_disconnect_is_forgiven() -> None:
    fd = FailureDetector(timeout=1.0, token_grace=0.1)
    fd.on_token(1, 1, now=0.0)
    fd.on_token_deleted(1, 1, now=0.5)
    fd.set_connected(False, now=0.55)
    fd.set_connected(True, now=0.9)
    fd.on_heartbeat(hb(1), now=1.0)
    assert fd.expire(1.2) == []


def test_invalid_parameters() -> None:
    with pytest.raises(ValueError, match="timeout"):
        FailureDetector(timeout=0)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 2), st.floats(0, 0.5)), min_size=1, max_size=40),
       st.floats(0.1, 1.0))
def test_expiry_matches_brute_force(beats: list[tuple[int, float]], timeout: float) -> None:
    """Random heartbeat gaps for robots 0..2, expire() called every 0.05 s: each robot is
    declared dead at the first tick whose gap since its last beat exceeds the timeout, where
    a stretch in which two or more live robots are all silent counts for half the timeout at
    most (FailureDetector._forgive_a_common_silence), replayed tick by tick."""
    fd = FailureDetector(timeout=timeout)
    now, schedule = 0.0, []
    for robot, gap in beats:
        now += gap
        schedule.append((now, robot))
    ticks = [i * 0.05 for i in range(int((now + 2 * timeout) / 0.05) + 2)]
    # Oracle: the rule replayed on plain dicts, tick by tick.
    expected: dict[int, float] = {}
    last: dict[int, float] = {}
    for tick in ticks:
        for t, robot in schedule:
            if t <= tick and robot not in expected:
                last[robot] = max(last.get(robot, t), t)
        alive = [r for r in last if r not in expected]
        if len(alive) >= 2 and tick - max(last[r] for r in alive) > timeout / 2:
            for r in alive:
                last[r] = max(last[r], tick - timeout / 2)
        for r in alive:
            if tick - last[r] > timeout:
                expected[r] = tick
    got: dict[int, float] = {}
    events = iter(schedule)
    pending = next(events, None)
    for tick in ticks:
        while pending is not None and pending[0] <= tick:
            fd.on_heartbeat(hb(pending[1]), now=pending[0])
            pending = next(events, None)
        for notice in fd.expire(tick):
            got.setdefault(notice.robot, tick)
    # After a death the robot's later beats are fenced, so the first death is the only one.
    assert got == expected


def test_local_stall_gives_everyone_a_fresh_timeout() -> None:
    fd = FailureDetector(timeout=1.0)
    fd.on_heartbeat(hb(1), now=0.0)
    fd.on_local_stall(now=30.0)  # we were SIGSTOPped for half a minute
    assert fd.expire(30.5) == []
    assert [n.robot for n in fd.expire(31.01)] == [1]


def test_token_deletions_after_a_session_losing_stall_wait_for_heartbeats() -> None:
    """Woken from a stall that cost it its session, a robot hears every peer's token go
    (its own link's doing) before the re-announcements: no peer is declared on that, and a
    peer that really stopped is declared a timeout after its last beat."""
    fd = FailureDetector(timeout=3.0, token_grace=0.1, detector=3)
    for robot in (0, 1, 2):
        fd.on_token(robot, 1, now=0.0)
        fd.on_heartbeat(hb(robot), now=1.0)
    for robot in (0, 1, 2):  # heard as the loop wakes, before it notices its stall
        fd.on_token_deleted(robot, 1, now=2.43)
    fd.doubt_token_deletions(now=2.44, until=5.44)
    for robot in (0, 1, 2):  # and more of them while the link comes back
        fd.on_token_deleted(robot, 1, now=2.5)
    assert fd.expire(2.7) == []
    for robot in (0, 1):  # re-announced, beating again; robot 2 really hung at 1.0
        fd.on_token(robot, 1, now=2.8)
        for now in (3.0, 3.5, 4.0):
            fd.on_heartbeat(hb(robot), now=now)
    # Everyone was silent past half the timeout at 2.7, so robot 2's silence counts from 1.2
    # (test_every_peer_silent_at_once_is_not_a_massacre).
    assert fd.expire(4.1) == []
    assert fd.expire(4.25) == [DeathNotice(2, 1, 3, "heartbeat", 4.25)]
    # Once the doubt is over, a token deletion is a death after the grace again.
    fd.on_token_deleted(1, 1, now=6.0)
    assert fd.expire(6.05) == []
    assert fd.expire(6.15) == [DeathNotice(1, 1, 3, "token", 6.15)]


def test_every_peer_silent_at_once_is_not_a_massacre() -> None:
    """A router holding traffic back silences every peer at once: nobody is declared dead
    while it lasts, and a peer that stays silent when the others are heard again is declared
    half a timeout later."""
    fd = FailureDetector(timeout=1.0, detector=0)
    for robot in (1, 2, 3):
        fd.on_heartbeat(hb(robot), now=0.0)
    for tick in range(1, 60):  # six seconds of silence from everyone
        assert fd.expire(tick * 0.1) == []
    # the last silent tick (5.9) left everybody last heard at 5.4
    for seq, now in enumerate((6.0, 6.1, 6.2, 6.3, 6.4), start=1):
        fd.on_heartbeat(hb(1, seq=seq), now=now)
        fd.on_heartbeat(hb(2, seq=seq), now=now)
        assert fd.expire(now) == []
    assert [n.robot for n in fd.expire(6.41)] == [3]
    assert fd.alive() == {1: 1, 2: 1}


def test_one_silent_peer_among_heard_ones_is_declared_on_time() -> None:
    fd = FailureDetector(timeout=1.0, detector=0)
    for robot in (1, 2, 3):
        fd.on_heartbeat(hb(robot), now=0.0)
    for tick in range(1, 11):
        fd.on_heartbeat(hb(1, seq=tick), now=tick * 0.1)
        fd.on_heartbeat(hb(2, seq=tick), now=tick * 0.1)
    fd.on_heartbeat(hb(1, seq=11), now=1.0)
    assert [n.robot for n in fd.expire(1.01)] == [3]


def test_a_single_peer_silent_is_declared_whatever_the_cause() -> None:
    """With one peer, its silence and a stalled router look alike: the timeout decides."""
    fd = FailureDetector(timeout=1.0, detector=0)
    fd.on_heartbeat(hb(1), now=0.0)
    assert [n.robot for n in fd.expire(1.01)] == [1]


def test_with_confirmation_a_deletion_counts_once_two_later_censuses_lack_the_token() -> None:
    fd = FailureDetector(timeout=5.0, token_grace=0.1, confirm_tokens=True)
    for robot in (1, 2, 3):
        fd.on_token(robot, 1, now=0.0)
    assert not fd.unconfirmed_token_losses()
    fd.on_token_deleted(1, 1, now=1.0)
    fd.on_token_deleted(2, 1, now=1.0)
    assert fd.unconfirmed_token_losses()
    assert fd.expire(2.0) == []  # past the grace, but nobody has asked the router yet
    # The router, asked at 2.0, still holds robot 2's token but not robot 1's.
    assert fd.on_token_census({(2, 1), (3, 1)}, asked_at=2.0, now=2.01) == [2]
    assert fd.unconfirmed_token_losses() and fd.expire(2.02) == []  # one census is not enough
    assert fd.on_token_census({(2, 1), (3, 1)}, asked_at=2.05, now=2.06) == []
    assert not fd.unconfirmed_token_losses()
    assert [(n.robot, n.reason) for n in fd.expire(2.07)] == [(1, "token")]
    assert fd.alive() == {2: 1, 3: 1}
    # A deletion heard after the question is not settled by its answer.
    fd.on_token_deleted(3, 1, now=3.0)
    assert fd.on_token_census(set(), asked_at=2.9, now=3.1) == []
    assert fd.unconfirmed_token_losses() and fd.expire(3.2) == []
    assert fd.on_token_census(set(), asked_at=3.2, now=3.3) == []
    assert fd.on_token_census(set(), asked_at=3.35, now=3.4) == []
    assert [(n.robot, n.reason) for n in fd.expire(3.4)] == [(3, "token")]


def test_a_census_cut_short_is_overruled_by_the_next_one() -> None:
    """Zenoh now and then ends a liveliness get before the router's replies are in: an
    answer lacking live tokens, followed by a full one, confirms nothing."""
    fd = FailureDetector(timeout=5.0, token_grace=0.1, confirm_tokens=True)
    for robot in (1, 2):
        fd.on_token(robot, 1, now=0.0)
        fd.on_token_deleted(robot, 1, now=1.0)
    assert fd.on_token_census({(0, 1)}, asked_at=1.1, now=1.11) == []
    assert fd.on_token_census({(0, 1), (1, 1), (2, 1)}, asked_at=1.15, now=1.16) == [1, 2]
    assert not fd.unconfirmed_token_losses() and fd.expire(1.5) == []
    # A deletion heard again after a refutation starts its count afresh.
    fd.on_token_deleted(1, 1, now=2.0)
    assert fd.on_token_census({(0, 1)}, asked_at=2.1, now=2.11) == []
    fd.on_token(1, 1, now=2.12)  # a late put of the token: a sign of life too
    fd.on_token_deleted(1, 1, now=2.2)
    assert fd.on_token_census({(0, 1)}, asked_at=2.3, now=2.31) == []
    assert fd.expire(2.4) == []
    assert fd.on_token_census({(0, 1)}, asked_at=2.45, now=2.46) == []
    assert [(n.robot, n.reason) for n in fd.expire(2.5)] == [(1, "token")]


def test_a_refuted_deletion_is_a_sign_of_life_and_heartbeats_still_decide() -> None:
    fd = FailureDetector(timeout=1.0, token_grace=0.1, confirm_tokens=True)
    fd.on_token(1, 1, now=0.0)
    fd.on_token(2, 1, now=0.0)
    fd.on_token_deleted(1, 1, now=0.5)
    fd.on_token_deleted(2, 1, now=0.5)
    assert fd.on_token_census({(1, 1), (2, 1)}, asked_at=0.6, now=0.8) == [1, 2]
    fd.on_heartbeat(hb(2), now=1.5)
    assert fd.expire(1.7) == []  # robot 1 was last seen at the census, 0.9 s ago
    # No census answers a deletion (the router cannot be reached): heartbeats decide.
    fd.on_token_deleted(2, 1, now=1.8)
    assert [(n.robot, n.reason) for n in fd.expire(1.85)] == [(1, "heartbeat")]
    assert fd.expire(2.4) == []
    assert [(n.robot, n.reason) for n in fd.expire(2.51)] == [(2, "heartbeat")]
