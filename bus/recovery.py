"""Recoverable families on Zenoh's advanced pub/sub (``zenoh.ext``).

A family with a publisher cache depth in the wire schema (``KeyFamily.cache``,
bus.messages.schema.RECOVERABLE) is published by an advanced publisher per key: it keeps
that many samples, numbers them (sample-miss detection) and, when the number changed, says
the last one every HEARTBEAT_S seconds. An advanced subscriber with history and heartbeat
recovery then asks the publisher's cache for what it missed (a router restart or freeze, a
late start) and hands samples over in each publisher's order; what no cache holds any more
(the publisher died, or the cut outlasted its cache) is reported as a miss: a source and a
count, never silently.

The extra keys live under each key's ``@adv`` chunk (``<key>/@adv/pub/<zid>/<eid>/_``: the
publisher's liveliness token, its cache queryable and its heartbeats); the router's access
rules allow them where the family itself is allowed (bus.security.acl).

A recovering subscription to a whole mission (``mstc/<m>/**``, recorders and launchers) is an
advanced subscriber per recoverable family and a plain subscriber for every other key: one
advanced subscriber on every key lost plain samples of a tree fleet's report flood (a step of
one robot missing from the recording, its report judged as a failed run), and plain families
have nothing to recover anyway.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh
import zenoh.ext

from bus import keys
from bus.drops import DropCounter
from bus.handoff import handed_off
from bus.messages.schema import RECOVERABLE
from bus.qos import Qos

HEARTBEAT_S = 0.5
# Samples per key a recovering subscriber asks a late publisher's cache for (the deepest
# cache in the schema: the query returns what there is).
HISTORY_SAMPLES = 4096
# What every advanced key hangs under: a verbatim chunk, so ``mstc/<m>/**`` never matches it
ADVANCED_CHUNK = "@adv"


def advanced_keys(key_expr: str) -> str:
    """The key expression of the advanced pub/sub's own keys under ``key_expr``."""
    return f"{key_expr}/{ADVANCED_CHUNK}/**"


class Publishers:
    """One advanced publisher per key of a recoverable family, declared on first use.
    Thread-safe: a delayed copy (bus.faults) may be put from a timer."""

    def __init__(self, session: zenoh.Session) -> None:
        self._session = session
        self._by_key: dict[str, Any] = {}
        self._lock = threading.Lock()

    def put(self, key: str, payload: bytes, qos: Qos, depth: int) -> None:
        with self._lock:
            publisher = self._by_key.get(key)
            if publisher is None:
                publisher = zenoh.ext.declare_advanced_publisher(
                    self._session, key, priority=qos.priority,
                    congestion_control=qos.congestion, express=qos.express,
                    cache=zenoh.ext.CacheConfig(
                        max_samples=depth, replies_config=zenoh.ext.RepliesConfig(
                            priority=qos.priority, congestion_control=qos.congestion)),
                    sample_miss_detection=zenoh.ext.MissDetectionConfig(
                        heartbeat=None, sporadic_heartbeat=HEARTBEAT_S),
                    publisher_detection=True)
                self._by_key[key] = publisher
        publisher.put(payload)

    def close(self) -> None:
        with self._lock:
            publishers, self._by_key = list(self._by_key.values()), {}
        for publisher in publishers:
            publisher.undeclare()


class MissedSources:
    """Which key each advanced publisher (by its entity id) was last heard on, and when: a
    miss names only its source, the recording wants its key and the interval."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._seen: dict[str, tuple[str, float]] = {}

    def heard(self, sample: zenoh.Sample) -> None:
        info = sample.source_info
        if info is not None and info.source_id is not None:
            self._seen[str(info.source_id)] = (str(sample.key_expr), self._clock())

    def last(self, source: str) -> tuple[str, float] | None:
        """The key and the time of the last sample heard from ``source`` (None if none)."""
        return self._seen.get(source)


class MissReport:
    """What a recovering subscription does with a miss, on the Zenoh thread that reports it:
    count it (by the kind of the key its source was last heard on) and hand ``on_miss(key,
    count, last heard)`` to the loop."""

    def __init__(self, key_expr: str, drops: DropCounter, loop: asyncio.AbstractEventLoop,
                 on_miss: Callable[[str | None, int, float | None], None] | None) -> None:
        self.sources = MissedSources()
        self._key_expr, self._drops, self._loop, self._on_miss = key_expr, drops, loop, on_miss

    def __call__(self, source: str, count: int) -> None:
        last = self.sources.last(source)
        where = self._key_expr if last is None else last[0]
        self._drops.count(keys.kind_of(where), "missed", f"{count} from {source}", n=count)
        if self._on_miss is None:
            return
        with contextlib.suppress(RuntimeError):  # the loop closed: nobody listens any more
            self._loop.call_soon_threadsafe(self._on_miss, None if last is None else last[0],
                                            count, None if last is None else last[1])


def declare_recovering_subscriber(session: zenoh.Session, key_expr: str,
                                  on_sample: Callable[[zenoh.Sample], None],
                                  on_miss: Callable[[str, int], None],
                                  ) -> tuple[Any, Any]:
    """An advanced subscriber on ``key_expr`` that asks late and cut-off publishers' caches
    for what it missed; ``on_miss(source id, count)`` (on a Zenoh thread) for samples no
    cache held. Returns the subscriber and its miss listener (undeclare both)."""
    subscriber = handed_off(
        lambda handler: zenoh.ext.declare_advanced_subscriber(
            session, key_expr, handler,
            history=zenoh.ext.HistoryConfig(detect_late_publishers=True,
                                            max_samples=HISTORY_SAMPLES),
            recovery=zenoh.ext.RecoveryConfig(heartbeat=True, periodic_queries=None)),
        on_sample, key_expr)
    listener = subscriber.sample_miss_listener(
        lambda miss: on_miss(str(miss.source), int(miss.nb)))
    return subscriber, listener


def declare_recovering(session: zenoh.Session, key_expr: str, mission: str,
                       on_sample: Callable[[zenoh.Sample], None],
                       on_miss: Callable[[str, int], None]) -> list[Any]:
    """The declarations of a recovering subscription to ``key_expr`` (undeclare each): on the
    whole of ``mission``, advanced subscribers on the recoverable families only and a plain
    subscriber that passes on every other key; else one advanced subscriber."""
    if key_expr != keys.everything(mission):
        return list(declare_recovering_subscriber(session, key_expr, on_sample, on_miss))
    declared: list[Any] = []
    for label in sorted(RECOVERABLE):
        declared += declare_recovering_subscriber(session, keys.wildcard(label, mission),
                                                  on_sample, on_miss)
    depth = CacheDepths()

    def on_plain(sample: zenoh.Sample) -> None:
        if not depth(str(sample.key_expr)):
            on_sample(sample)

    declared.append(handed_off(lambda handler: session.declare_subscriber(key_expr, handler),
                               on_plain, key_expr))
    return declared


class CacheDepths:
    """The publisher cache depth of a key's family (0: not recoverable), remembered per key:
    publishing parses no key twice (a mission has few distinct keys; the memory is dropped
    past MAX_KEYS, which no mission reaches)."""

    MAX_KEYS = 1 << 16

    def __init__(self) -> None:
        self._known: dict[str, int] = {}

    def __call__(self, key: str) -> int:
        known = self._known.get(key)
        if known is None:
            if len(self._known) >= self.MAX_KEYS:
                self._known.clear()
            known = self._known[key] = RECOVERABLE.get(keys.kind_of(key), 0)
        return known
