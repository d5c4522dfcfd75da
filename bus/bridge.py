"""asyncio bridge over one open Zenoh session.

Zenoh's receive threads hand each declaration's samples to a thread of its own
(bus.handoff), which only appends the raw sample to a small buffer under a lock and, if no
wake-up is pending, schedules one with ``call_soon_threadsafe``: a burst of samples costs
one wake-up (measured ~40k msg/s against ~15k/s with one wake-up per sample). Decoding,
handlers, responders and liveliness callbacks all run on the event loop. Buffers are bounded
by the subscription's policy so a slow consumer costs dropped (and counted) messages, never
a blocked Zenoh thread.

Use ``async with Bus(session, mission) as bus`` (or ``Bus.connect(settings)``): async
query responders run in the bus's own task group, which is cancelled and awaited on exit.
"""

from __future__ import annotations

import asyncio
import contextlib
import inspect
import logging
import threading
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Sequence
from contextlib import asynccontextmanager
from typing import Any, Generic, TypeVar

import zenoh

from bus import keys
from bus.codec import DEFAULT_MAX_PAYLOAD, Expected, decode, encode
from bus.config import ConnectionSettings, open_session_async
from bus.drops import DropCounter
from bus.errors import BusClosedError, DecodeError
from bus.faults import MessageFaults
from bus.handles import LivelinessWatch, QueryableHandle, Responder
from bus.handoff import handed_off
from bus.inbox import BoundedFifo, Inbox, LatestWins, Policy, Received
from bus.messages.schema import ROBOT_NAMED
from bus.qos import DEFAULT as DEFAULT_QOS
from bus.qos import Qos, qos_for
from bus.recovery import CacheDepths, MissedSources, MissReport, Publishers, declare_recovering

__all__ = ["BoundedFifo", "Bus", "LatestWins", "LivelinessWatch", "Policy",
           "QueryableHandle", "Received", "Subscription"]

_log = logging.getLogger("mstc.bus")

M = TypeVar("M")
T = TypeVar("T")


class Subscription(Generic[M]):
    """Decoded messages of one key expression: ``async for rx in sub`` or ``await sub.recv()``
    when no handler was given; with a handler, it is called on the loop for each message."""

    def __init__(self, bus: Bus, key: str, expected: Expected[M], policy: Policy,
                 handler: Callable[[str, M], None] | None) -> None:
        self.key = key
        self._bus = bus
        self._expected = expected
        self._handler = handler
        self._event = asyncio.Event()
        self._inbox: Inbox[bytes] = Inbox(
            bus.loop, policy, self._on_wake,
            lambda k: bus.drops.count(keys.kind_of(k), "overflow", f"buffer full on {k}"))
        # zenoh Subscribers, zenoh.ext AdvancedSubscribers and their miss listeners
        self._declared: list[Any] = []
        self.sources: MissedSources | None = None  # for a recovering subscription

    def _on_sample(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        if self.sources is not None:
            self.sources.heard(sample)
        key = str(sample.key_expr)
        # Refuse a flood of huge payloads before copying them out of Zenoh's buffers.
        if len(sample.payload) > self._bus.max_payload:
            self._bus.drops.count(keys.kind_of(key), "oversized",
                                  f"{key}: {len(sample.payload)} bytes")
            return
        faults = self._bus.faults
        if faults is not None and faults.incoming_dropped(keys.kind_of(key)):
            return
        self._inbox.push(key, sample.payload.to_bytes())

    def _on_wake(self) -> None:
        if self._handler is None:
            self._event.set()
            return
        while (item := self._next()) is not None:
            try:
                self._handler(item.key, item.msg)
            except Exception:  # noqa: BLE001 - a handler bug must not stop delivery of the rest
                _log.exception("handler for %s failed on %s", self.key, item.key)
                self._bus.drops.count(keys.kind_of(item.key), "handler_error")

    def _next(self) -> Received[M] | None:
        while (raw := self._inbox.pop()) is not None:
            msg = self._bus.decode_or_count(raw[0], raw[1], self._expected)
            if msg is not None:
                return Received(raw[0], msg)
        return None

    def try_recv(self) -> Received[M] | None:
        """The next buffered message, or None without waiting."""
        return self._next()

    async def recv(self) -> Received[M]:
        """Wait for the next message; BusClosedError once the subscription is closed."""
        while True:
            item = self._next()
            if item is not None:
                return item
            if self._inbox.closed:
                raise BusClosedError(f"subscription to {self.key} is closed")
            self._event.clear()
            await self._event.wait()

    def __aiter__(self) -> AsyncIterator[Received[M]]:
        return self

    async def __anext__(self) -> Received[M]:
        try:
            return await self.recv()
        except BusClosedError:
            raise StopAsyncIteration from None

    def close(self) -> None:
        self._inbox.close()
        self._event.set()
        declared, self._declared = self._declared, []
        for declaration in reversed(declared):  # miss listeners before their subscribers
            declaration.undeclare()


class Bus:
    """One Zenoh session seen from one asyncio loop. Enter with ``async with``."""

    def __init__(self, session: zenoh.Session, mission: str, *,
                 drops: DropCounter | None = None,
                 max_payload: int = DEFAULT_MAX_PAYLOAD,
                 faults: MessageFaults | None = None) -> None:
        self.session = session
        self.faults = faults  # injected message faults (bus.faults), for robustness trials
        self.mission = keys.check_mission(mission)
        self.drops = drops or DropCounter()
        self.max_payload = max_payload
        self._loop: asyncio.AbstractEventLoop | None = None
        self._tasks: asyncio.TaskGroup | None = None
        self._pending: set[asyncio.Task[None]] = set()
        self._closables: list[Subscription[Any] | LivelinessWatch | QueryableHandle] = []
        self._tokens: list[zenoh.LivelinessToken] = []
        self._publishers = Publishers(session)
        self._cache_depth = CacheDepths()

    @classmethod
    @asynccontextmanager
    async def connect(cls, settings: ConnectionSettings, **kwargs: Any) -> AsyncIterator[Bus]:
        """Open a session for ``settings`` and a Bus on it; both closed on exit."""
        async with open_session_async(settings) as session, \
                cls(session, settings.mission, **kwargs) as bus:
            yield bus

    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        if self._loop is None:
            raise BusClosedError("use the Bus inside 'async with'")
        return self._loop

    async def __aenter__(self) -> Bus:
        self._loop = asyncio.get_running_loop()
        self._tasks = asyncio.TaskGroup()
        await self._tasks.__aenter__()
        return self

    async def __aexit__(self, *exc_info: Any) -> None:
        self.close_declarations()
        tasks, self._tasks = self._tasks, None
        if tasks is not None:
            for task in list(self._pending):
                task.cancel()
            await tasks.__aexit__(*exc_info)

    def close_declarations(self) -> None:
        """Undeclare every subscriber, queryable and token of this bus."""
        for item in self._closables:
            item.close()
        self._closables.clear()
        for token in self._tokens:
            token.undeclare()
        self._tokens.clear()
        self._publishers.close()

    # --- pub/sub --------------------------------------------------------------------------

    def publish(self, key: str, msg: Any, qos: Qos | None = None) -> None:
        """Encode and put ``msg`` on ``key`` with its kind's QoS (bus.qos) unless given; a
        key of a recoverable family goes through its advanced publisher (bus.recovery)."""
        chosen = qos or qos_for(type(msg))
        payload = encode(msg, max_size=self.max_payload)
        depth = self._cache_depth(key)

        def put() -> None:
            if depth:
                self._publishers.put(key, payload, chosen, depth)
                return
            self.session.put(key, payload, priority=chosen.priority,
                             congestion_control=chosen.congestion, express=chosen.express)

        if self.faults is None:
            put()
            return
        for delay in self.faults.outgoing(keys.kind_of(key)):
            if delay <= 0:
                put()
            else:
                self.loop.call_later(delay, self._put_late, put)

    def _put_late(self, put: Callable[[], None]) -> None:
        """A delayed copy (bus.faults): the session may have closed meanwhile."""
        try:
            put()
        except Exception:  # noqa: BLE001 - a late copy of a closed session is simply lost
            _log.debug("a delayed message was lost: the session closed")

    def subscribe(self, key: str, expected: Expected[M], handler: Callable[[str, M], None]
                  | None = None, policy: Policy | None = None, *, recover: bool = False,
                  on_miss: Callable[[str | None, int, float | None], None] | None = None,
                  ) -> Subscription[M]:
        """Subscribe to ``key`` (wildcards allowed); see Subscription. With ``recover`` (or
        ``on_miss``) the subscription recovers what it missed from the publishers' caches
        (bus.recovery); each sample no cache held any more is counted as a drop ("missed")
        and reported to ``on_miss(key, count, last heard)`` on the loop (key and
        time.monotonic() of the source's last sample, None if it was never heard)."""
        sub: Subscription[M] = Subscription(self, key, expected, policy or BoundedFifo(),
                                            handler)
        if not recover and on_miss is None:
            sub._declared = [handed_off(
                lambda handler: self.session.declare_subscriber(key, handler),
                sub._on_sample, key)]
        else:
            report = MissReport(key, self.drops, self.loop, on_miss)
            sub.sources = report.sources
            sub._declared = declare_recovering(self.session, key, self.mission,
                                               sub._on_sample, report)
        self._closables.append(sub)
        return sub

    def decode_or_count(self, key: str, payload: bytes, expected: Expected[M]) -> M | None:
        """Decode, or count the drop (by key kind) and return None. A message about another
        robot than its key names is dropped too (counted as "robot_mismatch")."""
        try:
            msg = decode(payload, expected, max_size=self.max_payload)
        except DecodeError as error:
            self.drops.count(keys.kind_of(key), "decode", f"{key}: {error}")
            return None
        parsed = keys.parse(key)
        if parsed is not None and parsed.robot is not None:
            named = ROBOT_NAMED.get((getattr(msg, "KIND", ""), parsed.kind))
            if named is not None and getattr(msg, named) != parsed.robot:
                self.drops.count(parsed.kind, "robot_mismatch",
                                 f"{key}: {named} {getattr(msg, named)}")
                return None
        return msg

    # --- queries --------------------------------------------------------------------------

    async def query(self, key: str, request: Any | None, expected: Expected[M], *,
                    timeout: float = 2.0, qos: Qos | None = None) -> list[Received[M]]:
        """Ask every matching queryable; return the valid replies that came within
        ``timeout`` seconds (bad replies are counted as drops)."""
        loop = self.loop
        done = loop.create_future()
        raw: list[tuple[str, bytes | str]] = []  # a payload, or the text of an error reply
        lock = threading.Lock()

        def on_reply(reply: zenoh.Reply) -> None:
            sample = reply.ok
            if sample is not None:
                got: tuple[str, bytes | str] = (str(sample.key_expr), sample.payload.to_bytes())
            else:  # e.g. Zenoh's "Timeout" when the queryable answered too late
                error = reply.err
                got = (key, "" if error is None else
                       error.payload.to_bytes().decode("utf-8", "replace"))
            with lock:
                raw.append(got)

        def on_done() -> None:
            # A closed loop means nobody awaits this query any more.
            with contextlib.suppress(RuntimeError):
                loop.call_soon_threadsafe(_resolve, done)

        chosen = qos or (qos_for(type(request)) if request is not None else DEFAULT_QOS)
        cancel = zenoh.CancellationToken()
        payload = None if request is None else encode(request, max_size=self.max_payload)
        self.session.get(
            key, zenoh.handlers.Callback(on_reply, on_done, indirect=False),
            target=zenoh.QueryTarget.ALL, consolidation=zenoh.ConsolidationMode.NONE,
            timeout=timeout, payload=payload, priority=chosen.priority,
            congestion_control=chosen.congestion, cancellation_token=cancel)
        try:
            # Zenoh ends the query at ``timeout``; the margin only guards against a lost end.
            async with asyncio.timeout(timeout + 1.0):
                await done
        except TimeoutError:
            _log.warning("query %s: no end-of-replies from Zenoh after %.1f s", key, timeout)
        finally:
            if not done.done():
                cancel.cancel()
        with lock:
            got = list(raw)
        out: list[Received[M]] = []
        for reply_key, data in got:
            if isinstance(data, str):
                self.drops.count(keys.kind_of(reply_key), "reply_error", data)
                continue
            msg = self.decode_or_count(reply_key, data, expected)
            if msg is not None:
                out.append(Received(reply_key, msg))
        return out

    def declare_queryable(self, key: str, responder: Responder,
                          request_type: Expected[Any] | None = None, *,
                          max_queue: int = 1024) -> QueryableHandle:
        """Serve queries on the concrete ``key``. ``responder(request)`` gets the decoded
        request (None when ``request_type`` is None or the query had no payload) and returns
        a message, a sequence of messages, or an awaitable of either; each is a reply."""
        handle = QueryableHandle(
            self.loop, self.drops, key, max_queue,
            lambda query: self.answer(key, query, responder, request_type))
        handle._zenoh = handed_off(
            lambda handler: self.session.declare_queryable(key, handler), handle._on_query, key)
        self._closables.append(handle)
        return handle

    def answer(self, key: str, query: zenoh.Query, responder: Responder,
               request_type: Expected[Any] | None) -> None:
        """Run ``responder`` for ``query`` on the loop (async ones in the bus task group)."""
        request = None
        payload = query.payload
        if request_type is not None and payload is not None:
            data = payload.to_bytes()
            request = self.decode_or_count(key, data, request_type)
            if request is None:
                _finish(query, error="malformed request")
                return
        try:
            result = responder(request)
        except Exception as error:  # noqa: BLE001 - logged and sent to the querier
            _log.exception("responder on %s failed", key)
            _finish(query, error=f"responder failed: {error}")
            return
        if inspect.isawaitable(result):
            if self._tasks is None:
                _finish(query, error="bus closed")
                return
            task = self._tasks.create_task(self._answer_later(key, query, result))
            self._pending.add(task)
            task.add_done_callback(self._pending.discard)
            return
        self._reply(key, query, result)

    async def _answer_later(self, key: str, query: zenoh.Query,
                            result: Awaitable[Any]) -> None:
        try:
            value = await result
        except asyncio.CancelledError:
            _finish(query, error="bus closed")
            raise
        except Exception as error:  # noqa: BLE001 - logged and sent to the querier
            _log.exception("async responder on %s failed", key)
            _finish(query, error=f"responder failed: {error}")
            return
        self._reply(key, query, value)

    def _reply(self, key: str, query: zenoh.Query, result: Any) -> None:
        items: Sequence[Any] = result if isinstance(result, (list, tuple)) else (
            () if result is None else (result,))
        try:
            for msg in items:
                query.reply(key, encode(msg, max_size=self.max_payload))
        finally:
            query.drop()

    # --- liveliness -----------------------------------------------------------------------

    def declare_token(self, key: str) -> zenoh.LivelinessToken:
        """Declare a liveliness token, undeclared when the bus closes (or the process dies)."""
        token = self.session.liveliness().declare_token(key)
        self._tokens.append(token)
        return token

    def watch_liveliness(self, key: str, on_put: Callable[[str], None],
                         on_delete: Callable[[str], None]) -> LivelinessWatch:
        """Watch tokens matching ``key``; existing tokens are reported first as puts."""
        watch = LivelinessWatch(self.loop, self.drops, key, on_put, on_delete)
        watch._zenoh = handed_off(
            lambda handler: self.session.liveliness().declare_subscriber(
                key, handler, history=True), watch._on_sample, f"tokens {key}")
        self._closables.append(watch)
        return watch

    def connected(self) -> bool:
        """Whether the session reaches anyone now: a router (client mode) or a peer."""
        info = self.session.info
        return any(True for _ in info.routers_zid()) or any(True for _ in info.peers_zid())

    def ask_tokens(self, key: str, timeout: float,
                   on_answer: Callable[[frozenset[str] | None], None]) -> None:
        """Ask the network which tokens matching ``key`` exist now. ``on_answer`` is called
        on the loop with their keys, or with None when the answer proves nothing: the
        session reached no router or peer when asked (the get then returns only this
        session's own tokens), or the get ran into its timeout (a link that is dead but not
        yet known to be answers nothing, which must not read as "every token is gone")."""
        loop = self.loop
        if not self.connected():
            loop.call_soon(on_answer, None)
            return
        found: set[str] = set()
        lock = threading.Lock()
        asked = time.monotonic()

        def on_reply(reply: zenoh.Reply) -> None:
            sample = reply.ok
            if sample is not None:
                with lock:
                    found.add(str(sample.key_expr))

        def on_done() -> None:
            complete = time.monotonic() - asked < 0.9 * timeout
            with lock:
                answer = frozenset(found) if complete else None
            with contextlib.suppress(RuntimeError):  # the loop closed: nobody waits any more
                loop.call_soon_threadsafe(on_answer, answer)

        self.session.liveliness().get(
            key, zenoh.handlers.Callback(on_reply, on_done, indirect=False), timeout=timeout)


def _resolve(future: asyncio.Future[None]) -> None:
    if not future.done():
        future.set_result(None)


def _finish(query: zenoh.Query, error: str) -> None:
    try:
        query.reply_err(error.encode())
    finally:
        query.drop()
