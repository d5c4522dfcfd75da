"""The hardware service without Zenoh: command semantics, sim time, failures, ground truth."""

from __future__ import annotations

import asyncio

import msgpack
import numpy as np
import pytest

from bus import keys
from bus.codec import decode, encode
from bus.messages import (
    NO_ROBOT,
    AdminCommand,
    BumpEvent,
    CoverEvent,
    GroundTruthPose,
    HwCommand,
    HwReply,
    WorldState,
    world_crossed,
    world_first,
    world_free,
    world_visits,
)
from planner.types import OccupancyGrid
from simhw.clock import FastClock
from simhw.kinematics import Kinematics
from simhw.service import HwService
from simhw.types import Heading, Pose, SonarMode, WorldConfig
from simhw.world import World

KIN = Kinematics()


def make(rows: list[str], poses: list[Pose], **config: object) -> tuple[HwService, list]:
    free = np.array([[ch != "#" for ch in row] for row in rows], dtype=bool)
    world = World(OccupancyGrid(free, name="t"), poses, WorldConfig(**config))  # type: ignore[arg-type]
    sent: list[tuple[str, object]] = []
    svc = HwService(world, FastClock(), KIN, "m", lambda k, m: sent.append((k, m)),
                    frozen_hold_s=5.0)
    return svc, sent


def cmd(robot: int, action: str, cmd_id: int = 1, inc: int = 0,
        sensors: tuple[str, ...] = ()) -> bytes:
    return encode(HwCommand(cmd_id=cmd_id, robot=robot, incarnation=inc,
                            action=action, sensors=sensors))  # type: ignore[arg-type]


async def test_forward_reply_pose_odometry_and_sim_time() -> None:
    svc, sent = make(["....", "...."], [Pose(0, 0, Heading.E)])
    reply = await svc.command(0, cmd(0, "forward", cmd_id=7))
    assert (reply.status, reply.cmd_id, reply.pose) == ("ok", 7, (0, 1, 1))
    assert reply.odometry == (WorldConfig().sub_cell_m, 0.0)
    assert reply.sim_time == pytest.approx(KIN.forward_s())
    reply = await svc.command(0, cmd(0, "turn_right"))
    assert reply.pose == (0, 1, 2)
    assert reply.sim_time == pytest.approx(KIN.forward_s() + KIN.turn_s())
    covers = [m for k, m in sent if isinstance(m, CoverEvent)]
    assert [c.cell for c in covers] == [(0, 0), (0, 1)]
    assert all(k == keys.sim_cover("m", 0) for k, m in sent if isinstance(m, CoverEvent))
    assert [m.pose for _, m in sent if isinstance(m, GroundTruthPose)] == [(0, 1, 1), (0, 1, 2)]


async def test_bump_reply_and_event() -> None:
    svc, sent = make(["#..."], [Pose(0, 1, Heading.W)])
    reply = await svc.command(0, cmd(0, "forward"))
    assert reply.status == "bumped" and reply.bumper and reply.pose == (0, 1, 3)
    assert reply.odometry[0] == 0.0
    bumps = [m for _, m in sent if isinstance(m, BumpEvent)]
    assert len(bumps) == 1 and (bumps[0].at, bumps[0].into) == ((0, 1), (0, 0))


async def test_sense_and_one_at_a_time_rejection() -> None:
    svc, _ = make(["....", "....", "...."], [Pose(1, 1, Heading.N)],
                  sonar_mode=SonarMode.ONE_AT_A_TIME)
    ok = await svc.command(0, cmd(0, "sense", sensors=("left",)))
    assert ok.status == "ok" and ok.sonar == {"left": 2}
    bad = await svc.command(0, cmd(0, "sense", sensors=("left", "front")))
    assert bad.status == "rejected" and "one-at-a-time" in bad.message


@pytest.mark.parametrize("payload", [
    b"", b"\xff\x00garbage", msgpack.packb({"_kind": "hw_cmd"}),
    encode(AdminCommand(action="status")),
])
async def test_garbage_is_rejected_and_counted(payload: bytes) -> None:
    svc, _ = make(["..."], [Pose(0, 0)])
    reply = await svc.command(0, payload)
    assert isinstance(reply, HwReply) and reply.status == "rejected"
    assert svc.counts["rejected"] == 1
    assert (await svc.command(0, cmd(0, "pose"))).status == "ok"


async def test_wrong_robot_and_stale_incarnation_are_rejected() -> None:
    svc, _ = make(["...."], [Pose(0, 0), Pose(0, 3)])
    assert (await svc.command(1, cmd(0, "pose"))).status == "rejected"
    assert (await svc.command(5, cmd(5, "pose"))).status == "rejected"
    assert (await svc.command(0, cmd(0, "pose", inc=3))).status == "ok"
    assert (await svc.command(0, cmd(0, "pose", inc=2))).status == "rejected"


async def test_failed_body_replies_failed() -> None:
    svc, _ = make(["...."], [Pose(0, 0, Heading.E)])
    admin = svc.admin(encode(AdminCommand(action="fail", robot=0)))
    assert admin.ok
    for action in ("forward", "turn_left", "sense"):
        reply = await svc.command(0, cmd(0, action, sensors=("front",)))
        assert reply.status == "failed"
    assert svc.world_state().robots[0].failed


async def test_frozen_body_holds_the_reply_until_unfrozen() -> None:
    svc, _ = make(["...."], [Pose(0, 0, Heading.E), Pose(0, 3, Heading.W)])
    svc.admin(encode(AdminCommand(action="freeze", robot=0)))
    held = asyncio.create_task(svc.command(0, cmd(0, "forward")))
    other = await svc.command(1, cmd(1, "forward"))  # other bodies are not held up
    assert other.status == "ok"
    for _ in range(20):
        await asyncio.sleep(0)
    assert not held.done()
    svc.admin(encode(AdminCommand(action="unfreeze", robot=0)))
    reply = await asyncio.wait_for(held, 2.0)
    assert reply.status == "ok" and reply.pose == (0, 1, 1)


async def test_a_body_failed_while_frozen_replies_failed() -> None:
    svc, _ = make(["...."], [Pose(0, 0, Heading.E)])
    svc.admin(encode(AdminCommand(action="freeze", robot=0)))
    held = asyncio.create_task(svc.command(0, cmd(0, "forward")))
    await asyncio.sleep(0)
    svc.admin(encode(AdminCommand(action="fail", robot=0)))
    assert (await asyncio.wait_for(held, 2.0)).status == "failed"


async def test_frozen_too_long_replies_frozen() -> None:
    svc, _ = make(["...."], [Pose(0, 0, Heading.E)])
    svc.frozen_hold_s = 0.05
    svc.admin(encode(AdminCommand(action="freeze", robot=0)))
    assert (await svc.command(0, cmd(0, "forward"))).status == "frozen"


async def test_two_bodies_racing_for_one_sub_cell() -> None:
    svc, _ = make(["..."], [Pose(0, 0, Heading.E), Pose(0, 2, Heading.W)])
    a, b = await asyncio.gather(svc.command(0, cmd(0, "forward")),
                                svc.command(1, cmd(1, "forward")))
    assert sorted([a.status, b.status]) == ["bumped", "ok"]
    winner, loser = (a, b) if a.status == "ok" else (b, a)
    assert winner.pose[:2] == (0, 1)
    assert loser.pose[:2] == ((0, 0) if loser.robot == 0 else (0, 2))


async def test_commands_of_one_robot_run_one_at_a_time() -> None:
    svc, _ = make(["......"], [Pose(0, 0, Heading.E)])
    replies = await asyncio.gather(*(svc.command(0, cmd(0, "forward", cmd_id=i))
                                     for i in range(4)))
    assert all(r.status == "ok" for r in replies)
    assert sorted(r.pose[1] for r in replies) == [1, 2, 3, 4]
    assert sorted(r.sim_time for r in replies) == pytest.approx(
        [KIN.forward_s() * i for i in (1, 2, 3, 4)])


async def test_admin_errors_and_status() -> None:
    svc, _ = make(["..."], [Pose(0, 0)])
    assert not (svc.admin(b"junk")).ok
    assert not (svc.admin(encode(AdminCommand(action="fail", robot=9)))).ok
    assert not (svc.admin(encode(AdminCommand(action="fail")))).ok
    status = svc.admin(encode(AdminCommand(action="status")))
    assert status.ok and status.data["robot.0"] == "alive" and status.data["robots"] == 1
    shut = svc.admin(encode(AdminCommand(action="shutdown")))
    assert shut.ok and svc.shutdown.is_set()


async def test_world_state_round_trip() -> None:
    rows = ["..#.", "...."]
    svc, _ = make(rows, [Pose(1, 0, Heading.E)])
    await svc.command(0, cmd(0, "forward"))
    state = svc.world_state()
    assert np.array_equal(world_free(state), [[ch != "#" for ch in r] for r in rows])
    visits = world_visits(state)
    assert visits[1, 0] == 1 and visits[1, 1] == 1 and visits.sum() == 2
    assert state.robots[0].pose == (1, 1, 1) and state.robots[0].covered == 2


class GateClock:
    """A clock whose motions end only when the test opens the gate."""

    def __init__(self) -> None:
        self.gate = asyncio.Event()
        self.started = asyncio.Event()

    def now(self) -> float:
        return 0.0

    def lane_now(self, lane: int) -> float:
        return 0.0

    async def run(self, lane: int, duration: float) -> tuple[float, float]:
        self.started.set()
        await self.gate.wait()
        return 0.0, duration


async def test_freeze_mid_motion_finishes_after_unfreeze_even_past_the_hold() -> None:
    world = World(OccupancyGrid(np.ones((1, 3), dtype=bool)), [Pose(0, 0, Heading.E)])
    clock = GateClock()
    svc = HwService(world, clock, KIN, "m", lambda k, m: None, frozen_hold_s=0.01)
    moving = asyncio.create_task(svc.command(0, cmd(0, "forward")))
    await clock.started.wait()
    assert world.body(0).target == (0, 1)
    svc.admin(encode(AdminCommand(action="freeze", robot=0)))
    clock.gate.set()
    await asyncio.sleep(0.05)  # longer than the hold: a motion under way is not abandoned
    assert not moving.done() and world.body(0).target == (0, 1)
    svc.admin(encode(AdminCommand(action="unfreeze", robot=0)))
    reply = await asyncio.wait_for(moving, 2.0)
    assert reply.status == "ok" and reply.pose == (0, 1, 1) and world.body(0).target is None


async def test_fail_mid_motion_releases_the_target() -> None:
    world = World(OccupancyGrid(np.ones((1, 3), dtype=bool)), [Pose(0, 0, Heading.E)])
    clock = GateClock()
    svc = HwService(world, clock, KIN, "m", lambda k, m: None)
    moving = asyncio.create_task(svc.command(0, cmd(0, "forward")))
    await clock.started.wait()
    svc.admin(encode(AdminCommand(action="fail", robot=0)))
    clock.gate.set()
    reply = await asyncio.wait_for(moving, 2.0)
    assert reply.status == "failed" and reply.pose == (0, 0, 1)
    assert world.held() == {(0, 0): 0}


async def test_world_state_first_visitors_and_crossers_match_the_cover_events() -> None:
    """Oracle: the published CoverEvents, replayed naively in the order they were sent."""
    rows = ["......", "......", "..#...", "......"]
    svc, sent = make(rows, [Pose(0, 0, Heading.E), Pose(3, 5, Heading.W)])
    svc.publish_initial()
    script = {0: ["forward", "forward", "turn_right", "forward", "forward", "forward",
                  "turn_left", "forward"],
              1: ["forward", "forward", "forward", "turn_right", "forward", "forward",
                  "forward", "turn_right", "forward"]}
    for i in range(max(map(len, script.values()))):
        await asyncio.gather(*(svc.command(r, cmd(r, acts[i], cmd_id=i + 1))
                               for r, acts in script.items() if i < len(acts)))
    first: dict[tuple[int, int], int] = {}
    crossed: dict[tuple[tuple[int, int], tuple[int, int]], int] = {}
    last: dict[int, tuple[int, int]] = {}
    for _, ev in sent:
        if not isinstance(ev, CoverEvent):
            continue
        first.setdefault(ev.cell, ev.robot)
        if ev.robot in last:
            a = (last[ev.robot][0] // 2, last[ev.robot][1] // 2)
            b = (ev.cell[0] // 2, ev.cell[1] // 2)
            if a != b:
                crossed.setdefault((min(a, b), max(a, b)), ev.robot)
        last[ev.robot] = ev.cell
    state = decode(encode(svc.world_state()), WorldState)
    got_first = world_first(state)
    assert {(int(r), int(c)): int(got_first[r, c])
            for r, c in np.argwhere(got_first != NO_ROBOT)} == first
    right, down = world_crossed(state)
    got = {((int(r), int(c)), (int(r), int(c) + 1)): int(right[r, c])
           for r, c in np.argwhere(right != NO_ROBOT)}
    got.update({((int(r), int(c)), (int(r) + 1, int(c))): int(down[r, c])
                for r, c in np.argwhere(down != NO_ROBOT)})
    assert got == crossed and set(crossed.values()) == {0, 1}


async def test_a_fenced_robots_verdicts_fence_nobody() -> None:
    """Across a healed partition the far side's death notices about the near side arrive
    after the near side had the far side fenced: simhw refuses them, or nobody could move."""
    from bus.messages import DeathNotice
    from simhw.dead_bodies import on_death

    svc, _ = make(["...."], [Pose(0, 0), Pose(0, 3)])
    assert (await svc.command(0, cmd(0, "pose", inc=1))).status == "ok"
    assert (await svc.command(1, cmd(1, "pose", inc=1))).status == "ok"
    assert on_death(svc, DeathNotice(1, 1, 0, "token", 0.0), "vanish")  # 0 sees 1 die
    assert svc.life_is_fenced(1) and not svc.life_is_fenced(0)
    assert not on_death(svc, DeathNotice(0, 1, 1, "token", 0.0), "vanish")  # 1's, too late
    assert (await svc.command(0, cmd(0, "pose", inc=1))).status == "ok"
    assert (await svc.command(1, cmd(1, "pose", inc=1))).status == "rejected"
    # a new life of robot 1 is a live detector again
    assert (await svc.command(1, cmd(1, "pose", inc=2))).status == "ok"
    assert not svc.life_is_fenced(1)
    assert on_death(svc, DeathNotice(0, 1, 1, "token", 0.0), "vanish")


async def test_admin_fail_after_covered_is_armed_and_fires_on_the_covering_step() -> None:
    svc, _ = make(["....", "...."], [Pose(0, 0, Heading.E), Pose(1, 0, Heading.E)])
    armed = svc.admin(encode(AdminCommand("fail", 1, after_covered=3)))
    assert armed.ok and "armed for 3 covered sub-cells" in armed.message
    assert armed.data["status"] == "alive" and armed.data["covered"] == 2
    assert (await svc.command(0, cmd(0, "forward"))).status == "ok"  # the third sub-cell
    assert svc.status()["robot.1"] == "failed"
    assert (await svc.command(1, cmd(1, "forward"))).status == "failed"
    # already reached: at once; only "fail" can wait, and the count is not negative
    now = svc.admin(encode(AdminCommand("fail", 0, after_covered=1)))
    assert now.ok and now.message == "robot 0: fail done" and now.data["status"] == "failed"
    assert not svc.admin(encode(AdminCommand("freeze", 0, after_covered=5))).ok
    assert not svc.admin(encode(AdminCommand("fail", 0, after_covered=-1))).ok


async def test_an_armed_failure_ends_a_freeze_in_progress() -> None:
    svc, _ = make(["....", "...."], [Pose(0, 0, Heading.E), Pose(1, 0, Heading.E)])
    svc.admin(encode(AdminCommand("fail", 1, after_covered=3)))
    svc.admin(encode(AdminCommand("freeze", 1)))
    frozen = asyncio.ensure_future(svc.command(1, cmd(1, "forward")))
    await asyncio.sleep(0.01)
    assert not frozen.done()
    await svc.command(0, cmd(0, "forward"))  # sets off robot 1's failure
    reply = await asyncio.wait_for(frozen, 1.0)
    assert reply.status == "failed"


async def test_a_pause_holds_every_body_until_resume() -> None:
    svc, _ = make(["....", "...."], [Pose(0, 0, Heading.E), Pose(1, 0, Heading.E)])
    armed = svc.admin(encode(AdminCommand("pause", after_covered=3)))
    assert armed.ok and armed.message == "pause armed for 3 covered sub-cells"
    assert not svc.admin(encode(AdminCommand("pause"))).ok  # needs the count
    assert (await svc.command(0, cmd(0, "forward"))).status == "ok"  # covers the third
    held = [asyncio.ensure_future(svc.command(r, cmd(r, "forward", cmd_id=2)))
            for r in (0, 1)]
    await asyncio.sleep(0.01)
    assert not any(h.done() for h in held) and svc.world.covered == 3
    assert svc.admin(encode(AdminCommand("resume"))).ok
    replies = await asyncio.wait_for(asyncio.gather(*held), 1.0)
    assert [r.status for r in replies] == ["ok", "ok"] and svc.world.covered == 5
