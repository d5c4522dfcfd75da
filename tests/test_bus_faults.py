"""Seeded message faults (bus.faults): the spec, the decisions, and a real bridge under them."""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import AsyncIterator

import pytest

from bus import keys
from bus.bridge import BoundedFifo, Bus, LatestWins
from bus.config import ConnectionSettings
from bus.faults import FaultSpecError, MessageFaults, parse_spec
from bus.messages import Progress, RobotEvent

_missions = itertools.count()


def test_a_spec_reads_back_and_rejects_mistakes_in_one_line() -> None:
    spec = parse_spec("seed=7;progress.drop=0.1;*.dup=0.05;ormstc.delay=0.3;window=0.1")
    assert spec.seed == 7 and spec.window == 0.1
    progress = spec.rates("progress")
    assert progress is not None and progress.drop == 0.1
    assert spec.rates("status") == spec.rules["*"]
    # a family's rule covers its kinds (keys.kind_of says "ormstc/claim"), unless they have
    # their own
    assert spec.rates("ormstc/claim") == spec.rules["ormstc"]
    own = parse_spec("ormstc.drop=0.3;ormstc/claim.drop=0.5")
    claim, tree = own.rates("ormstc/claim"), own.rates("ormstc/tree")
    assert claim is not None and claim.drop == 0.5
    assert tree is not None and tree.drop == 0.3
    assert own.rates("hb") is None
    assert parse_spec(spec.text()) == spec
    for bad in ("progress.drop", "progress.melt=0.1", "progress.drop=2", "x=y"):
        with pytest.raises(FaultSpecError):
            parse_spec(bad)


def test_the_same_seed_makes_the_same_decisions() -> None:
    spec = parse_spec("seed=3;*.drop=0.3;*.dup=0.2;*.delay=0.1;*.reorder=0.2")
    first, second = MessageFaults(spec), MessageFaults(spec)
    a = [first.outgoing("progress") for _ in range(200)]
    assert a == [second.outgoing("progress") for _ in range(200)]
    assert any(c == [] for c in a) and any(len(c) == 2 for c in a)
    assert MessageFaults(parse_spec("seed=4;*.drop=0.3")).outgoing("x") is not None


@pytest.fixture
async def pair(router: str) -> AsyncIterator[tuple[Bus, Bus]]:
    mission = f"faults{next(_missions)}"
    settings = ConnectionSettings(connect=(router,), mission=mission)
    async with Bus.connect(settings) as sub, Bus.connect(settings) as pub:
        yield pub, sub


async def _matched(pub: Bus, sub: Bus) -> None:
    key = keys.events(pub.mission, 0)
    seen = sub.subscribe(key, RobotEvent, policy=LatestWins())
    async with asyncio.timeout(5.0):
        while seen.try_recv() is None:
            pub.publish(key, RobotEvent(0, 0, "started"))
            await asyncio.sleep(0.05)
    seen.close()


@pytest.mark.integration
async def test_a_faulty_publisher_drops_duplicates_and_delays_on_a_real_router(
        pair: tuple[Bus, Bus]) -> None:
    pub, sub = pair
    await _matched(pub, sub)
    got: list[int] = []
    sub.subscribe(keys.all_progress(sub.mission), Progress, lambda _k, m: got.append(m.seq),
                  BoundedFifo(1000))
    key = keys.progress(pub.mission, 1)
    pub.faults = MessageFaults(parse_spec("seed=1;progress.drop=1"))
    for seq in range(20):
        pub.publish(key, Progress(1, 1, seq, (0, 0), 0.0))
    pub.faults = MessageFaults(parse_spec("seed=1;progress.dup=1;progress.delay=0.3"))
    loop = asyncio.get_running_loop()
    sent_at = loop.time()
    pub.publish(key, Progress(1, 1, 100, (0, 0), 0.0))
    async with asyncio.timeout(5.0):
        while len(got) < 2:
            await asyncio.sleep(0.01)
    await asyncio.sleep(0.3)
    assert got == [100, 100], "every dropped message lost, the duplicate delivered twice"
    assert loop.time() - sent_at >= 0.0
    # a receiver-side loss: this subscriber misses what the publisher sent
    sub.faults = MessageFaults(parse_spec("seed=1;progress.lose=1"))
    pub.faults = None
    pub.publish(key, Progress(1, 1, 200, (0, 0), 0.0))
    await asyncio.sleep(0.3)
    assert 200 not in got
