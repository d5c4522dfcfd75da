"""Waiting in tests on something observable, with a deadline, instead of a fixed sleep.

A fixed sleep is too short on a loaded machine (a positive check fails) and says nothing
in a negative check (nothing happened, but did it have its chance?). These helpers wait for
a condition; a negative check first waits for a positive witness that the thing it rules
out would have been seen by then.
"""

from __future__ import annotations

import asyncio
import inspect
import itertools
import time
from collections.abc import Awaitable, Callable

import zenoh

from bus import keys
from bus.bridge import Bus
from bus.config import ConnectionSettings

POLL = 0.02  # seconds between two looks at the condition
_probes = itertools.count()


async def wait_until(predicate: Callable[[], bool | Awaitable[bool]], timeout: float,
                     what: str) -> None:
    """Return as soon as ``predicate()`` (a plain or an async function) is true; fail the
    test with ``what`` if it is still false after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if inspect.isawaitable(result):
            result = await result
        if result:
            return
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        await asyncio.sleep(POLL)


def wait_until_sync(predicate: Callable[[], bool], timeout: float, what: str) -> None:
    """:func:`wait_until` for tests outside an event loop."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() >= deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(POLL)


async def through_router(bus: Bus, router: str, timeout: float = 10.0) -> None:
    """Return once a sample put by another session on ``router`` reaches ``bus``.

    A session's declarations reach the router in order, so afterwards the router routes
    every subscription ``bus`` declared before the call; and as the router forwards to a
    session in order of priority, what it got before the probe has reached ``bus`` too."""
    # A key of the test's own under the mission: no process of the project uses it.
    probe = f"{keys.ROOT}/{bus.mission}/test-probe/{next(_probes)}"
    arrived = asyncio.Event()
    loop = asyncio.get_running_loop()
    subscriber = bus.session.declare_subscriber(
        probe, lambda _sample: loop.call_soon_threadsafe(arrived.set))
    try:
        settings = ConnectionSettings(connect=(router,), mission=bus.mission)
        async with Bus.connect(settings) as other:
            await _put_until(other.session, probe, arrived, timeout)
    finally:
        subscriber.undeclare()


async def _put_until(session: zenoh.Session, key: str, arrived: asyncio.Event,
                     timeout: float) -> None:
    # Put again until heard: the router may learn of the probe subscription after a put.
    async with asyncio.timeout(timeout):
        while not arrived.is_set():
            # Lowest priority: it cannot overtake anything the router got before it.
            session.put(key, b"probe", priority=zenoh.Priority.BACKGROUND)
            try:
                await asyncio.wait_for(arrived.wait(), 0.1)
            except TimeoutError:
                continue
