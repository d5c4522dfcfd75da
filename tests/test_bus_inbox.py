"""The thread-to-loop hand-off (bus.inbox): a flood of samples must not starve the loop."""

from __future__ import annotations

import asyncio
import sys

import pytest

from bus.config import GIL_SWITCH_INTERVAL_S, ConnectionSettings, open_session_async
from bus.inbox import WAKE_BATCH, BoundedFifo, Inbox, LatestWins, Policy


@pytest.mark.parametrize("policy", [BoundedFifo(100_000), LatestWins()],
                         ids=["fifo", "latest"])
async def test_a_flood_is_handed_over_in_slices_and_other_work_runs_between(
        policy: Policy) -> None:
    """A handler that pops until the inbox is empty gets WAKE_BATCH items per wake-up; work
    the loop had ready runs before the rest, and nothing is lost or reordered."""
    loop = asyncio.get_running_loop()
    handled: list[int] = []
    inbox: Inbox[int] = Inbox(loop, policy, lambda: drain(), lambda _key: None)

    def drain() -> None:
        while (item := inbox.pop()) is not None:
            handled.append(item[1])

    total = 5 * WAKE_BATCH + 7
    for value in range(total):  # what a Zenoh thread does; the first push schedules a wake
        inbox.push(f"k/{value}", value)
    seen_by_timer: list[int] = []
    loop.call_soon(lambda: seen_by_timer.append(len(handled)))
    for _ in range(20):
        await asyncio.sleep(0)
    assert seen_by_timer == [WAKE_BATCH]  # it ran after one slice, not after the flood
    assert handled == list(range(total))
    assert inbox.pop() is None


async def test_outside_a_wake_up_pop_is_not_limited() -> None:
    """A consumer that pulls (Subscription.recv) gets everything queued."""
    loop = asyncio.get_running_loop()
    inbox: Inbox[int] = Inbox(loop, BoundedFifo(100_000), lambda: None, lambda _key: None)
    for value in range(3 * WAKE_BATCH):
        inbox.push("k", value)
    got = [item[1] for _ in range(3 * WAKE_BATCH) if (item := inbox.pop()) is not None]
    assert got == list(range(3 * WAKE_BATCH))


async def test_opening_a_session_shortens_the_gil_switch_interval(router: str) -> None:
    """Zenoh's threads need the GIL for every sample they hand over; with the default 5 ms
    a busy loop would let them in about 200 times a second (see bus.config)."""
    sys.setswitchinterval(0.005)
    async with open_session_async(ConnectionSettings(connect=(router,), mission="gil")):
        assert sys.getswitchinterval() <= GIL_SWITCH_INTERVAL_S
