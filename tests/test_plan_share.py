"""A crowded offline fleet's first plan computed once (agent.offline.planshare): the lowest
participant computes and shares it; the others rebuild it, check it against the inputs they
hold and fly it, or compute it themselves when the share is unusable."""

from __future__ import annotations

import asyncio
import dataclasses
import subprocess
import sys
import time
from collections.abc import Sequence
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from agent.offline import apart as apart_module
from agent.offline import driver as driver_module
from agent.offline.driver import OfflineAgent
from agent.offline.options import OfflineOptions
from agent.offline.plan import fleet_plan
from agent.offline.planshare import (
    SHARE_FROM,
    UnusableShareError,
    plan_inputs,
    plan_of,
    share_of,
    share_wait,
    sharer,
    unshared,
)
from bus import keys
from bus.codec import decode, encode
from bus.drops import DropCounter
from bus.messages import PlanShare, join_moves, pack_moves, split_moves, unpack_moves
from planner.digest import plan_digest
from planner.grid import work_area
from planner.maps import resolve_world
from planner.placement import random_starts
from planner.types import OccupancyGrid, Plan, SubCell

IDS = (0, 2, 3, 5, 7, 8)  # participants with gaps: robots 1, 4 and 6 took no part


def _made(world: str, algo: str, k: int = len(IDS), seed: int = 0
          ) -> tuple[OccupancyGrid, Sequence[SubCell], list[int], Plan]:
    grid = resolve_world(world)
    starts = random_starts(grid, k, seed)
    ids = list(IDS) if k == len(IDS) else list(range(k))
    return grid, starts, ids, fleet_plan(grid, starts, ids, algo, "dfs", seed)


@pytest.mark.parametrize(("world", "algo", "k"), [
    ("office", "nb", 6), ("office", "bt", 6), ("office", "opt", 6), ("office", "balanced", 6),
    ("cave", "balanced", 6), ("grid30x20", "balanced", 30), ("maze:15x17:3", "balanced", 6)])
def test_a_shared_plan_rebuilds_into_the_plan_made(world: str, algo: str, k: int) -> None:
    grid, starts, ids, plan = _made(world, algo, k)
    share = share_of(plan, ids[0], 1, plan_inputs(grid, ids, starts, algo, "dfs", 0))
    # over the wire and back, strictly decoded
    share = decode(encode(share), PlanShare)
    got = plan_of(share, work_area(grid, starts), ids, algo)
    assert plan_digest(got) == plan_digest(plan) == share.digest
    assert np.array_equal(got.cycle.index, plan.cycle.index)
    for mine, theirs in zip(got.robots, plan.robots, strict=True):
        assert (mine.robot, mine.start, mine.start_index, mine.legs, mine.path,
                mine.walk_out) == (theirs.robot, theirs.start, theirs.start_index,
                                   theirs.legs, theirs.path, theirs.walk_out)
    assert got.notes == plan.notes


def test_walks_pack_to_two_bits_a_move_and_back() -> None:
    walks = [[(3, 3), (3, 4), (4, 4), (4, 3), (3, 3)], [(0, 0)], [(5, 1), (6, 1)]]
    back = split_moves(join_moves(walks), [w[0] for w in walks], [len(w) - 1 for w in walks])
    assert [[tuple(map(int, s)) for s in walk] for walk in back] == walks
    one = unpack_moves(pack_moves(walks[0]), (3, 3), 4)
    assert [tuple(map(int, s)) for s in one] == walks[0]
    with pytest.raises(ValueError, match="not one 4-adjacent move"):
        pack_moves([(0, 0), (1, 1)])
    with pytest.raises(ValueError, match="expected for 9 moves"):
        unpack_moves(pack_moves(walks[0]), (3, 3), 9)
    with pytest.raises(ValueError, match="does not decompress"):
        unpack_moves(b"not zlib", (0, 0), 2)


def _changed(share: PlanShare, plan: Plan, other: Plan, change: str) -> PlanShare:
    """``share`` with one thing wrong, as a faulty or forged sharer might send it."""
    lengths = list(share.lengths)
    if change == "one walk too few":
        return dataclasses.replace(share, lengths=share.lengths[:-1])
    if change == "a walk cut short":
        lengths[0] -= 1
        return dataclasses.replace(share, lengths=tuple(lengths))
    if change == "another plan's walks":
        return dataclasses.replace(share, lengths=tuple(rp.steps for rp in other.robots),
                                   moves=join_moves([rp.path for rp in other.robots]))
    if change == "the cycle begun elsewhere":
        r, c = share.cycle_start
        return dataclasses.replace(share, cycle_start=(r + 2, c))
    if change == "a cycle that passes a sub-cell twice":
        first, second = plan.cycle.at(0), plan.cycle.at(1)
        assert plan.cycle.n % 2 == 0  # back and forth, closing where it began
        return dataclasses.replace(share, cycle=pack_moves([first, second] * (plan.cycle.n // 2)))
    if change == "a leg of nothing":
        return dataclasses.replace(share, legs=("sideways4", *share.legs[1:]))
    if change == "walk-outs changed":
        return dataclasses.replace(share, digest="0" * 64)
    if change == "not shared":
        return unshared(share.robot, 1, share.inputs, "does not fit a message")
    raise AssertionError(change)


@pytest.mark.parametrize(("change", "reason"), [
    ("one walk too few", "walks of 5 robots, 6 participants"),
    ("a walk cut short", "not covered|moves"),
    ("another plan's walks", "robot 0 starts|not covered|rebuilds"),
    ("the cycle begun elsewhere", "cycle|4-adjacent"),
    ("a cycle that passes a sub-cell twice", "4-adjacent|twice"),
    ("a leg of nothing", "leg 'sideways4'"),
    ("walk-outs changed", "rebuilds into plan"),
    ("not shared", "not shared: does not fit a message")])
def test_a_share_that_is_wrong_is_refused_with_its_reason(change: str, reason: str) -> None:
    grid, starts, ids, plan = _made("office", "opt")
    other = fleet_plan(grid, starts, ids, "nb", "dfs", 0)
    share = share_of(plan, ids[0], 1, plan_inputs(grid, ids, starts, "opt", "dfs", 0))
    bad = _changed(share, plan, other, change)
    with pytest.raises(UnusableShareError, match=reason):
        plan_of(bad, work_area(grid, starts), ids, "opt")


def test_the_inputs_name_every_input_of_the_plan() -> None:
    grid = resolve_world("office")
    starts = random_starts(grid, 3, 0)
    base: dict[str, Any] = {"grid": grid, "participants": [0, 1, 2], "starts": starts,
                            "algo": "opt", "tree": "dfs", "seed": 0}
    other_grid = resolve_world("cave")
    changes: dict[str, Any] = {"grid": other_grid, "participants": [0, 1, 3],
                               "starts": [starts[1], starts[0], starts[2]], "algo": "balanced",
                               "tree": "bfs", "seed": 1}
    digests = {plan_inputs(**base)}
    for name, value in changes.items():
        digests.add(plan_inputs(**{**base, name: value}))
    assert len(digests) == 1 + len(changes)
    assert plan_inputs(**base) == plan_inputs(**base)


def test_the_lowest_participant_shares_and_only_in_a_crowd() -> None:
    crowd = list(range(3, 3 + SHARE_FROM))
    assert sharer(crowd, SHARE_FROM) == 3
    assert sharer(crowd[:-1], SHARE_FROM) is None
    assert sharer([4, 2], 2) == 2
    assert share_wait(100) > share_wait(30) >= share_wait(2) > 0


def test_on_a_large_map_fewer_participants_share_the_first_plan_and_wait_longer() -> None:
    """A balanced plan of rooms:120x120:1 (45 420 sub-cells) took 51 s of CPU at k = 20:
    each of 20 participants computing it cost the fleet 17 minutes of CPU."""
    assert sharer(list(range(20)), SHARE_FROM, 45_420) == 0
    assert sharer([7, 5, 9], SHARE_FROM, 45_420) == 5
    assert sharer([7, 5], SHARE_FROM, 45_420) is None  # two: each computes, side by side
    assert sharer(list(range(20)), SHARE_FROM, 884) is None  # the office: a crowd only
    assert share_wait(3, 45_420) > 100 and share_wait(3, 884) == share_wait(3)


async def test_a_large_maps_plan_is_computed_apart_where_each_computes_it(
        monkeypatch: pytest.MonkeyPatch) -> None:
    fleet = _Fleet(4, None)
    fleet.agent.options = OfflineOptions(world="office", plan_share_from=99)  # each computes
    apart: list[Any] = []
    real = driver_module.computed_apart

    async def recorded(work: Any, *args: Any) -> Any:
        apart.append(work)
        return await real(work, *args)

    monkeypatch.setattr(driver_module, "computed_apart", recorded)
    plan, how = await fleet.agent._first_plan(list(fleet.starts))
    assert how == "" and apart == []  # the office: in a thread
    monkeypatch.setattr(apart_module, "APART_FROM_SUB_CELLS", 1)
    again, how = await fleet.agent._first_plan(list(fleet.starts))
    # in a process of its own that leads its own session (no note), the same plan
    assert how == "" and apart == [fleet_plan] and plan_digest(again) == plan_digest(plan)


async def test_a_fleet_on_a_large_map_shares_its_first_plan(
        monkeypatch: pytest.MonkeyPatch) -> None:
    fleet = _Fleet(0, None)
    fleet.agent.options = OfflineOptions(world="office")  # 6 participants: no crowd
    monkeypatch.setattr(apart_module, "SHARE_SUB_CELLS", 100)  # the office weighs 8 each
    plan, how = await fleet.agent._first_plan(list(fleet.starts))
    assert how == ", shared with the fleet"
    [(_, share)] = fleet.announced
    assert share.digest == plan_digest(plan)


class _Fleet:
    """Just enough of an offline agent to drive its first plan (OfflineAgent._first_plan)
    without processes: robot ``robot`` of participants 0-5 on office, sharing from 2."""

    def __init__(self, robot: int, monkeypatch: pytest.MonkeyPatch | None) -> None:
        grid = resolve_world("office")
        self.starts = random_starts(grid, 6, 0)
        agent = OfflineAgent.__new__(OfflineAgent)
        agent.robot, agent.incarnation, agent.grid = robot, 1, grid
        agent.roster = dict(enumerate(self.starts))
        agent.options = OfflineOptions(world="office", plan_share_from=2)
        agent.config = SimpleNamespace(algo="opt", seed=0, k=6,  # type: ignore[assignment]
                                       announce_period=0.01)
        agent._plan_shares, agent._pulled, agent._t0 = {}, -float("inf"), time.monotonic()
        agent.bus = SimpleNamespace(mission="m", drops=DropCounter(),  # type: ignore[assignment]
                                    max_payload=64 * 1024)
        self.announced: list[tuple[str, Any]] = []
        agent.announcer = SimpleNamespace(  # type: ignore[assignment]
            set=lambda key, msg: self.announced.append((key, msg)))
        self.dead: set[int] = set()
        self.pulls: list[int] = []

        async def wait_news(timeout: float) -> None:
            await asyncio.sleep(min(timeout, 0.005))

        async def pull(robot: int) -> None:
            self.pulls.append(robot)

        agent.peers = SimpleNamespace(dead=self.dead, wait_news=wait_news,  # type: ignore
                                      changed=asyncio.Event())
        agent.pull = pull  # type: ignore[method-assign]
        self.agent = agent
        self.computed = 0
        if monkeypatch is None:  # the sharer's plan goes to a process: nothing to count
            return
        made = driver_module.fleet_plan

        def counted(*args: Any) -> Plan:
            self.computed += 1
            return made(*args)

        monkeypatch.setattr(driver_module, "fleet_plan", counted)

    def share(self) -> PlanShare:
        grid, ids = self.agent.grid, list(range(6))
        plan = fleet_plan(grid, self.starts, ids, "opt", "dfs", 0)
        return share_of(plan, 0, 1, plan_inputs(grid, ids, self.starts, "opt", "dfs", 0))


async def test_the_sharer_computes_apart_and_announces_what_the_others_fly(
        monkeypatch: pytest.MonkeyPatch) -> None:
    sharer_fleet = _Fleet(0, None)
    plan, how = await sharer_fleet.agent._first_plan(list(sharer_fleet.starts))
    # in a process of its own that leads its own session: no note (a thread would say so)
    assert how == ", shared with the fleet"
    [(key, share)] = sharer_fleet.announced
    assert key == keys.plan_share("m", 0) and share.digest == plan_digest(plan)

    other = _Fleet(3, monkeypatch)
    other.agent._on_plan_share(key, share)
    got, how = await other.agent._first_plan(list(other.starts))
    assert how == ", shared by robot 0" and plan_digest(got) == plan_digest(plan)
    assert other.computed == 0 and other.announced == []


async def test_a_lost_share_is_pulled_from_the_sharer_alone_until_it_comes(
        monkeypatch: pytest.MonkeyPatch) -> None:
    fleet = _Fleet(2, monkeypatch)
    share = fleet.share()

    async def arrives_late() -> None:
        await asyncio.sleep(0.1)
        fleet.agent._on_plan_share(keys.plan_share("m", 0), share)

    async with asyncio.TaskGroup() as group:
        group.create_task(arrives_late())
        plan, how = await fleet.agent._first_plan(list(fleet.starts))
    assert how == ", shared by robot 0" and fleet.computed == 0
    assert plan_digest(plan) == share.digest
    assert fleet.pulls and set(fleet.pulls) == {0}  # the sharer's state, nobody else's


@pytest.mark.parametrize("trouble", ["unusable", "dead", "silent", "elsewhere", "impostor"])
async def test_without_a_usable_share_a_robot_computes_the_plan_itself(
        trouble: str, monkeypatch: pytest.MonkeyPatch) -> None:
    fleet = _Fleet(4, monkeypatch)
    share = fleet.share()
    monkeypatch.setattr(driver_module, "share_wait", lambda robots, sub_cells=0: 0.2)
    if trouble == "unusable":
        fleet.agent._on_plan_share(keys.plan_share("m", 0),
                                   dataclasses.replace(share, lengths=share.lengths[1:]))
    elif trouble == "dead":
        fleet.dead.add(0)
    elif trouble == "elsewhere":  # made from other starts: not this fleet's plan
        fleet.agent._on_plan_share(keys.plan_share("m", 0),
                                   dataclasses.replace(share, inputs="0" * 64))
    elif trouble == "impostor":  # robot 5 may not speak for robot 0
        fleet.agent._on_plan_share(keys.plan_share("m", 5), share)
    plan, how = await fleet.agent._first_plan(list(fleet.starts))
    assert fleet.computed == 1 and plan_digest(plan) == share.digest
    expected = {"unusable": "computed here: robot 0's share is unusable: walks of 5 robots",
                "dead": "computed here: robot 0 died",
                "silent": "computed here: robot 0's not heard in 0 s",
                "elsewhere": "computed here: robot 0's share was made from other inputs",
                "impostor": "computed here: robot 0's not heard in 0 s"}[trouble]
    assert how.startswith(", " + expected), how
    counted = {kind for kind, _ in fleet.agent.bus.drops.snapshot()}
    assert ("plan_share" in counted) == (trouble in ("unusable", "impostor")), counted


@pytest.mark.parametrize(("k", "asked"), [(30, [[4, 9]]), (6, ["everyone"])])
async def test_a_crowd_waiting_for_digests_asks_only_the_robots_it_waits_for(
        k: int, asked: list[Any]) -> None:
    """100 robots that pulled every robot's state while they waited for the plan digests
    took 27 s to hear them all; in a crowd the wait asks the missing robots alone."""
    fleet = _Fleet(0, None)
    fleet.agent.config.k = k  # type: ignore[misc]
    fleet.agent.config.announce_period = 0.5  # type: ignore[misc]
    pulled: list[Any] = []

    async def each(robots: Sequence[int]) -> None:
        pulled.append(list(robots))

    async def refresh() -> None:
        pulled.append("everyone")

    fleet.agent.each = each  # type: ignore[method-assign]
    fleet.agent.refresh = refresh  # type: ignore[method-assign]
    await fleet.agent._wait_news([4, 9])
    await fleet.agent._wait_news([4, 9])  # within the pull period: nothing more
    assert pulled == asked


def test_flying_a_balanced_plan_imports_none_of_the_planner() -> None:
    """An agent that flies a shared balanced plan loads its machine only: 100 agents that
    imported the planner with it (scipy, 0.9 s each) at once kept a fleet still for 20 s."""
    probe = ("import sys; from planner.algorithms import algorithm; "
             "algorithm('balanced').load_machine(); "
             "print(sorted(m for m in ('scipy', 'planner.balanced.plan') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True, timeout=60)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
