"""Who is dead, decided from heartbeats, token deletions and others' death notices: a
sans-I/O failure detector (bus.liveness feeds it from the wire).

Two signals. A robot's liveliness token ``mstc/<m>/alive/<r>/<i>`` disappears ~3 ms after its
process dies (the TCP close is seen at once) or ~0.75 x lease after the process hangs
entirely. Heartbeats cover the other hang: a process whose event loop is stuck while Zenoh's
threads still keep its transport (and token) alive. Token deletions are confirmed after a
short grace so that losing *our own* router (which deletes everybody's token locally) is
not mistaken for a massacre: while disconnected nothing expires, and on reconnection every
peer gets a fresh timeout. A link that drops and comes back between two looks at it does the
same unseen, so a deletion can be made to count only once censuses of the router's tokens
lack the token too, twice in a row (FailureDetector.on_token_census). Incarnations fence
stale lives: a heartbeat from a life already declared dead is ignored, a higher incarnation
is a new life.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass

from bus.messages import DeathNotice, DeathReason, Heartbeat

# How often a robot beats (bus.liveness) and how long a silence is a death.
DEFAULT_HEARTBEAT_PERIOD = 0.2
DEFAULT_TIMEOUT = 1.0
# A vanished liveliness token is confirmed after this grace, which also sets how often the
# liveness service wakes (every min(heartbeat period, grace) / 2).
DEFAULT_TOKEN_GRACE = 0.1
# A token deletion counts once this many censuses in a row lack the token. On a loaded host
# Zenoh 1.10 ends up to one liveliness get in a hundred before all of the router's replies
# are in, when the session also watches those tokens (benchmarks/bench_bus.py: 4-10 of
# 1 000, none without the watch, 2026-12-06): one census alone once confirmed two live
# robots' deletions in CI.
CENSUSES_TO_CONFIRM = 2


@dataclass
class _Peer:
    incarnation: int
    last_seen: float
    token_lost_at: float | None = None
    censuses_without_token: int = 0

    @property
    def token_loss_confirmed(self) -> bool:
        return self.censuses_without_token >= CENSUSES_TO_CONFIRM

    def token_held(self) -> None:
        """No token loss pending: its censuses start afresh with the next deletion."""
        self.token_lost_at = None
        self.censuses_without_token = 0


class FailureDetector:
    """Decides deaths from heartbeats, token deletions and others' death notices.

    Clock values are injected (seconds, any monotonic origin); nothing here sleeps or does
    I/O. ``detector`` is the robot running this detector (None for an observer). With
    ``confirm_tokens`` a token deletion counts only once censuses of the router's tokens
    taken after it (:meth:`on_token_census`) lack the token too, CENSUSES_TO_CONFIRM in a
    row.
    """

    def __init__(self, *, timeout: float = DEFAULT_TIMEOUT,
                 token_grace: float = DEFAULT_TOKEN_GRACE, detector: int | None = None,
                 confirm_tokens: bool = False) -> None:
        if timeout <= 0 or token_grace < 0:
            raise ValueError("timeout must be > 0 and token_grace >= 0")
        self.timeout = timeout
        self.token_grace = token_grace
        self.detector = detector
        self.confirm_tokens = confirm_tokens
        self._peers: dict[int, _Peer] = {}
        self._dead: dict[int, DeathNotice] = {}  # robot -> notice of its newest dead life
        self._connected = True
        self._tokens_doubtful_until = -math.inf

    # --- inputs ---------------------------------------------------------------------------

    def _fenced(self, robot: int, incarnation: int) -> bool:
        notice = self._dead.get(robot)
        return notice is not None and incarnation <= notice.incarnation

    def _touch(self, robot: int, incarnation: int, now: float) -> bool:
        if self._fenced(robot, incarnation):
            return False
        peer = self._peers.get(robot)
        if peer is not None and incarnation < peer.incarnation:
            return False  # an older life of a robot that has since restarted
        if peer is None or incarnation > peer.incarnation:
            self._peers[robot] = _Peer(incarnation, now)
        else:
            peer.last_seen = max(peer.last_seen, now)
        return True

    def on_heartbeat(self, hb: Heartbeat, now: float) -> bool:
        """Record a heartbeat; False if it comes from a fenced (dead or superseded) life."""
        return self._touch(hb.robot, hb.incarnation, now)

    def on_token(self, robot: int, incarnation: int, now: float) -> bool:
        """A liveliness token appeared (or was re-announced after a router restart)."""
        accepted = self._touch(robot, incarnation, now)
        peer = self._peers.get(robot)
        if accepted and peer is not None and peer.incarnation == incarnation:
            peer.token_held()
        return accepted

    def on_token_deleted(self, robot: int, incarnation: int, now: float) -> None:
        """A token vanished: the life is declared dead by :meth:`expire` after the grace."""
        if not self._connected or now < self._tokens_doubtful_until:
            return
        peer = self._peers.get(robot)
        if peer is None:
            if not self._fenced(robot, incarnation):
                self._peers[robot] = _Peer(incarnation, now, token_lost_at=now)
            return
        if peer.incarnation == incarnation:
            peer.token_lost_at = now
            peer.censuses_without_token = 0

    def unconfirmed_token_losses(self) -> bool:
        """Some token deletion awaits a census (only with ``confirm_tokens``)."""
        return self.confirm_tokens and any(
            peer.token_lost_at is not None and not peer.token_loss_confirmed
            for peer in self._peers.values())

    def on_token_census(self, present: Collection[tuple[int, int]], asked_at: float,
                        now: float) -> list[int]:
        """The router, asked at ``asked_at``, holds the tokens ``present`` (robot,
        incarnation). A deletion heard before the question is confirmed by the token's
        absence from CENSUSES_TO_CONFIRM answers in a row; a token the router still holds
        was deleted by this process's own link (it dropped and came back unseen: Zenoh
        deletes every remote token locally when its session goes), and counts as a sign of
        life. Returns the robots whose deletion the census refuted."""
        refuted = []
        for robot, peer in sorted(self._peers.items()):
            if peer.token_lost_at is None or peer.token_lost_at > asked_at:
                continue
            if (robot, peer.incarnation) in present:
                peer.token_held()
                peer.last_seen = max(peer.last_seen, now)
                refuted.append(robot)
            else:
                peer.censuses_without_token += 1
        return refuted

    def on_death_notice(self, notice: DeathNotice) -> bool:
        """Accept another detector's verdict; True if it is news (a newer dead life)."""
        if self._fenced(notice.robot, notice.incarnation):
            return False
        self._dead[notice.robot] = notice
        peer = self._peers.get(notice.robot)
        if peer is not None and peer.incarnation <= notice.incarnation:
            del self._peers[notice.robot]
        return True

    def notice_problem(self, notice: DeathNotice) -> str | None:
        """Why a death notice heard on the wire must not be acted on, or None.

        The router lets only robots publish notices but cannot check what they say: the
        detector must be a participant this detector knows (alive, or dead since, whose
        re-announced verdicts stay learnable), and a known robot cannot be declared dead in
        an incarnation it never had (which would fence its future lives in advance).

        A dead detector's verdict is learnable only about a robot not alive here: across a
        partition each side declares the other dead, and the far side's verdicts, heard once
        it heals, would otherwise stop the robots that went on working (simhw, which the
        near side still reaches, fences the far side; simhw refuses them too)."""
        detector = notice.detected_by
        if detector is None:
            return "no detector"
        gone = detector != self.detector and detector not in self._peers  # not alive here
        if gone and detector not in self._dead:
            return f"detector {detector} is not a known participant"
        if gone and detector != notice.robot:  # a robot's own "leaving" stays learnable
            if notice.robot == self.detector:
                return f"detector {detector} is dead: its verdict on this robot is not " \
                       f"acted on (simhw fences this robot if it really was dead)"
            if notice.robot in self._peers:
                return f"detector {detector} is dead and robot {notice.robot} is alive here"
        if notice.robot == self.detector:
            return None  # about this robot: its service checks against its own life
        peer = self._peers.get(notice.robot)
        newest = max(peer.incarnation if peer is not None else -1,
                     self._dead[notice.robot].incarnation if notice.robot in self._dead else -1)
        if newest >= 0 and notice.incarnation > newest:
            return f"robot {notice.robot} never had incarnation {notice.incarnation}"
        return None

    def set_connected(self, connected: bool, now: float) -> None:
        """Our own link to the network: while down, silence proves nothing about peers."""
        if connected and not self._connected:
            for peer in self._peers.values():
                peer.last_seen = max(peer.last_seen, now)
                peer.token_held()
        if not connected:
            for peer in self._peers.values():
                peer.token_held()
        self._connected = connected

    def on_local_stall(self, now: float) -> None:
        """This process itself was paused (its loop ran late): the silence it measured is
        its own, so every peer gets a fresh timeout instead of being declared dead."""
        for peer in self._peers.values():
            peer.last_seen = max(peer.last_seen, now)

    def doubt_token_deletions(self, now: float, until: float) -> None:
        """This process stalled long enough for its router to drop its session: the token
        deletions heard since, and until ``until``, are its own link's (Zenoh deletes every
        remote token locally when the session goes, and re-announces them on reconnection),
        not peers' deaths. Heartbeats alone decide meanwhile: a peer that really died then
        is declared a timeout after its last beat rather than a grace after its token went.
        (A woken robot that took them for deaths declared its whole fleet dead: chaos seed
        4249, trial 23.)"""
        for peer in self._peers.values():
            peer.token_held()
        self._tokens_doubtful_until = max(self._tokens_doubtful_until, until)

    # --- outputs --------------------------------------------------------------------------

    def _forgive_a_common_silence(self, now: float) -> None:
        """Two or more peers hold their tokens and none has been heard for half the timeout:
        hold their silence at half the timeout. A router holding traffic back
        (docs/architecture.md, "Sessions that read slowly") silences every peer at once,
        while robots hang one at a time. A peer that really hung is declared dead half a
        timeout after the others are heard again."""
        holding = [peer for peer in self._peers.values() if peer.token_lost_at is None]
        if len(holding) < 2 or now - max(peer.last_seen for peer in holding) <= \
                self.timeout / 2:
            return
        for peer in holding:
            peer.last_seen = max(peer.last_seen, now - self.timeout / 2)

    def expire(self, now: float, *, tokens_only: bool = False) -> list[DeathNotice]:
        """Declare dead every life whose token is gone (after the grace) or whose last sign
        of life is older than the timeout; each death is reported once. A silence of every
        peer at once is not a sign of death (_forgive_a_common_silence). With
        ``tokens_only`` silences are left alone: a caller that has not checked for a stall
        of its own (:meth:`on_local_stall`) cannot tell a peer's silence from its own."""
        if not self._connected:
            return []
        if not tokens_only:
            self._forgive_a_common_silence(now)
        notices = []
        for robot, peer in sorted(self._peers.items()):
            reason: DeathReason | None = None
            if peer.token_lost_at is not None and now - peer.token_lost_at >= self.token_grace \
                    and (peer.token_loss_confirmed or not self.confirm_tokens):
                reason = "token"
            elif not tokens_only and now - peer.last_seen > self.timeout:
                reason = "heartbeat"
            if reason is not None:
                notices.append(DeathNotice(robot, peer.incarnation, self.detector, reason, now))
        for notice in notices:
            self.on_death_notice(notice)
        return notices

    def alive(self) -> dict[int, int]:
        """Robots currently believed alive -> their incarnation."""
        return {robot: peer.incarnation for robot, peer in sorted(self._peers.items())}

    def deaths(self) -> list[DeathNotice]:
        """The newest known death of each robot (re-announce these: they are durable)."""
        return [self._dead[robot] for robot in sorted(self._dead)]

    def is_dead(self, robot: int, incarnation: int) -> bool:
        return self._fenced(robot, incarnation)

    def death_of(self, robot: int) -> DeathNotice | None:
        """The newest known death notice of ``robot``, if any."""
        return self._dead.get(robot)
