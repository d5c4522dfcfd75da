"""The monitor's Zenoh side: every key of a mission, liveliness tokens and state queries.

Bus handlers only append a Record to a deque (its depth is the monitor's queue, shown on
screen and measured by benchmarks/bench_monitor.py); the consumer drains it on the loop.
A late joiner learns the past by querying ``state/*`` (agents' statuses, deaths, verdicts,
agent states with ORMSTC trees and claims) and ``sim/world`` (map, visit counts, first
visitors and crossers, bodies) at start and then every ``world_period`` seconds. State
replies are decoded here from the raw payload, so that a kind this process does not know
(a newer peer's) is kept as an Opaque instead of being counted as a drop. Every kind it
needs is in bus.messages: the monitor imports no agent or simhw code.

The mission subscription recovers (bus.recovery): after a router restart or freeze the
publishers' caches give back what was missed, in order; what no cache holds any more is
recorded as a Gap record naming the key and the interval, so a report can tell lost data
from a failed mission.
"""

from __future__ import annotations

import asyncio
import time
from collections import deque
from collections.abc import Callable

import zenoh

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.errors import DecodeError
from bus.messages import MESSAGE_TYPES, WorldState
from deploy.monitor.recorder import decode_payload
from deploy.monitor.types import Gap, Record, TokenChange
from deploy.monitor.view import FeedStats

QUERY_TIMEOUT_S = 2.0
FIRST_WORLD_RETRY_S = 0.2
SUB_BUFFER = 65536


class LiveFeed:
    """Records of one mission as they arrive; ``t`` counts from ``t0`` (monotonic)."""

    def __init__(self, bus: Bus, t0: float | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.bus = bus
        self.clock = clock
        self.t0 = clock() if t0 is None else t0
        self.queue: deque[Record] = deque()
        self.max_queue = 0
        self.world_seen = False

    def start(self) -> None:
        """Subscribe to every key of the mission and watch the robots' tokens."""
        m = self.bus.mission
        self.bus.subscribe(keys.everything(m), tuple(MESSAGE_TYPES.values()), self._on_msg,
                           BoundedFifo(SUB_BUFFER), on_miss=self._on_miss)
        self.bus.watch_liveliness(keys.all_alive(m), lambda k: self._on_token(k, True),
                                  lambda k: self._on_token(k, False))

    def _push(self, record: Record) -> None:
        self.queue.append(record)
        self.max_queue = max(self.max_queue, len(self.queue))

    def _on_msg(self, key: str, msg: object) -> None:
        self._push(Record(self.clock() - self.t0, key, msg, "sub"))

    def _on_miss(self, key: str | None, missed: int, last_heard: float | None) -> None:
        where = key or keys.everything(self.bus.mission)
        parsed = keys.parse(where)
        self._push(Record(self.clock() - self.t0, where, Gap(
            where, "unknown" if parsed is None else parsed.kind, missed,
            None if last_heard is None else last_heard - self.t0, self.clock() - self.t0),
            "gap"))

    def _on_token(self, key: str, present: bool) -> None:
        parsed = keys.parse(key)
        if parsed is None or parsed.robot is None or parsed.incarnation is None:
            self.bus.drops.count("alive", "invalid", key)
            return
        self._push(Record(self.clock() - self.t0, key,
                          TokenChange(parsed.robot, parsed.incarnation, present), "token"))

    def drain(self, limit: int = 100_000) -> list[Record]:
        out: list[Record] = []
        while self.queue and len(out) < limit:
            out.append(self.queue.popleft())
        return out

    async def sync(self) -> None:
        """Ask for the re-learnable state and the world; the answers join the queue."""
        m = self.bus.mission
        for key in (keys.all_states(m), keys.world(m)):
            for reply_key, payload in await asyncio.to_thread(self._get, key):
                if payload is None:
                    self.bus.drops.count(keys.kind_of(reply_key), "reply_error")
                    continue
                try:
                    msg = decode_payload(payload, self.bus.max_payload)
                except DecodeError as error:
                    self.bus.drops.count(keys.kind_of(reply_key), "decode",
                                         f"{reply_key}: {error}")
                    continue
                self.world_seen = self.world_seen or isinstance(msg, WorldState)
                self._push(Record(self.clock() - self.t0, reply_key, msg, "query"))

    def _get(self, key: str) -> list[tuple[str, bytes | None]]:
        replies = self.bus.session.get(key, target=zenoh.QueryTarget.ALL,
                                       consolidation=zenoh.ConsolidationMode.NONE,
                                       timeout=QUERY_TIMEOUT_S)
        out: list[tuple[str, bytes | None]] = []
        for reply in replies:
            sample = reply.ok
            out.append((key, None) if sample is None else
                       (str(sample.key_expr), sample.payload.to_bytes()))
        return out

    def stats(self, rate: float, source: str = "live") -> FeedStats:
        drops = {f"{kind}.{why}": n for (kind, why), n in self.bus.drops.snapshot().items()}
        return FeedStats(source=source, rate=rate, drops=drops, queue=len(self.queue),
                         max_queue=self.max_queue)


async def poll(feed: LiveFeed, period: float) -> None:
    """Query state and world now and every ``period`` seconds, until cancelled; more often
    until the world has answered once (the map is needed for coverage, and a fast mission
    may be over before the first period ends)."""
    while True:
        await feed.sync()
        await asyncio.sleep(period if feed.world_seen else min(period, FIRST_WORLD_RETRY_S))
