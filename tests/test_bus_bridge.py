"""The asyncio bridge against a real ``mstc router`` subprocess on loopback."""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import signal
import subprocess
import sys
import threading
from collections.abc import AsyncIterator, Callable, Iterator
from typing import Any

import pytest

from bus import keys
from bus.bridge import BoundedFifo, Bus, LatestWins, Received, Subscription
from bus.config import ConnectionSettings
from bus.inbox import Inbox
from bus.messages import AdminCommand, AdminReply, Heartbeat, Progress, RobotEvent, RobotStatus

pytestmark = pytest.mark.integration
_missions = itertools.count()


@pytest.fixture
async def bus(router: str) -> AsyncIterator[Bus]:
    settings = ConnectionSettings(connect=(router,), mission=f"t{next(_missions)}")
    async with Bus.connect(settings) as opened:
        yield opened


@pytest.fixture
async def other(router: str, bus: Bus) -> AsyncIterator[Bus]:
    """A second session on the same mission (publisher side)."""
    settings = ConnectionSettings(connect=(router,), mission=bus.mission)
    async with Bus.connect(settings) as opened:
        yield opened


def progress(seq: int, robot: int = 1) -> Progress:
    return Progress(robot=robot, incarnation=1, seq=seq, cell=(seq, 0), sim_time=seq * 0.1)


async def until(predicate: object, timeout: float = 5.0) -> None:
    """Wait until ``predicate()`` is true (polling: the wire is asynchronous)."""
    assert callable(predicate)
    async with asyncio.timeout(timeout):
        while not predicate():
            await asyncio.sleep(0.02)


async def wait_matched(pub: Bus, sub: Bus, key: str) -> None:
    """Publish probes until the subscription path is live (declarations propagate async)."""
    seen = sub.subscribe(key, RobotEvent, policy=LatestWins())
    probe = RobotEvent(robot=0, incarnation=0, kind="started")
    async with asyncio.timeout(5.0):
        while seen.try_recv() is None:
            pub.publish(key, probe)
            await asyncio.sleep(0.05)
    seen.close()


async def test_fifo_delivers_in_order(bus: Bus, other: Bus) -> None:
    key = keys.progress(bus.mission, 1)
    sub = bus.subscribe(keys.all_progress(bus.mission), Progress, policy=BoundedFifo(1000))
    await wait_matched(other, bus, keys.events(bus.mission, 0))
    for seq in range(200):
        other.publish(key, progress(seq))
    got = [(await sub.recv()).msg.seq for _ in range(200)]
    assert got == list(range(200))
    assert bus.drops.total() == 0


async def test_latest_wins_keeps_only_newest_per_key(bus: Bus, other: Bus) -> None:
    sub = bus.subscribe(keys.all_progress(bus.mission), Progress, policy=LatestWins())
    everything: list[Progress] = []
    bus.subscribe(keys.all_progress(bus.mission), Progress, lambda _k, m: everything.append(m))
    await wait_matched(other, bus, keys.events(bus.mission, 0))
    # Nothing consumes while both robots publish 50 each: only the last of each key stays.
    for seq in range(50):
        for robot in (1, 2):
            other.publish(keys.progress(bus.mission, robot), progress(seq, robot))
    await until(lambda: len(everything) == 100)
    await asyncio.sleep(0.1)  # the other subscription's callback for the last sample
    first, second = sub.try_recv(), sub.try_recv()
    assert first is not None and second is not None
    assert sub.try_recv() is None
    assert {(r.msg.robot, r.msg.seq) for r in (first, second)} == {(1, 49), (2, 49)}
    assert {r.key for r in (first, second)} == {keys.progress(bus.mission, 1),
                                                  keys.progress(bus.mission, 2)}


async def test_slow_consumer_does_not_block_and_drops_are_counted(bus: Bus, other: Bus) -> None:
    sub = bus.subscribe(keys.all_progress(bus.mission), Progress, policy=BoundedFifo(10))
    fast = bus.subscribe(keys.all_progress(bus.mission), Progress, policy=BoundedFifo(1000))
    await wait_matched(other, bus, keys.events(bus.mission, 0))
    for seq in range(300):
        other.publish(keys.progress(bus.mission, 1), progress(seq))
    # The other subscription on the same session keeps receiving everything meanwhile.
    got = [(await fast.recv()).msg.seq for _ in range(300)]
    assert got == list(range(300))
    # Zenoh calls the two subscriptions' callbacks one after the other: let the last land.
    await until(lambda: bus.drops.total("progress", "overflow") == 290)
    kept = [r.msg.seq for r in iter(sub.try_recv, None)]
    assert kept == list(range(290, 300))
    assert bus.drops.total("progress", "overflow") == 290


@contextlib.contextmanager
def held(inbox: Inbox[Any]) -> Iterator[threading.Event]:
    """Hold every hand-over into ``inbox`` (on its declaration's thread) until the block
    ends; yields the event set once one is held."""
    entered, release = threading.Event(), threading.Event()

    def hold(key: str, item: object) -> None:
        entered.set()
        release.wait(20.0)

    inbox.push = hold  # type: ignore[method-assign]
    try:
        yield entered
    finally:
        release.set()


async def hears_every_one(other: Bus, fast: Subscription[Progress], entered: threading.Event,
                          publish_held: Callable[[], None]) -> None:
    """``fast`` hears, then a hand-over is held (``publish_held`` brings one on), then
    ``fast`` hears 50 more all the same."""
    mission = other.mission
    async with asyncio.timeout(5.0):
        while fast.try_recv() is None:  # both declarations have reached the router
            other.publish(keys.progress(mission, 2), progress(0, robot=2))
            await asyncio.sleep(0.05)
        while not entered.is_set():
            publish_held()
            await asyncio.sleep(0.05)
    for seq in range(1, 51):
        other.publish(keys.progress(mission, 2), progress(seq, robot=2))
    async with asyncio.timeout(5.0):
        while (await fast.recv()).msg.seq < 50:
            pass


async def test_a_stalled_subscription_holds_back_no_other_on_the_link(
        bus: Bus, other: Bus) -> None:
    # bus.handoff: Zenoh's receive thread hands samples over and reads on. Had it run the
    # stuck hand-over itself, nothing more would be read from the link: the second
    # subscription would hear nothing, and the link would expire after its lease.
    stuck = bus.subscribe(keys.progress(bus.mission, 1), Progress)
    fast = bus.subscribe(keys.progress(bus.mission, 2), Progress)
    with held(stuck._inbox) as entered:
        await hears_every_one(other, fast, entered, lambda: other.publish(
            keys.progress(bus.mission, 1), progress(0)))


async def test_a_stalled_queryable_holds_back_no_subscription_on_the_link(
        bus: Bus, other: Bus) -> None:
    # simhw's command queryables: a query waiting to be handed over must not stop the link
    key = keys.hw_cmd(bus.mission, 0)
    handle = bus.declare_queryable(key, lambda _request: None)
    fast = bus.subscribe(keys.progress(bus.mission, 2), Progress)
    asked: list[asyncio.Future[list[Received[AdminReply]]]] = []
    with held(handle._inbox) as entered:
        await hears_every_one(other, fast, entered, lambda: asked.append(asyncio.ensure_future(
            other.query(key, None, AdminReply, timeout=3.0))))
    assert [await answer for answer in asked] == [[]] * len(asked)  # held: never answered


def test_a_process_that_closes_its_bus_exits_cleanly(router: str) -> None:
    script = ("import asyncio, sys\n"
              "from bus import keys\n"
              "from bus.bridge import Bus\n"
              "from bus.config import ConnectionSettings\n"
              "from bus.messages import Progress\n"
              "async def main() -> None:\n"
              "    settings = ConnectionSettings(connect=(sys.argv[1],), mission='exit')\n"
              "    async with Bus.connect(settings) as bus:\n"
              "        bus.subscribe(keys.all_progress('exit'), Progress)\n"
              "        bus.watch_liveliness(keys.all_alive('exit'), print, print)\n"
              "        bus.declare_queryable(keys.hw_cmd('exit', 0), lambda _request: None)\n"
              "asyncio.run(main())\n"
              "print('closed', flush=True)\n")
    done = subprocess.run([sys.executable, "-c", script, router], capture_output=True,
                          text=True, timeout=30)
    assert done.returncode == 0 and "closed" in done.stdout, done.stderr


async def test_garbage_is_counted_not_raised(bus: Bus, other: Bus) -> None:
    handled: list[Heartbeat] = []
    bus.subscribe(keys.all_heartbeats(bus.mission), Heartbeat,
                  lambda _key, hb: handled.append(hb))
    await wait_matched(other, bus, keys.events(bus.mission, 0))
    key = keys.heartbeat(bus.mission, 3)
    other.session.put(key, b"\xc1 not msgpack")
    other.session.put(key, b"\x93\x01\x02\x03")  # msgpack, but an array
    other.publish(key, progress(1))  # valid message of the wrong kind
    good = Heartbeat(robot=3, incarnation=1, seq=1, pose=(0, 0, 1), state="ok", sim_time=0.0)
    other.publish(key, good)
    await until(lambda: handled)
    assert handled == [good]
    assert bus.drops.total("hb", "decode") == 3


async def test_handler_exception_is_logged_and_delivery_continues(
        bus: Bus, other: Bus, caplog: pytest.LogCaptureFixture) -> None:
    seen: list[int] = []

    def handler(_key: str, msg: Progress) -> None:
        seen.append(msg.seq)
        if msg.seq == 0:
            raise RuntimeError("boom")

    bus.subscribe(keys.all_progress(bus.mission), Progress, handler)
    await wait_matched(other, bus, keys.events(bus.mission, 0))
    for seq in range(3):
        other.publish(keys.progress(bus.mission, 1), progress(seq))
    await until(lambda: len(seen) == 3)
    assert seen == [0, 1, 2]
    assert "boom" in caplog.text
    assert bus.drops.total("progress", "handler_error") == 1


async def test_query_sync_and_async_responders(bus: Bus, other: Bus) -> None:
    mission = bus.mission

    def status(_request: None) -> RobotStatus:
        return RobotStatus(robot=4, incarnation=2, start=(1, 1), algo="mstc",
                           plan_digest="d", state="covering")

    async def admin(request: AdminCommand) -> AdminReply:
        await asyncio.sleep(0.01)
        return AdminReply(ok=True, message=f"{request.action} {request.robot}")

    other.declare_queryable(keys.state(mission, 4), status)
    other.declare_queryable(keys.hw_admin(mission), admin, AdminCommand)
    await asyncio.sleep(0.2)
    states = await bus.query(keys.all_states(mission), None, RobotStatus, timeout=2.0)
    assert [(r.key, r.msg.robot) for r in states] == [(keys.state(mission, 4), 4)]
    replies = await bus.query(keys.hw_admin(mission), AdminCommand("freeze", 3),
                              AdminReply, timeout=2.0)
    assert [r.msg for r in replies] == [AdminReply(ok=True, message="freeze 3")]


async def test_query_errors_are_counted(bus: Bus, other: Bus,
                                        caplog: pytest.LogCaptureFixture) -> None:
    def broken(_request: AdminCommand) -> AdminReply:
        raise ValueError("cannot")

    other.declare_queryable(keys.hw_admin(bus.mission), broken, AdminCommand)
    await asyncio.sleep(0.2)
    with caplog.at_level(logging.WARNING, logger="mstc.bus.drops"):
        replies = await bus.query(keys.hw_admin(bus.mission), AdminCommand("status"),
                                  AdminReply, timeout=2.0)
    assert replies == []
    assert bus.drops.total("hw/admin", "reply_error") == 1
    # the warning says what the other side answered, not only that it was an error
    assert "responder failed: cannot" in caplog.text
    # A malformed request is answered with an error too, not a crash of the server.
    bad = await bus.query(keys.hw_admin(bus.mission), progress(1), AdminReply, timeout=2.0)
    assert bad == []
    assert other.drops.total("hw/admin", "decode") == 1


async def test_query_with_no_queryable_returns_empty(bus: Bus) -> None:
    assert await bus.query(keys.world(bus.mission), None, RobotStatus, timeout=0.5) == []


TOKEN_HOLDER = """
import asyncio, sys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus import keys

async def main():
    settings = ConnectionSettings(connect=(sys.argv[1],), mission=sys.argv[2])
    async with Bus.connect(settings) as bus:
        bus.declare_token(keys.alive(bus.mission, 5, 9))
        print("ready", flush=True)
        await asyncio.sleep(60)

asyncio.run(main())
"""


async def test_liveliness_delete_after_sigkill(bus: Bus, router: str) -> None:
    events: list[tuple[str, str]] = []
    bus.watch_liveliness(keys.all_alive(bus.mission), lambda k: events.append(("put", k)),
                         lambda k: events.append(("delete", k)))
    proc = subprocess.Popen([sys.executable, "-c", TOKEN_HOLDER, router, bus.mission],
                            stdout=subprocess.PIPE, text=True)
    try:
        token = keys.alive(bus.mission, 5, 9)
        await until(lambda: ("put", token) in events, timeout=10.0)
        assert events == [("put", token)]
        proc.send_signal(signal.SIGKILL)
        await until(lambda: ("delete", token) in events, timeout=3.0)
        assert events == [("put", token), ("delete", token)]
    finally:
        proc.kill()
        proc.wait()
        assert proc.stdout is not None
        proc.stdout.close()


async def test_late_watcher_sees_existing_tokens(bus: Bus, other: Bus) -> None:
    other.declare_token(keys.alive(bus.mission, 2, 1))
    await asyncio.sleep(0.2)
    puts: list[str] = []
    bus.watch_liveliness(keys.all_alive(bus.mission), puts.append, lambda _k: None)
    await until(lambda: puts)
    assert puts == [keys.alive(bus.mission, 2, 1)]


async def ask(bus: Bus, key: str) -> frozenset[str] | None:
    answered: asyncio.Future[frozenset[str] | None] = bus.loop.create_future()
    bus.ask_tokens(key, 1.0, answered.set_result)
    return await asyncio.wait_for(answered, 3.0)


async def test_ask_tokens_answers_through_a_router(bus: Bus, other: Bus) -> None:
    """What the liveness census asks (bus.liveness): the tokens that exist now, the
    session's own and its peers', through the router."""
    mine, theirs = keys.alive(bus.mission, 0, 1), keys.alive(bus.mission, 1, 1)
    bus.declare_token(mine)
    other.declare_token(theirs)
    async with asyncio.timeout(3.0):
        while (answer := await ask(bus, keys.all_alive(bus.mission))) is None \
                or theirs not in answer:
            await asyncio.sleep(0.05)
    assert answer == {mine, theirs}


async def test_ask_tokens_answers_in_peer_mode_and_not_when_alone(free_port: int) -> None:
    """Peers with no router answer too (a census that asked only routers would never
    confirm a death in a peer-mode fleet); a session that reaches no one gets None, not
    its own token alone (which would read as every peer gone)."""
    mission = f"t{next(_missions)}"
    endpoint = f"tcp/127.0.0.1:{free_port}"
    first = ConnectionSettings(mode="peer", listen=(endpoint,), mission=mission)
    async with Bus.connect(first) as alone:
        alone.declare_token(keys.alive(mission, 0, 1))
        assert await ask(alone, keys.all_alive(mission)) is None
        second = ConnectionSettings(mode="peer", connect=(endpoint,),
                                    listen=("tcp/127.0.0.1:0",), mission=mission)
        async with Bus.connect(second) as peer:
            peer.declare_token(keys.alive(mission, 1, 1))
            wanted = {keys.alive(mission, 0, 1), keys.alive(mission, 1, 1)}
            async with asyncio.timeout(5.0):
                while await ask(alone, keys.all_alive(mission)) != wanted:
                    await asyncio.sleep(0.05)
