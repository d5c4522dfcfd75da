"""Who is alive: a sans-I/O failure detector plus the async service that feeds it.

Two signals. A robot's liveliness token ``mstc/<m>/alive/<r>/<i>`` disappears ~3 ms after its
process dies (the TCP close is seen at once) or ~0.75 x lease after the process hangs
entirely. Heartbeats cover the other hang: a process whose event loop is stuck while Zenoh's
threads still keep its transport (and token) alive. Token deletions are confirmed after a
short grace so that losing *our own* router (which deletes everybody's token locally) is
not mistaken for a massacre: while disconnected nothing expires, and on reconnection every
peer gets a fresh timeout. A link that drops and comes back between two looks at it does the
same unseen, so the service also asks the router which tokens it still holds before a
deletion counts (FailureDetector.on_token_census). Incarnations fence stale lives: a
heartbeat from a life already declared dead is ignored, a higher incarnation is a new life.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import DEFAULT_LEASE_MS
from bus.messages import DeathNotice, DeathReason, Heartbeat, Pose

_log = logging.getLogger("mstc.bus.liveness")

DEFAULT_HEARTBEAT_PERIOD = 0.2
DEFAULT_TIMEOUT = 1.0
DEFAULT_TOKEN_GRACE = 0.1
# An early heartbeat (LivelinessService.beat_soon) comes at most this often, as a fraction of
# the period: a burst of peers' claims costs at most 20 heartbeats per period.
SOON_FRACTION = 20
# A loop that ran this fraction of the lease late may have lost its session: a hung process's
# session is dropped after ~0.75 x its lease (bus/config.py), so half of it is taken as enough.
LEASE_STALL_FRACTION = 0.5
# How long the router has to answer which tokens it holds; an answer that took this long
# proves nothing (LivelinessService._ask_census).
CENSUS_TIMEOUT = 1.0


@dataclass
class _Peer:
    incarnation: int
    last_seen: float
    token_lost_at: float | None = None
    token_loss_confirmed: bool = False


class FailureDetector:
    """Decides deaths from heartbeats, token deletions and others' death notices.

    Clock values are injected (seconds, any monotonic origin); nothing here sleeps or does
    I/O. ``detector`` is the robot running this detector (None for an observer). With
    ``confirm_tokens`` a token deletion counts only once a census of the router's tokens
    taken after it (:meth:`on_token_census`) lacks the token too.
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
            peer.token_lost_at = None
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
            peer.token_loss_confirmed = False

    def unconfirmed_token_losses(self) -> bool:
        """Some token deletion awaits a census (only with ``confirm_tokens``)."""
        return self.confirm_tokens and any(
            peer.token_lost_at is not None and not peer.token_loss_confirmed
            for peer in self._peers.values())

    def on_token_census(self, present: Collection[tuple[int, int]], asked_at: float,
                        now: float) -> list[int]:
        """The router, asked at ``asked_at``, holds the tokens ``present`` (robot,
        incarnation). A deletion heard before the question is confirmed by the token's
        absence; a token the router still holds was deleted by this process's own link (it
        dropped and came back unseen: Zenoh deletes every remote token locally when its
        session goes), and counts as a sign of life. Returns the robots whose deletion the
        census refuted."""
        refuted = []
        for robot, peer in sorted(self._peers.items()):
            if peer.token_lost_at is None or peer.token_lost_at > asked_at:
                continue
            if (robot, peer.incarnation) in present:
                peer.token_lost_at = None
                peer.last_seen = max(peer.last_seen, now)
                refuted.append(robot)
            else:
                peer.token_loss_confirmed = True
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
                peer.token_lost_at = None
        if not connected:
            for peer in self._peers.values():
                peer.token_lost_at = None
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
            peer.token_lost_at = None
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

    def expire(self, now: float) -> list[DeathNotice]:
        """Declare dead every life whose token is gone (after the grace) or whose last sign
        of life is older than the timeout; each death is reported once. A silence of every
        peer at once is not a sign of death (_forgive_a_common_silence)."""
        if not self._connected:
            return []
        self._forgive_a_common_silence(now)
        notices = []
        for robot, peer in sorted(self._peers.items()):
            reason: DeathReason | None = None
            if peer.token_lost_at is not None and now - peer.token_lost_at >= self.token_grace \
                    and (peer.token_loss_confirmed or not self.confirm_tokens):
                reason = "token"
            elif now - peer.last_seen > self.timeout:
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


@dataclass(frozen=True)
class HeartbeatInfo:
    """What a heartbeat says besides identity: filled in by the agent at each beat."""

    pose: Pose | None = None
    state: str = "running"
    sim_time: float = 0.0
    said: int = 0  # numbered messages said this life (Heartbeat.said)
    heard: tuple[tuple[int, int, int], ...] = ()  # Heartbeat.heard


class HeartbeatPublisher:
    """Publishes a robot's heartbeat every ``period`` seconds until cancelled."""

    def __init__(self, bus: Bus, robot: int, incarnation: int, *,
                 period: float = DEFAULT_HEARTBEAT_PERIOD,
                 info: Callable[[], HeartbeatInfo] = HeartbeatInfo) -> None:
        self._bus = bus
        self._key = keys.heartbeat(bus.mission, robot)
        self.robot = robot
        self.incarnation = incarnation
        self.period = period
        self._info = info
        self.seq = 0

    def beat(self) -> None:
        info = self._info()
        self.seq += 1
        self._bus.publish(self._key, Heartbeat(self.robot, self.incarnation, self.seq,
                                               info.pose, info.state, info.sim_time,
                                               info.said, info.heard))

    async def run(self) -> None:
        while True:
            self.beat()
            await asyncio.sleep(self.period)


class LivelinessService:
    """A robot's liveness plumbing: its token and heartbeats, a FailureDetector fed from
    the wire, and death notices broadcast for the deaths it detects.

    ``on_death(notice)`` is called on the loop once per newly known death of a peer;
    ``on_beat(heartbeat)`` with each heartbeat of a live peer's life (what it says besides
    being alive, such as its pose: one subscription to heartbeats per process); ``fenced``
    is set when this robot's own life has been declared dead (it must stop).
    Run ``await service.run()`` inside the agent's TaskGroup.
    """

    def __init__(self, bus: Bus, robot: int, incarnation: int, *,
                 heartbeat_period: float = DEFAULT_HEARTBEAT_PERIOD,
                 timeout: float = DEFAULT_TIMEOUT,
                 token_grace: float = DEFAULT_TOKEN_GRACE,
                 info: Callable[[], HeartbeatInfo] = HeartbeatInfo,
                 on_death: Callable[[DeathNotice], None] | None = None,
                 on_beat: Callable[[Heartbeat], None] | None = None,
                 lease: float = DEFAULT_LEASE_MS / 1000,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.bus = bus
        self.robot = robot
        self.incarnation = incarnation
        # The service ticks every min(heartbeat period, token grace) / 2: a longer grace
        # (crowded fleets, deploy.settings.fleet_timing) makes an idle agent wake less often.
        self.detector = FailureDetector(timeout=timeout, token_grace=token_grace,
                                        detector=robot, confirm_tokens=True)
        self.heartbeats = HeartbeatPublisher(bus, robot, incarnation,
                                             period=heartbeat_period, info=info)
        self.fenced = asyncio.Event()
        self._on_death = on_death
        self._on_beat = on_beat
        self._clock = clock
        self.lease = lease
        self._last_tick: float | None = None
        self._reminded: dict[int, float] = {}
        self._soon = asyncio.Event()
        self._last_beat = -math.inf
        self._census_asked_at: float | None = None  # a census is on its way
        self.refuted_deletions = 0

    def beat_soon(self) -> None:
        """Publish the next heartbeat now rather than at its period: a peer waits for what
        it acknowledges (an ORMSTC claim is decided only once every live peer's heartbeat
        says it was heard). At most one per period / SOON_FRACTION."""
        self._soon.set()

    def _news(self, notice: DeathNotice) -> None:
        if notice.robot == self.robot:
            # Only a verdict on this very life fences it: a notice about a life it never
            # had is a forgery (accept_notice), never an order to stop.
            if notice.incarnation == self.incarnation:
                self.fenced.set()
            return
        if self._on_death is not None:
            self._on_death(notice)

    def _on_heartbeat(self, key: str, hb: Heartbeat) -> None:
        if hb.robot == self.robot:
            return
        now = self._clock()
        if not self.detector.on_heartbeat(hb, now):
            self._remind(hb, now)
        elif self._on_beat is not None:
            self._on_beat(hb)

    def _remind(self, hb: Heartbeat, now: float) -> None:
        """A dead life is still beating (it was hung, or missed the notice during an
        outage): tell it again, at most once per timeout, so it fences itself."""
        notice = self.detector.death_of(hb.robot)
        if notice is None or hb.incarnation > notice.incarnation:
            return
        if now - self._reminded.get(hb.robot, -float("inf")) < self.detector.timeout:
            return
        self._reminded[hb.robot] = now
        self.bus.publish(keys.death(self.bus.mission, hb.robot), notice)

    def _on_notice(self, key: str, notice: DeathNotice) -> None:
        self.accept_notice(notice)

    def accept_notice(self, notice: DeathNotice) -> bool:
        """Act on a death notice from the wire (subscription or state reply) unless
        FailureDetector.notice_problem or this robot's own incarnation refuses it (counted
        as a "forged" drop); True if it was news or fences this life."""
        problem = self.detector.notice_problem(notice)
        if problem is None and notice.robot == self.robot \
                and notice.incarnation > self.incarnation:
            problem = f"this robot never had incarnation {notice.incarnation}"
        if problem is not None:
            self.bus.drops.count("death", "forged", problem)
            return False
        if self.detector.on_death_notice(notice) or notice.robot == self.robot:
            self._news(notice)
            return True
        return False

    def _on_token(self, key: str, present: bool) -> None:
        parsed = keys.parse(key)
        if parsed is None or parsed.robot is None or parsed.incarnation is None:
            return
        if parsed.robot == self.robot:
            return
        if present:
            self.detector.on_token(parsed.robot, parsed.incarnation, self._clock())
        else:
            self.detector.on_token_deleted(parsed.robot, parsed.incarnation, self._clock())


    def tick(self) -> list[DeathNotice]:
        """Check connectivity, expire, and broadcast the deaths found (one call per tick)."""
        now = self._clock()
        stalled = 0.0 if self._last_tick is None else now - self._last_tick
        if stalled > self.detector.timeout / 2:
            self.detector.on_local_stall(now)
        if stalled > self.lease * LEASE_STALL_FRACTION:
            self.detector.doubt_token_deletions(now, now + max(self.detector.timeout, self.lease))
        self._last_tick = now
        self.detector.set_connected(self.bus.connected(), now)
        if self.detector.unconfirmed_token_losses() and self._census_asked_at is None:
            self._ask_census(now)
        notices = self.detector.expire(now)
        for notice in notices:
            self.bus.publish(keys.death(self.bus.mission, notice.robot), notice)
            self._news(notice)
        return notices

    def _ask_census(self, now: float) -> None:
        """Ask the router which tokens it holds; the answer confirms or refutes the token
        deletions heard so far (FailureDetector.on_token_census). One question at a time;
        an answer that proves nothing (no one reached, a timeout, or this robot's own token
        missing from it) is asked again at the next tick, and heartbeats still decide
        meanwhile."""
        self._census_asked_at = now
        self.bus.ask_tokens(keys.all_alive(self.bus.mission),
                            max(CENSUS_TIMEOUT, self.detector.token_grace),
                            lambda answer: self._on_census(now, answer))

    def _on_census(self, asked_at: float, answer: frozenset[str] | None) -> None:
        self._census_asked_at = None
        if answer is None or not self.bus.connected():
            return
        present = set()
        for key in answer:
            parsed = keys.parse(key)
            if parsed is not None and parsed.robot is not None \
                    and parsed.incarnation is not None:
                present.add((parsed.robot, parsed.incarnation))
        if (self.robot, self.incarnation) not in present:
            # Zenoh 1.10 now and then ends a liveliness get at once with no reply at all,
            # not even this session's own token (at least five times in about a hundred
            # runs of the service's test): an answer without it proves nothing, and the
            # next tick asks again.
            return
        refuted = self.detector.on_token_census(present, asked_at, self._clock())
        if refuted:
            self.refuted_deletions += len(refuted)
            _log.warning("robot %d: the router still holds the tokens of robots %s, whose "
                         "deletion this process heard: its own link dropped and came back",
                         self.robot, refuted)

    async def run(self) -> None:
        mission = self.bus.mission
        self.bus.declare_token(keys.alive(mission, self.robot, self.incarnation))
        heartbeats = self.bus.subscribe(keys.all_heartbeats(mission), Heartbeat,
                                        self._on_heartbeat, BoundedFifo(4096))
        notices = self.bus.subscribe(keys.all_deaths(mission), DeathNotice, self._on_notice,
                                     BoundedFifo(4096))
        watch = self.bus.watch_liveliness(
            keys.all_alive(mission), lambda k: self._on_token(k, True),
            lambda k: self._on_token(k, False))
        tick = min(self.heartbeats.period, self.detector.token_grace) / 2
        period = self.heartbeats.period
        next_beat = next_tick = self._clock()
        try:
            while True:
                now = self._clock()
                if self._soon.is_set():
                    next_beat = min(next_beat, self._last_beat + period / SOON_FRACTION)
                if now >= next_beat:
                    self._soon.clear()
                    self.heartbeats.beat()
                    self._last_beat, next_beat = now, now + period
                if now >= next_tick:
                    self.tick()
                    next_tick = now + tick
                delay = max(min(next_beat, next_tick) - self._clock(), 0.0)
                if self._soon.is_set():  # asked for, held back by the rate: no wait on it
                    await asyncio.sleep(delay)
                    continue
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(delay):
                        await self._soon.wait()
        finally:
            watch.close()
            heartbeats.close()
            notices.close()

    def declare_absent(self, robot: int) -> None:
        """Robot ``robot`` was never heard and the fleet goes on without it: declare its
        first life dead, so simhw fences and clears its body and, should it boot after all,
        it fences itself instead of covering what the others divided."""
        notice = DeathNotice(robot, 1, self.robot, "heartbeat", self._clock())
        if self.detector.on_death_notice(notice):
            self.bus.publish(keys.death(self.bus.mission, robot), notice)
            self._news(notice)

    def leave(self, now: float | None = None) -> None:
        """Announce a voluntary departure (reason "leaving") before the process exits."""
        stamp = self._clock() if now is None else now
        notice = DeathNotice(self.robot, self.incarnation, self.robot, "leaving", stamp)
        self.bus.publish(keys.death(self.bus.mission, self.robot), notice)
