"""A router restart loses what was published during the outage; re-announced and queryable
state lets a subscriber re-learn it. Publisher in a separate process (subprocess, no fork)."""

from __future__ import annotations

import asyncio
import subprocess
import sys
import time

import pytest

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import ConnectionSettings
from bus.messages import RobotStatus
from bus.router import start_router_process, stop_process

pytestmark = pytest.mark.integration

ANNOUNCER = """
import asyncio, sys
from bus import keys
from bus.announce import Announcer
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.messages import RobotStatus

async def main():
    settings = ConnectionSettings(connect=(sys.argv[1],), mission="restart")
    async with Bus.connect(settings) as bus:
        announcer = Announcer(bus, keys.state(bus.mission, 7), period=0.3)
        announcer.set(keys.status(bus.mission, 7), RobotStatus(
            robot=7, incarnation=3, start=(2, 4), algo="ormstc", plan_digest="-",
            state="covering"))
        print("ready", flush=True)
        await announcer.run()

asyncio.run(main())
"""

EXPECTED = RobotStatus(robot=7, incarnation=3, start=(2, 4), algo="ormstc", plan_digest="-",
                       state="covering")


async def _query_until_found(bus: Bus, timeout: float) -> list[RobotStatus]:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        found = await bus.query(keys.all_states(bus.mission), None, RobotStatus, timeout=0.5)
        if found:
            return [r.msg for r in found]
        await asyncio.sleep(0.1)
    return []


@pytest.mark.slow
async def test_subscriber_relearns_state_after_router_restart(free_port: int) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port}"
    router = start_router_process(endpoint)
    publisher = subprocess.Popen([sys.executable, "-c", ANNOUNCER, endpoint],
                                 stdout=subprocess.PIPE, text=True)
    try:
        settings = ConnectionSettings(connect=(endpoint,), mission="restart")
        async with Bus.connect(settings) as bus:
            sub = bus.subscribe(keys.all_statuses(bus.mission), RobotStatus,
                                policy=BoundedFifo(100))
            async with asyncio.timeout(10.0):
                assert (await sub.recv()).msg == EXPECTED
            assert await _query_until_found(bus, 5.0) == [EXPECTED]

            stop_process(router)
            await asyncio.sleep(1.0)
            while sub.try_recv() is not None:
                pass  # forget what was heard before the outage
            router = start_router_process(endpoint)
            restarted = time.monotonic()

            async with asyncio.timeout(8.0):
                again = await sub.recv()
            relearn_s = time.monotonic() - restarted
            assert again.msg == EXPECTED
            assert await _query_until_found(bus, 5.0) == [EXPECTED]
            print(f"re-learned by re-announce {relearn_s:.2f} s after the router restart")
    finally:
        publisher.kill()
        publisher.wait()
        assert publisher.stdout is not None
        publisher.stdout.close()
        stop_process(router)


async def test_clients_may_start_before_the_router(free_port: int) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port}"
    settings = ConnectionSettings(connect=(endpoint,), mission="order")

    async def early() -> Bus | None:
        async with Bus.connect(settings) as bus:
            sub = bus.subscribe(keys.all_statuses(bus.mission), RobotStatus)
            async with asyncio.timeout(10.0):
                return (await sub.recv()).msg  # type: ignore[return-value]
        return None

    async with asyncio.TaskGroup() as group:
        waiting = group.create_task(early())
        # The loop keeps running (this sleep returns) while the early client waits.
        await asyncio.sleep(0.5)
        assert not waiting.done()
        router = start_router_process(endpoint)
        try:
            async with Bus.connect(settings) as late:
                async with asyncio.timeout(10.0):
                    while not waiting.done():
                        late.publish(keys.status(late.mission, 7), EXPECTED)
                        await asyncio.sleep(0.1)
        finally:
            stop_process(router)
    assert waiting.result() == EXPECTED
