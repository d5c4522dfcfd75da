"""The agent's parts without Zenoh: the OfflineRobot machine under late and reordered
knowledge, the peer table's validation, and the hardware client against simhw's service."""

from __future__ import annotations

import itertools
import random
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agent.core.errors import FencedError, HardwareError
from agent.offline.hardware import Hardware
from agent.offline.peers import PeerTable
from agent.offline.plan import compute_plan
from bus.bridge import Received
from bus.drops import DropCounter
from bus.messages import (
    AgentState,
    DeathNotice,
    HwCommand,
    Progress,
    RobotStatus,
    pack_covered,
    unpack_covered,
)
from planner.errors import PlannerError
from planner.invariants import check_path_moves
from planner.offline.machine import Finished, MoveTo, OfflineRobot, WaitFor
from planner.types import OccupancyGrid, Plan, SubCell
from simhw.clock import FastClock
from simhw.dead_bodies import on_death
from simhw.kinematics import Kinematics
from simhw.service import HwService
from simhw.types import Heading, Pose
from simhw.world import World


def room(h: int, w: int, pillar: bool) -> OccupancyGrid:
    free = np.ones((h, w), dtype=bool)
    if pillar:
        free[h // 2 - 1: h // 2 + 1, 2:4] = False
    return OccupancyGrid(free, name="room")


def random_plan(rng: random.Random, k: int, algo: str) -> Plan:
    grid = room(2 * rng.randint(2, 5), 2 * rng.randint(3, 6), rng.random() < 0.5)
    subs = [(int(r), int(c)) for r, c in np.argwhere(grid.free)]
    while True:
        starts = rng.sample(subs, k)
        try:
            return compute_plan(grid, starts, algo, rng.choice(["dfs", "bfs"]),
                                rng.randint(0, 9))
        except PlannerError:  # two starts in one cell, say: draw again
            continue


def run_async_fleet(plan: Plan, deaths: dict[int, int], rng: random.Random,
                    max_delay: int) -> tuple[dict[int, list[int]], np.ndarray]:
    """Drive one OfflineRobot per robot with random speeds and message delays.

    Each step every live robot acts with probability 1/2; each arrival reaches each peer
    after 0..max_delay steps (out of order across senders); a death reaches each peer after
    1..max_delay + 1 steps. Returns every robot's walk (cycle indices) and true coverage."""
    n = plan.cycle.n
    ids = [rp.robot for rp in plan.robots]
    machines = {r: OfflineRobot(plan, r) for r in ids}
    walks = {rp.robot: [rp.start_index] for rp in plan.robots}
    covered = np.zeros(n, dtype=bool)
    covered[[rp.start_index for rp in plan.robots]] = True
    inbox: dict[int, list[tuple[int, str, int]]] = {r: [] for r in ids}
    alive = set(ids)
    for step in range(50 * n):
        for robot, when in deaths.items():
            if when == step and robot in alive:
                alive.discard(robot)
                for peer in ids:
                    inbox[peer].append((step + 1 + rng.randint(0, max_delay), "dead", robot))
        for robot in ids:
            due = [m for m in inbox[robot] if m[0] <= step]
            inbox[robot] = [m for m in inbox[robot] if m[0] > step]
            for _, what, value in due:
                if what == "dead":
                    machines[robot].on_dead(value)
                else:
                    machines[robot].on_covered(value)
        for robot in sorted(alive):
            if rng.random() < 0.5:
                continue
            action = machines[robot].next_action()
            machines[robot].pop_decisions()
            if isinstance(action, MoveTo):
                index = machines[robot].on_moved()
                assert index == action.index
                walks[robot].append(index)
                covered[index] = True
                for peer in ids:
                    if peer != robot:
                        inbox[peer].append((step + rng.randint(0, max_delay), "cell", index))
        if all(isinstance(machines[r].next_action(), Finished) for r in alive):
            break
    return walks, covered


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), k=st.integers(2, 4),
       algo=st.sampled_from(["nb", "bt", "opt"]), max_delay=st.integers(0, 6))
def test_late_knowledge_never_leaves_a_sub_cell_uncovered(seed: int, k: int, algo: str,
                                                           max_delay: int) -> None:
    rng = random.Random(seed)
    plan = random_plan(rng, k, algo)
    victims = rng.sample([rp.robot for rp in plan.robots], rng.randint(0, k - 1))
    deaths = {robot: rng.randint(0, plan.makespan + 2) for robot in victims}
    walks, covered = run_async_fleet(plan, deaths, rng, max_delay)
    assert covered.all(), f"uncovered cycle indices {np.flatnonzero(~covered)}"
    for robot, walk in walks.items():
        check_path_moves([plan.cycle.at(i) for i in walk])
        own = [plan.cycle.position(s) for s in plan.robots[robot].path]
        prefix = walk[:len(own)]
        assert prefix == own[:len(prefix)], f"robot {robot} left its own walk"
        if robot not in deaths:
            assert walk[:len(own)] == own
            # After its own walk a robot only ever moves counter-clockwise (takeovers).
            for a, b in zip(walk[len(own) - 1:], walk[len(own):], strict=False):
                assert (b - a) % plan.cycle.n == 1


def test_without_failures_every_robot_walks_its_plan_and_finishes() -> None:
    plan = random_plan(random.Random(5), 3, "nb")
    walks, covered = run_async_fleet(plan, {}, random.Random(1), max_delay=3)
    assert covered.all()
    for rp in plan.robots:
        assert walks[rp.robot] == [plan.cycle.position(s) for s in rp.path]
    visits = np.zeros(plan.cycle.n, dtype=int)
    for walk in walks.values():
        np.add.at(visits, walk, 1)
    assert (visits == 1).all(), "non-backtracking MSTC covers every sub-cell exactly once"


def test_a_robot_waits_for_its_successor_and_takes_over_only_when_told() -> None:
    plan = random_plan(random.Random(8), 2, "nb")
    a, b = (rp.robot for rp in plan.robots)
    machine = OfflineRobot(plan, a)
    while isinstance(action := machine.next_action(), MoveTo):
        machine.on_moved()
    assert action == WaitFor(b)
    assert machine.pop_decisions() == [] and not machine.about_to_take_over
    machine.on_dead(b)
    assert machine.about_to_take_over
    action = machine.next_action()
    assert not machine.about_to_take_over
    (decision,) = machine.pop_decisions()
    assert decision.dead == b
    assert decision.target == machine.last_uncovered(b)
    assert isinstance(action, MoveTo)


def test_covered_bits_round_trip() -> None:
    bits = np.random.default_rng(3).random(77) < 0.5
    assert np.array_equal(unpack_covered(pack_covered(bits), 77), bits)
    with pytest.raises(ValueError):
        unpack_covered(b"\x01", 77)
    with pytest.raises(ValueError):
        unpack_covered(pack_covered(bits[:8]), 77)


# --- the peer table -----------------------------------------------------------------------

def test_peer_table_counts_nonsense_and_keeps_facts() -> None:
    plan = random_plan(random.Random(2), 3, "bt")
    drops = DropCounter()
    peers = PeerTable(robot=0, k=3, drops=drops)
    m = "t"
    peers.on_status(f"mstc/{m}/status/5", RobotStatus(5, 1, (0, 0), "bt", "", "x"))
    peers.on_status(f"mstc/{m}/status/2", RobotStatus(1, 1, (0, 0), "bt", "", "x"))
    assert drops.total("status", "invalid") == 2 and peers.statuses == {}
    start = plan.robots[1].start
    peers.on_status(f"mstc/{m}/status/1", RobotStatus(1, 2, start, "bt", "", "x"))
    peers.on_status(f"mstc/{m}/status/1", RobotStatus(1, 1, (9, 9), "bt", "", "old"))
    assert peers.statuses[1].state == "x", "an older life's status is ignored"
    # Coverage heard before the plan is replayed into the machine once it exists.
    cell = plan.cycle.at(plan.robots[1].start_index + 1)
    peers.on_progress(f"mstc/{m}/progress/1", Progress(1, 2, 1, cell, 0.0))
    peers.on_progress(f"mstc/{m}/progress/1", Progress(1, 2, 2, (99, 99), 0.0))
    peers.on_death(DeathNotice(2, 1, 0, "token", 0.0))
    peers.on_death(DeathNotice(1, 1, 0, "token", 0.0))  # robot 1's older life
    machine = OfflineRobot(plan, 0)
    peers.attach(machine)
    assert machine.covered[plan.cycle.position(cell)]
    assert drops.total("progress", "invalid") == 1
    assert machine.dead == {2}
    # Another robot's knowledge merges in; a wrong-size one is dropped.
    bits = np.zeros(plan.cycle.n, dtype=bool)
    bits[:5] = True
    state = AgentState(1, 2, "covering", 3, plan.cycle.n, pack_covered(bits), (), ())
    peers.on_state(f"mstc/{m}/state/1", state)
    assert machine.covered[:5].all()
    peers.on_state(f"mstc/{m}/state/1", AgentState(1, 2, "x", 0, 3, b"", (), ()))
    assert drops.total("state", "invalid") == 1


# --- the hardware client against simhw's own service ---------------------------------------

class ServiceBus:
    """Stands in for the Bus: hardware queries go straight to an HwService."""

    mission = "unit"

    def __init__(self, service: HwService) -> None:
        self.service = service

    async def query(self, key: str, request: Any, expected: Any, *,
                    timeout: float = 2.0) -> list[Received[Any]]:
        assert isinstance(request, HwCommand)
        reply = await self.service.execute(request.robot, request)
        return [Received(key, reply)]


def service_for(grid: OccupancyGrid, poses: list[Pose]) -> HwService:
    world = World(grid, poses)
    return HwService(world, FastClock(), Kinematics(), "unit", lambda key, msg: None)


def quarter_turns(path: list[SubCell], heading: int) -> int:
    deltas = {(-1, 0): 0, (0, 1): 1, (1, 0): 2, (0, -1): 3}
    total = 0
    for a, b in itertools.pairwise(path):
        want = deltas[(b[0] - a[0], b[1] - a[1])]
        total += min((want - heading) % 4, (heading - want) % 4)
        heading = want
    return total


async def test_hardware_walks_a_plan_path_with_fewest_turns() -> None:
    plan = random_plan(random.Random(4), 2, "bt")
    h, w = plan.cycle.index.shape
    grid = room(h, w, pillar=False)
    rp = plan.robots[0]
    service = service_for(grid, [Pose(*rp.start, Heading.N)])
    hardware = Hardware(ServiceBus(service), 0, 1)  # type: ignore[arg-type]
    await hardware.wait_for_pose(1.0)
    for sub in rp.path[1:]:
        await hardware.step_to(sub)
    body = service.world.body(0)
    assert body.pose.sub == rp.path[-1]
    turns = service.counts["ok"] - len(rp.path) + 1 - 1  # minus forwards and the pose read
    assert turns == quarter_turns(list(rp.path), 0)
    visited = {rec.sub for rec in service.world.cover_log}
    assert visited == set(rp.path)


async def test_hardware_refuses_a_jump_and_reports_a_failed_body() -> None:
    grid = room(4, 4, pillar=False)
    service = service_for(grid, [Pose(0, 0, Heading.E)])
    hardware = Hardware(ServiceBus(service), 0, 1)  # type: ignore[arg-type]
    await hardware.wait_for_pose(1.0)
    with pytest.raises(HardwareError, match="not next to"):
        await hardware.step_to((2, 2))
    service.world.fail(0)
    with pytest.raises(HardwareError, match="failed"):
        await hardware.step_to((0, 1))


# --- dead bodies in simhw -----------------------------------------------------------------

async def test_a_dead_robot_is_fenced_and_its_body_stops_blocking() -> None:
    grid = room(4, 4, pillar=False)
    service = service_for(grid, [Pose(0, 0, Heading.E), Pose(0, 1, Heading.E)])
    service.drops = DropCounter()
    taker = Hardware(ServiceBus(service), 0, 1)  # type: ignore[arg-type]
    dead = Hardware(ServiceBus(service), 1, 1)  # type: ignore[arg-type]
    await taker.wait_for_pose(1.0)
    await dead.wait_for_pose(1.0)
    reply = await taker.command("forward")
    assert reply.status == "bumped", "a live body blocks"
    assert on_death(service, DeathNotice(1, 1, 0, "token", 0.0), "vanish")
    await taker.step_to((0, 1))
    assert service.world.body(0).pose.sub == (0, 1)
    with pytest.raises(FencedError):
        await dead.command("turn_left")
    assert not on_death(service, DeathNotice(7, 1, 0, "token", 0.0), "vanish")
    assert service.drops.total("death", "invalid") == 1


async def test_block_policy_keeps_the_dead_body_in_the_way() -> None:
    service = service_for(room(4, 4, pillar=False),
                          [Pose(0, 0, Heading.E), Pose(0, 1, Heading.E)])
    on_death(service, DeathNotice(1, 1, 0, "token", 0.0), "block")
    taker = Hardware(ServiceBus(service), 0, 1)  # type: ignore[arg-type]
    await taker.wait_for_pose(1.0)
    assert (await taker.command("forward")).status == "bumped"
