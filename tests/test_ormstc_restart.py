"""An ORMSTC fleet survives a router restart mid-mission (docs/ormstc.md, "Router restarts").

A router of its own on a free port, ``mstc simhw --time-scale 0`` and four ORMSTC agents, as in
tests/test_ormstc_fleet.py. Once robot 0 has moved a little the router is stopped for 1.5 s
and started again on the same port: every agent must ride out the outage (its hardware
commands are re-asked, not failed), restate what its peers may have lost, and end with exit
0, with every reachable sub-cell covered (simhw's ground truth, asked after the restart: the
test's own subscriptions missed the outage too).
"""

from __future__ import annotations

import asyncio
import subprocess
from pathlib import Path

import pytest
from fleet_helpers import write_room
from test_ormstc_fleet import ROOM, STARTS, check_complete, load_room, make_fleet, world_state

from bus import keys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.messages import GroundTruthPose
from bus.router import start_router_process, stop_process

OUTAGE_S = 1.5
MOVES_BEFORE = 12  # robot 0's pose updates before the router goes away


@pytest.mark.integration
@pytest.mark.slow
async def test_a_router_restart_mid_mission_does_not_lose_the_ormstc_mission(
        tmp_path: Path, free_port: int) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port}"
    room = write_room(tmp_path, ROOM)
    router = start_router_process(endpoint)
    try:
        async with Bus.connect(ConnectionSettings(connect=(endpoint,),
                                                  mission="ormstcrestart")) as bus:
            fleet = await make_fleet(bus, endpoint, room)
            moved = asyncio.Event()
            poses = 0

            def on_pose(_key: str, _msg: GroundTruthPose) -> None:
                nonlocal poses
                poses += 1
                if poses >= MOVES_BEFORE:
                    moved.set()

            bus.subscribe(keys.sim_pose(bus.mission, 0), GroundTruthPose, on_pose)
            await asyncio.sleep(0.2)
            try:
                fleet.start()
                async with asyncio.timeout(60):
                    await moved.wait()
                stop_process(router)
                await asyncio.sleep(OUTAGE_S)
                router = start_router_process(endpoint)
                codes = [await fleet.wait_exit(r) for r in range(len(STARTS))]
                assert codes == [0] * len(STARTS), [fleet.stderr(r) for r in fleet.agents]
                outputs = [_stdout(fleet.agents[r]) for r in range(len(STARTS))]
                assert any("restated" in out for out in outputs), outputs
                state = await world_state(bus)
                check_complete(state, load_room(room), STARTS, dead=set())
            finally:
                fleet.stop_all()
    finally:
        stop_process(router)


def _stdout(proc: subprocess.Popen[str]) -> str:
    return proc.stdout.read() if proc.stdout is not None and proc.poll() is not None else ""
