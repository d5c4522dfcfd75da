"""``mstc simhw`` as a real process behind a real router, driven by a test-side Bus client."""

from __future__ import annotations

import asyncio
import select
import subprocess
import sys
import time
from collections.abc import AsyncIterator, Iterator

import pytest
import zenoh
from waiting import through_router, wait_until

from bus import keys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.messages import (
    AdminCommand,
    AdminReply,
    CoverEvent,
    GroundTruthPose,
    HwCommand,
    HwReply,
    WorldState,
    world_free,
    world_visits,
)

pytestmark = pytest.mark.integration

MISSION = "simhwtest"
STARTS = "0,0;2,10;2,20"


def start_simhw(endpoint: str, *extra: str) -> subprocess.Popen[str]:
    command = [sys.executable, "-m", "deploy.cli", "simhw", "--world", "example",
               "--robots", STARTS, "--headings", "E,E,E", "--time-scale", "0",
               "--connect", endpoint, "--mission", MISSION, *extra]
    proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline:
        if select.select([proc.stdout], [], [], 0.1)[0]:
            line = proc.stdout.readline()
            if line.startswith("simhw ready"):
                return proc
            if not line:
                break
    proc.kill()
    _, err = proc.communicate()
    raise RuntimeError(f"simhw did not start: {err}")


@pytest.fixture
def simhw(router: str) -> Iterator[subprocess.Popen[str]]:
    """A fresh world per test: the tests move, fail and freeze robots."""
    proc = start_simhw(router)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        proc.communicate()


@pytest.fixture
async def bus(router: str, simhw: subprocess.Popen[str]) -> AsyncIterator[Bus]:
    async with Bus.connect(ConnectionSettings(connect=(router,), mission=MISSION)) as b:
        await answered(b)
        yield b


async def answered(bus: Bus, limit: float = 20.0) -> None:
    """Return once simhw answers a query through the router. "simhw ready" says its
    queryables are declared, not that the router routes to them yet; a first query on a
    busy host came back empty once (CI, test_bad_admin_requests_are_refused)."""
    async with asyncio.timeout(limit):
        while not await bus.query(keys.world(MISSION), None, WorldState, timeout=1.0):
            await asyncio.sleep(0.1)


async def hw(bus: Bus, robot: int, action: str, cmd_id: int = 1,
             sensors: tuple[str, ...] = ()) -> HwReply:
    got = await bus.query(keys.hw_cmd(MISSION, robot), HwCommand(
        cmd_id=cmd_id, robot=robot, incarnation=0, action=action,  # type: ignore[arg-type]
        sensors=sensors), HwReply, timeout=5.0)  # type: ignore[arg-type]
    assert len(got) == 1, got
    return got[0].msg


async def admin(bus: Bus, action: str, robot: int | None = None) -> AdminReply:
    got = await bus.query(keys.hw_admin(MISSION), AdminCommand(
        action=action, robot=robot), AdminReply, timeout=5.0)  # type: ignore[arg-type]
    assert len(got) == 1, got
    return got[0].msg


async def world(bus: Bus) -> WorldState:
    got = await bus.query(keys.world(MISSION), None, WorldState, timeout=5.0)
    assert len(got) == 1
    return got[0].msg


async def test_world_state_matches_the_start(bus: Bus) -> None:
    state = await world(bus)
    starts = [tuple(map(int, s.split(","))) for s in STARTS.split(";")]
    assert [r.pose[:2] for r in state.robots] == starts
    visits = world_visits(state)
    free = world_free(state)
    assert all(visits[s] >= 1 for s in starts) and not (visits[~free] > 0).any()


async def test_motion_replies_and_ground_truth(bus: Bus, router: str) -> None:
    covers = bus.subscribe(keys.all_sim_covers(MISSION), CoverEvent)
    poses = bus.subscribe(keys.all_sim_poses(MISSION), GroundTruthPose)
    await through_router(bus, router)  # the subscriptions reach the router
    before = await hw(bus, 0, "pose")
    r, c, heading = before.pose
    reply = await hw(bus, 0, "forward", cmd_id=42)
    assert reply.cmd_id == 42 and reply.status == "ok"
    assert reply.pose == (r, c + 1, heading) and reply.sim_time > before.sim_time
    cover = await asyncio.wait_for(covers.recv(), 5.0)
    assert cover.msg.robot == 0 and cover.msg.cell == (r, c + 1)
    pose = await asyncio.wait_for(poses.recv(), 5.0)
    assert pose.msg.pose == reply.pose
    turned = await hw(bus, 0, "turn_left")
    assert turned.pose == (r, c + 1, (heading - 1) % 4)
    sensed = await hw(bus, 0, "sense", sensors=("front", "left", "right"))
    # Facing north from row 0: the map edge is the adjacent sub-cell.
    assert sensed.status == "ok" and sensed.sonar["front"] == 1
    bumped = await hw(bus, 0, "forward")
    assert bumped.status == "bumped" and bumped.bumper and bumped.pose == turned.pose
    assert (await world(bus)).robots[0].pose == turned.pose


def _refused(data: dict[str, int | float | str]) -> int:
    return sum(int(v) for k, v in data.items()
               if k.startswith("drops.hw/cmd") or k == "count.rejected")


async def test_garbage_on_the_command_key_is_answered_and_counted(bus: Bus) -> None:
    before = _refused((await admin(bus, "status")).data)
    garbage = (b"", b"\x00\xff junk", b"\x81\xa5_kind\xa6hw_cmd")
    for payload in garbage:
        replies = await asyncio.to_thread(_raw_get, bus, keys.hw_cmd(MISSION, 0), payload)
        assert len(replies) == 1, "the server must answer garbage"
        # The bridge refuses what does not decode as a command before simhw sees it.
        assert replies[0].ok is None and replies[0].err is not None
        assert replies[0].err.payload.to_bytes() == b"malformed request"
    assert (await hw(bus, 1, "pose")).status == "ok"  # still serving
    after = _refused((await admin(bus, "status")).data)
    assert after - before == len(garbage)


def _raw_get(bus: Bus, key: str, payload: bytes) -> list[zenoh.Reply]:
    return [r for r in bus.session.get(key, payload=payload, timeout=5.0)]


async def test_failed_body_replies_failed(bus: Bus) -> None:
    assert (await admin(bus, "fail", 1)).ok
    assert (await hw(bus, 1, "forward")).status == "failed"
    state = await world(bus)
    assert state.robots[1].failed and not state.robots[1].alive


async def test_frozen_body_replies_after_unfreeze(bus: Bus) -> None:
    assert (await admin(bus, "freeze", 2)).ok
    before = (await admin(bus, "status")).data.get("count.commands", 0)
    held = asyncio.create_task(hw(bus, 2, "forward"))

    async def command_arrived() -> bool:
        return (await admin(bus, "status")).data.get("count.commands", 0) != before

    # simhw has the command and holds it: no reply, the body has not moved.
    await wait_until(command_arrived, 5.0, "simhw to receive the forward command")
    assert (await world(bus)).robots[2].pose[:2] == (2, 20)
    assert not held.done()
    assert (await admin(bus, "unfreeze", 2)).ok
    reply = await asyncio.wait_for(held, 5.0)
    assert reply.status == "ok" and reply.pose[:2] == (2, 21)


async def test_bad_admin_requests_are_refused(bus: Bus) -> None:
    assert not (await admin(bus, "fail", 99)).ok
    assert not (await admin(bus, "freeze")).ok


def test_sigterm_exits_cleanly(router: str) -> None:
    proc = start_simhw(router)
    proc.terminate()
    assert proc.wait(10) == 0
    proc.communicate()


async def test_admin_shutdown_exits_cleanly(router: str) -> None:
    proc = start_simhw(router, "--mission", "simhwshut")
    settings = ConnectionSettings(connect=(router,), mission="simhwshut")
    async with Bus.connect(settings) as b:
        got = await b.query(keys.hw_admin("simhwshut"), AdminCommand(action="shutdown"),
                            AdminReply, timeout=5.0)
    assert got and got[0].msg.ok
    assert await asyncio.to_thread(proc.wait, 10) == 0
    proc.communicate()
