"""The offline agent computes its first plan off the event loop, as it does a re-plan: a
balanced plan took 3.4 s on a host busy with three chaos trials, the agent's heartbeats
stopped meanwhile, and a peer declared it dead (chaos seed 63, trial 71)."""

from __future__ import annotations

import asyncio
import time
from types import SimpleNamespace
from typing import Any

import pytest

from agent.offline import driver as driver_module
from agent.offline.driver import OfflineAgent
from agent.offline.options import OfflineOptions
from planner.maps import resolve_world
from planner.placement import random_starts

PLAN_S = 1.0
TICK_S = 0.05


class _Planned(Exception):
    """Stands for the rest of the mission: the test stops once the plan is made."""


async def test_the_event_loop_keeps_running_while_the_first_plan_is_computed(
        monkeypatch: pytest.MonkeyPatch) -> None:
    agent = OfflineAgent.__new__(OfflineAgent)  # only _mission's planning step is driven
    agent.roster = {0: (0, 0), 1: (0, 2)}  # a small fleet on a small map: each robot plans
    agent.options = OfflineOptions(world="office")
    agent.config = SimpleNamespace(algo="opt", seed=0)  # type: ignore[assignment]
    agent.grid = resolve_world("office")
    starts = random_starts(agent.grid, 2, 0)

    async def gather() -> list[tuple[int, int]]:
        return list(starts)

    def plan(*args: Any) -> None:
        time.sleep(PLAN_S)  # CPU-bound planning holds the thread it runs on
        raise _Planned

    agent._gather = gather  # type: ignore[method-assign]
    monkeypatch.setattr(driver_module, "fleet_plan", plan)
    ticks = 0

    async def heartbeat() -> None:
        nonlocal ticks
        while True:
            await asyncio.sleep(TICK_S)
            ticks += 1

    async with asyncio.TaskGroup() as group:
        beating = group.create_task(heartbeat())
        with pytest.raises(_Planned):
            await agent._mission()
        beating.cancel()
    # on the loop the plan lets no tick through (0); off it, up to 20 (fewer on a busy host)
    assert ticks >= 3, ticks
