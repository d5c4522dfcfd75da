"""LivelinessService end to end: a robot process is SIGKILLed (token path) or SIGSTOPped
(heartbeat path), peers declare it dead, and a woken stale life learns it is fenced."""

from __future__ import annotations

import asyncio
import itertools
import signal
import subprocess
import sys
import time
from collections.abc import AsyncIterator

import pytest
from waiting import through_router

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import ConnectionSettings
from bus.liveness import SOON_FRACTION, LivelinessService
from bus.messages import DeathNotice, Heartbeat

pytestmark = pytest.mark.integration
_missions = itertools.count()

ROBOT = """
import asyncio, sys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.liveness import LivelinessService

async def main():
    lease_ms, timeout = int(sys.argv[4]), float(sys.argv[5])
    settings = ConnectionSettings(connect=(sys.argv[1],), mission=sys.argv[2], lease_ms=lease_ms)
    async with Bus.connect(settings) as bus:
        service = LivelinessService(bus, robot=int(sys.argv[3]), incarnation=1,
                                    heartbeat_period=0.1, timeout=timeout)
        async with asyncio.TaskGroup() as group:
            task = group.create_task(service.run())
            print("ready", flush=True)
            await service.fenced.wait()
            print("fenced", flush=True)
            task.cancel()

asyncio.run(main())
"""


@pytest.fixture
def mission() -> str:
    return f"live{next(_missions)}"


@pytest.fixture
def watch_timeout() -> float:
    """The watcher's heartbeat timeout: short, so a hung robot is declared quickly."""
    return 0.6


@pytest.fixture
async def watcher(router: str, mission: str, watch_timeout: float
                  ) -> AsyncIterator[tuple[LivelinessService, list[DeathNotice]]]:
    deaths: list[DeathNotice] = []
    async with Bus.connect(ConnectionSettings(connect=(router,), mission=mission)) as bus:
        service = LivelinessService(bus, robot=0, incarnation=1, heartbeat_period=0.1,
                                    timeout=watch_timeout, on_death=deaths.append)
        async with asyncio.TaskGroup() as group:
            task = group.create_task(service.run())
            yield service, deaths
            task.cancel()


async def start_robot(router: str, mission: str, robot: int, *, lease_ms: int = 1000,
                      timeout: float = 0.6) -> subprocess.Popen[str]:
    """A robot process, once it says it is ready. Its readiness is awaited in a thread: a
    blocking read here stalled the watcher's loop while the process started (0.5 s and
    more in a loaded CI run), and a loop that stalls half a lease doubts the token deletions
    heard next (bus.liveness, LEASE_STALL_FRACTION), so a SIGKILL soon after was declared
    by heartbeat instead of by token."""
    proc = subprocess.Popen([sys.executable, "-c", ROBOT, router, mission, str(robot),
                             str(lease_ms), str(timeout)], stdout=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    line = await asyncio.wait_for(asyncio.to_thread(proc.stdout.readline), 30.0)
    assert line.strip() == "ready"
    return proc


def reap(proc: subprocess.Popen[str]) -> None:
    proc.kill()
    proc.wait()
    assert proc.stdout is not None
    proc.stdout.close()


async def until(predicate: object, timeout: float) -> None:
    assert callable(predicate)
    async with asyncio.timeout(timeout):
        while not predicate():
            await asyncio.sleep(0.01)


# The heartbeat path is the hung robot's test; this one gives the token path (two censuses
# after the deletion, bus.detector.CENSUSES_TO_CONFIRM: 110-170 ms here) all the time it
# needs under load, with no heartbeat timeout to race it.
@pytest.mark.parametrize("watch_timeout", [5.0])
async def test_sigkill_is_detected_by_token(watcher: tuple[LivelinessService, list[DeathNotice]],
                                            router: str, mission: str) -> None:
    _bus, deaths = watcher
    proc = await start_robot(router, mission, 3)
    try:
        await asyncio.sleep(0.5)  # let heartbeats and the token reach the watcher
        proc.send_signal(signal.SIGKILL)
        killed = time.monotonic()
        await until(lambda: deaths, timeout=4.0)  # under the heartbeat timeout
        latency = time.monotonic() - killed
        assert [(d.robot, d.incarnation, d.reason) for d in deaths] == [(3, 1, "token")]
        print(f"SIGKILL -> death notice in {latency * 1000:.0f} ms")
    finally:
        reap(proc)


async def test_hung_robot_is_declared_dead_and_fenced_when_it_wakes(
        watcher: tuple[LivelinessService, list[DeathNotice]], router: str, mission: str) -> None:
    service, deaths = watcher
    proc = await start_robot(router, mission, 4)
    try:
        await asyncio.sleep(0.5)
        proc.send_signal(signal.SIGSTOP)
        await until(lambda: deaths, timeout=5.0)
        assert [(d.robot, d.reason) for d in deaths] in ([(4, "heartbeat")], [(4, "token")])
        proc.send_signal(signal.SIGCONT)
        assert proc.stdout is not None
        line = await asyncio.wait_for(asyncio.to_thread(proc.stdout.readline), 10.0)
        assert line.strip() == "fenced"
        # The woken robot's stale view did not make it accuse the watcher: it has ended its
        # life, and what it sent before has come through the router.
        assert await asyncio.to_thread(proc.wait, 10.0) == 0
        await through_router(service.bus, router)
        assert not service.fenced.is_set()
        assert len(deaths) == 1 and service.detector.alive() == {}
    finally:
        reap(proc)


async def test_an_early_heartbeat_comes_at_once_and_a_burst_of_asks_makes_one(
        router: str, mission: str) -> None:
    """beat_soon (an ORMSTC agent acknowledging a peer's claim): the next heartbeat is
    published now, not at its period (6 s here), and asks that come together make one
    heartbeat (at most one per period / SOON_FRACTION)."""
    settings = ConnectionSettings(connect=(router,), mission=mission)
    beats: list[int] = []
    async with Bus.connect(settings) as listener, Bus.connect(settings) as bus:
        listener.subscribe(keys.all_heartbeats(mission), Heartbeat,
                           lambda _key, hb: beats.append(hb.seq), BoundedFifo(64))
        await through_router(listener, router)
        service = LivelinessService(bus, robot=2, incarnation=1, heartbeat_period=6.0,
                                    timeout=20.0)
        async with asyncio.TaskGroup() as group:
            task = group.create_task(service.run())
            await until(lambda: beats == [1], timeout=3.0)
            await asyncio.sleep(0.5)  # past the rate's gap (0.3 s) after the first beat
            for _ in range(5):
                service.beat_soon()
            await until(lambda: len(beats) >= 2, timeout=3.0)  # long before the period
            await asyncio.sleep(1.0)
            assert beats == [1, 2]
            # asked again at once: held back to the rate (period / SOON_FRACTION after it)
            published: list[float] = []
            beat = service.heartbeats.beat

            def timed_beat() -> None:
                published.append(time.monotonic())
                beat()

            service.heartbeats.beat = timed_beat  # type: ignore[method-assign]
            for n in (1, 2):
                service.beat_soon()
                await until(lambda: len(published) == n, timeout=3.0)  # noqa: B023
            await until(lambda: len(beats) == 4, timeout=3.0)
            assert published[1] - published[0] >= 6.0 / SOON_FRACTION - 0.01
            task.cancel()


async def test_deletions_of_tokens_the_router_still_holds_are_refuted(
        watcher: tuple[LivelinessService, list[DeathNotice]], router: str, mission: str) -> None:
    """A link that drops and comes back between two looks at it makes Zenoh delete every
    peer's token locally while the router holds them all (a starved agent once declared
    nine live robots dead so). The watcher hears two such deletions, fed as its own link
    would feed them: the census of the router's tokens refutes them, nobody is declared
    dead. A real SIGKILL afterwards is still declared at once, by its token.

    Zenoh 1.10 now and then ends the census's liveliness get before the router's replies are
    in, and a reply arriving after that reaches the watch as a second put of the token
    (2 of 30 runs of this test on a loaded host, 2026-12-06): such a put refutes the
    deletion too, and such a census proves nothing (bus.detector.CENSUSES_TO_CONFIRM)."""
    service, deaths = watcher
    # On a loaded host the watcher's own loop may run half a lease late, and then it rightly
    # doubts every token deletion for a while (the stall rule), and starved robots miss
    # their 0.6 s heartbeat timeout: this test is about the census, so both are long here.
    service.lease = 60.0
    service.detector.timeout = 30.0
    tokens_heard: set[str] = set()
    heard_again: set[str] = set()  # puts after the fed deletions
    fed = False
    on_token = service._on_token

    def recording(key: str, present: bool) -> None:
        if present:
            (heard_again if fed else tokens_heard).add(key)
        on_token(key, present)

    service._on_token = recording  # type: ignore[method-assign]
    # A robot process starved for 0.75 s of its 1 s lease is dropped by the router, and the
    # census then rightly confirms its deletion (the likeliest reading of a CI rehearsal's
    # failure, 2026-12-05, one of the two deletions left unrefuted): the robots keep their
    # sessions and peers for a minute here. A SIGKILL closes the link at once whatever the
    # lease.
    procs = [await start_robot(router, mission, robot, lease_ms=60_000, timeout=30.0)
             for robot in (5, 6)]
    try:
        # Both tokens heard first, and heard again if they come twice (history and live put
        # may both arrive): a put coming after the fed deletion would undo it.
        wanted = {keys.alive(mission, robot, 1) for robot in (5, 6)}
        await until(lambda: wanted <= tokens_heard, timeout=3.0)
        await asyncio.sleep(0.5)
        fed = True
        for robot in (5, 6):
            service._on_token(keys.alive(mission, robot, 1), False)
        await until(lambda: not service.detector.unconfirmed_token_losses(), timeout=5.0)
        refuted = service.refuted_deletions
        assert refuted + len(heard_again) >= 2 and refuted >= 1, (refuted, heard_again)
        await asyncio.sleep(0.5)  # five token graces
        assert deaths == [] and set(service.detector.alive()) == {5, 6}
        procs[0].send_signal(signal.SIGKILL)
        await until(lambda: deaths, timeout=3.0)
        # by its token (confirmed by a census), not by the heartbeat timeout
        assert [(d.robot, d.reason) for d in deaths] == [(5, "token")]
        assert service.refuted_deletions == refuted
    finally:
        for proc in procs:
            reap(proc)
