"""Who is alive: a robot's token and heartbeats, and the async service that feeds the
sans-I/O failure detector (bus.detector, whose docstring says what each signal covers) from
the wire and broadcasts its verdicts. The service also asks the router which tokens it
still holds before a token deletion counts (a census): a link that drops and comes back
between two looks makes Zenoh delete every remote token locally.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import DEFAULT_LEASE_MS
from bus.detector import (
    DEFAULT_HEARTBEAT_PERIOD,
    DEFAULT_TIMEOUT,
    DEFAULT_TOKEN_GRACE,
    FailureDetector,
)
from bus.messages import DeathNotice, Heartbeat, Pose

_log = logging.getLogger("mstc.bus.liveness")

# An early heartbeat (LivelinessService.beat_soon) comes at most this often, as a fraction of
# the period: a burst of peers' claims costs at most 20 heartbeats per period.
SOON_FRACTION = 20
# A loop that ran this fraction of the lease late may have lost its session: a hung process's
# session is dropped after ~0.75 x its lease (bus/config.py), so half of it is taken as enough.
LEASE_STALL_FRACTION = 0.5
# How long the router has to answer which tokens it holds; an answer that took this long
# proves nothing (LivelinessService._ask_census).
CENSUS_TIMEOUT = 1.0


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
        # (crowded fleets, deploy.fleet_timing.fleet_timing) makes an idle agent wake less often.
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
        self._declared: list[DeathNotice] = []  # since the last tick (tick returns them)

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
        self._declare(self.detector.expire(now))
        declared, self._declared = self._declared, []
        return declared

    def _declare(self, notices: list[DeathNotice]) -> None:
        """Broadcast the deaths this detector found; :meth:`tick` returns them."""
        for notice in notices:
            self.bus.publish(keys.death(self.bus.mission, notice.robot), notice)
            self._news(notice)
        self._declared.extend(notices)

    def _ask_census(self, now: float) -> None:
        """Ask the router which tokens it holds; the answer confirms or refutes the token
        deletions heard so far (FailureDetector.on_token_census). One question at a time,
        first asked at a tick; an answer that leaves a deletion unconfirmed asks again at
        once (:meth:`_on_census`). An answer that proves nothing (no one reached, a timeout,
        or this robot's own token missing from it) is asked again at the next tick, and
        heartbeats still decide meanwhile."""
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
        now = self._clock()
        refuted = self.detector.on_token_census(present, asked_at, now)
        if refuted:
            self.refuted_deletions += len(refuted)
            _log.warning("robot %d: the router still holds the tokens of robots %s, whose "
                         "deletion this process heard: its own link dropped and came back",
                         self.robot, refuted)
        # Acted on at once, not at the next tick: in a loaded fleet ticks come a second or
        # more apart, and waiting for two of them took two of the three seconds a SIGKILL
        # took to be declared among 100 robots on 2 cores (docs/protocol.md). Silences stay
        # the tick's (tokens_only): only the tick knows whether this loop itself stalled.
        self._declare(self.detector.expire(now, tokens_only=True))
        if self.detector.unconfirmed_token_losses():
            self._ask_census(now)

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
