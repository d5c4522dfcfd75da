"""A crowded fleet's re-plan computed once (agent.offline.replan, agent.offline.runner): the
epoch's lowest survivor computes and shares it; the others check it against their own
reports and walk it, or compute it themselves when no usable share comes in time."""

from __future__ import annotations

import asyncio
import dataclasses
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from agent.offline import apart as apart_module
from agent.offline import runner as runner_module
from agent.offline.apart import shared_by_one
from agent.offline.driver import next_in_turn
from agent.offline.plan import compute_plan
from agent.offline.replan import (
    SHARE_FROM,
    ReplanBoard,
    ReplanInputs,
    share_wait,
)
from agent.offline.runner import OfflineRunner
from bus import keys
from bus.drops import DropCounter
from bus.messages import ReplanReport, ReplanShare, pack_covered, pack_routes, unpack_routes
from bus.messages.schema import SCHEMA_VERSION
from planner.maps.worlds import builtin_world
from planner.offline.rebalance import rebalance
from planner.types import Plan

DEAD = (1,)


def _plan() -> Plan:
    world = builtin_world("office")
    free = np.argwhere(world.free)
    starts = [(int(r), int(c)) for r, c in free[[0, len(free) // 3, len(free) // 2, -1]]]
    return compute_plan(world, starts, "opt", "dfs", 0)


def _board(plan: Plan, share_from: int = 3) -> ReplanBoard:
    """A board holding every survivor's report of robot 1's death, each where it started,
    the first quarter of the cycle covered."""
    board = ReplanBoard(plan, DropCounter(), share_from=share_from)
    covered = np.arange(plan.cycle.n) < plan.cycle.n // 4
    for rp in plan.robots:
        if rp.robot not in DEAD:
            report = ReplanReport(rp.robot, 1, DEAD, rp.start_index, (), pack_covered(covered), 0.0)
            assert board.on_report(keys.replan("m", rp.robot), report)
    assert board.missing(DEAD) == []
    return board


def _share(inputs: ReplanInputs, *, sender: int = 0, **changes: Any) -> ReplanShare:
    replan = rebalance(inputs.cycle, inputs.covered, inputs.survivors, inputs.rank)
    robots = tuple(sorted(replan.routes))
    routes = [replan.routes[r] for r in robots]
    share = ReplanShare(sender, 1, inputs.dead, inputs.digest, robots,
                        tuple(len(r) for r in routes), pack_routes(routes))
    return dataclasses.replace(share, **changes)


def test_routes_pack_and_unpack_and_a_wrong_length_is_refused() -> None:
    routes = [[5, 6, 7, 8], [], [100, 99, 98, 2000]]
    packed = pack_routes(routes)
    assert unpack_routes(packed, [4, 0, 4]) == routes
    with pytest.raises(ValueError, match="expected"):
        unpack_routes(packed, [4, 0, 3])
    with pytest.raises(ValueError, match="expected"):
        unpack_routes(packed, [4, 0, 5])
    with pytest.raises(ValueError, match="negative"):
        unpack_routes(packed, [9, -1])
    with pytest.raises(ValueError, match="decompress"):
        unpack_routes(b"not zlib", [2])
    # a long route along the cycle packs to little: 99 routes of 700 places in under 1 kB
    assert len(pack_routes([range(i * 1000, i * 1000 + 700) for i in range(99)])) < 1000


def test_the_lowest_survivor_shares_and_only_a_crowd_shares() -> None:
    plan = _plan()
    assert _board(plan, share_from=3).sharer(DEAD) == 0
    assert _board(plan, share_from=3).sharer((0, 1)) is None  # two survivors: each computes
    assert _board(plan, share_from=2).sharer((0, 1)) == 2
    assert _board(plan, share_from=4).sharer(DEAD) is None


def test_on_a_large_map_fewer_survivors_share_the_replan(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """11 survivors of 12 on 40 392 sub-cells each computed a 7.2 s re-plan on 2 cores: 84-90
    s, five of them declared dead meanwhile. A survivor weighs once per 4 000 sub-cells."""
    # the office: a crowd only
    assert not shared_by_one(12, 884, SHARE_FROM) and shared_by_one(13, 884, SHARE_FROM)
    assert not shared_by_one(12, 4_000, SHARE_FROM) and shared_by_one(13, 4_000, SHARE_FROM)
    assert shared_by_one(11, 40_392, SHARE_FROM) and shared_by_one(3, 40_392, SHARE_FROM)
    # two computations: the wall time of one, on 2 cores
    assert not shared_by_one(2, 40_392, SHARE_FROM)
    assert not shared_by_one(4, 12_668, SHARE_FROM) and shared_by_one(5, 12_668, SHARE_FROM)
    assert shared_by_one(2, 884, 2)  # told so: shares whatever the map
    assert shared_by_one(20, 40_392, 100)
    assert not shared_by_one(20, 4_000, 100)
    plan = _plan()
    assert plan.cycle.n < 4_000 and _board(plan, share_from=SHARE_FROM).sharer(DEAD) is None
    # three survivors of a map ten times the office's (in weight): the lowest computes
    monkeypatch.setattr(apart_module, "SHARE_SUB_CELLS", plan.cycle.n // 10)
    assert _board(plan, share_from=SHARE_FROM).sharer(DEAD) == 0
    assert _board(plan, share_from=SHARE_FROM).sharer((0, 1)) is None  # two: each computes


def test_a_share_made_from_the_same_reports_is_used_as_made() -> None:
    plan = _plan()
    board = _board(plan)
    inputs = board.inputs(DEAD)
    share = _share(inputs)
    assert board.on_share(keys.replan_share("m", 0), share)
    assert not board.on_share(keys.replan_share("m", 0), share)  # no news the second time
    got = board.shared(inputs)
    assert got is not None and not got.problem
    replan = rebalance(inputs.cycle, inputs.covered, inputs.survivors, inputs.rank)
    assert got.sender == 0 and dict(got.routes) == replan.routes
    assert board.drops.total() == 0


@pytest.mark.parametrize(("change", "why"), [
    ({"robot": 1}, "invalid"),  # the dead robot's, or sent on another robot's key
    ({"robots": (0, 2)}, "invalid"),  # not the survivors
    ({"lengths": (1, 2)}, "invalid"),
    ({"places": b"garbage"}, "invalid"),
    ({"dead": (3, 1)}, "invalid"),
    ({"digest": "0" * 64}, "unusable"),  # made from other reports
])
def test_a_malformed_or_foreign_share_is_counted_and_not_used(change: dict[str, Any],
                                                              why: str) -> None:
    plan = _plan()
    board = _board(plan)
    inputs = board.inputs(DEAD)
    share = _share(inputs, **change)
    board.on_share(keys.replan_share("m", share.robot), share)
    got = board.shared(inputs)
    assert (got is None) == (why == "invalid")
    assert got is None or (got.problem.startswith("was made from other reports")
                           and not got.routes)
    assert board.drops.total("replan_share", why) == 1
    assert board.shared(inputs) is None  # forgotten


def test_a_share_that_leaves_work_uncovered_is_not_used() -> None:
    plan = _plan()
    board = _board(plan)
    inputs = board.inputs(DEAD)
    good = _share(inputs)
    routes = unpack_routes(good.places, good.lengths)
    routes[1] = routes[1][: len(routes[1]) // 2]  # robot 2 would stop half-way
    short = dataclasses.replace(good, lengths=tuple(len(r) for r in routes),
                                places=pack_routes(routes))
    assert board.on_share(keys.replan_share("m", 0), short)
    got = board.shared(inputs)
    assert got is not None and got.problem.startswith("leaves ") and not got.routes
    assert board.drops.total("replan_share", "unusable") == 1


def test_a_share_round_trips_the_wire() -> None:
    from bus.codec import decode, encode
    plan = _plan()
    share = _share(_board(plan).inputs(DEAD))
    assert decode(encode(share), ReplanShare) == share
    assert SCHEMA_VERSION >= 5


# --- the runner's side -------------------------------------------------------------------


class _Solves:
    """Counts the re-plans computed (ReplanInputs.solve) in a test."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.count = 0
        solve = ReplanInputs.solve

        def counted(inputs: ReplanInputs) -> Any:
            self.count += 1
            return solve(inputs)

        monkeypatch.setattr(ReplanInputs, "solve", counted)


def _runner(plan: Plan, board: ReplanBoard, robot: int,
            announced: list[tuple[str, Any]]) -> OfflineRunner:
    async def wait_news(timeout: float) -> None:
        await asyncio.sleep(min(timeout, 0.01))

    async def refresh() -> None:
        return None

    machine = SimpleNamespace(robot=robot, cycle=plan.cycle, position=0, dead={1},
                              all_covered=False)
    bus = SimpleNamespace(mission="m", publish=lambda key, msg: None)
    peers = SimpleNamespace(wait_news=wait_news)
    hardware = SimpleNamespace(state=SimpleNamespace(sim_time=0.0))
    return OfflineRunner(bus, hardware, peers, machine, 1,  # type: ignore[arg-type]
                         refresh=refresh, refresh_period=0.05, board=board,
                         announce=lambda key, msg: announced.append((key, msg)))


async def test_the_sharer_computes_once_and_announces_what_the_others_walk(
        monkeypatch: pytest.MonkeyPatch) -> None:
    plan = _plan()
    solves = _Solves(monkeypatch)
    announced: list[tuple[str, Any]] = []
    sharer = _runner(plan, _board(plan), 0, announced)
    inputs = sharer.board.inputs(DEAD)  # type: ignore[union-attr]
    made = await sharer._replan_of(inputs)
    # no note: the worker led a session of its own (agent.offline.apart), so a niced
    # agent's autogroup does not hold it back
    assert made is not None and made[1] == ", shared with the fleet"
    # computed in a process of its own (routes_apart): nothing here, the same routes
    replan = rebalance(inputs.cycle, inputs.covered, inputs.survivors, inputs.rank)
    assert solves.count == 0 and dict(made[0]) == replan.routes
    [(key, share)] = announced
    assert key == keys.replan_share("m", 0) and isinstance(share, ReplanShare)

    # another survivor, given the share, walks it without computing anything
    board = _board(plan)
    other = _runner(plan, board, 2, [])
    assert board.on_share(key, share)
    got = await other._replan_of(board.inputs(DEAD))
    assert got is not None and got[1] == ", shared by robot 0"
    assert dict(got[0]) == dict(made[0]) and solves.count == 0


async def test_a_sharer_that_cannot_start_a_process_computes_in_a_thread(
        monkeypatch: pytest.MonkeyPatch) -> None:
    plan = _plan()
    solves = _Solves(monkeypatch)

    def no_process(*args: Any, **kwargs: Any) -> Any:
        raise OSError(38, "Function not implemented")

    monkeypatch.setattr(apart_module, "ProcessPoolExecutor", no_process)
    announced: list[tuple[str, Any]] = []
    sharer = _runner(plan, _board(plan), 0, announced)
    made = await sharer._replan_of(sharer.board.inputs(DEAD))  # type: ignore[union-attr]
    assert made is not None and made[1].startswith(
        ", shared with the fleet (computed in a thread: no process for it:")
    assert solves.count == 1 and len(announced) == 1


async def test_a_survivor_computing_a_large_maps_replan_for_itself_does_it_apart(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """In a thread such a re-plan held the interpreter lock for seconds: the agent's Zenoh
    threads fell behind and its peers declared it dead (12 robots, 40 392 sub-cells)."""
    plan = _plan()
    solves = _Solves(monkeypatch)
    board = _board(plan, share_from=99)  # each survivor computes
    inputs = board.inputs(DEAD)
    replan = rebalance(inputs.cycle, inputs.covered, inputs.survivors, inputs.rank)
    got = await _runner(plan, board, 2, [])._replan_of(inputs)
    assert got is not None and got[1] == "" and dict(got[0]) == replan.routes
    assert solves.count == 1  # a small map: in a thread here
    monkeypatch.setattr(apart_module, "APART_FROM_SUB_CELLS", plan.cycle.n)
    got = await _runner(plan, board, 2, [])._replan_of(inputs)
    assert got is not None and got[1] == "" and dict(got[0]) == replan.routes
    assert solves.count == 1  # in a process of its own: nothing here

    def no_process(*args: Any, **kwargs: Any) -> Any:
        raise OSError(38, "Function not implemented")

    monkeypatch.setattr(apart_module, "ProcessPoolExecutor", no_process)
    got = await _runner(plan, board, 2, [])._replan_of(inputs)
    assert got is not None and got[1].startswith(" (computed in a thread: no process for it:")
    assert solves.count == 2 and dict(got[0]) == replan.routes


async def test_a_share_that_does_not_come_is_computed_after_the_wait(
        monkeypatch: pytest.MonkeyPatch) -> None:
    plan = _plan()
    solves = _Solves(monkeypatch)
    monkeypatch.setattr(runner_module, "share_wait", lambda survivors, sub_cells=0: 0.2)
    board = _board(plan)
    other = _runner(plan, board, 2, [])
    loop = asyncio.get_running_loop()
    began = loop.time()
    got = await other._replan_of(board.inputs(DEAD))
    assert got is not None and "computed here: robot 0's not heard in" in got[1]
    assert solves.count == 1 and loop.time() - began >= 0.2


async def test_waiting_for_a_share_ends_with_the_epoch(monkeypatch: pytest.MonkeyPatch) -> None:
    plan = _plan()
    _Solves(monkeypatch)
    board = _board(plan)
    other = _runner(plan, board, 2, [])
    task = asyncio.create_task(other._replan_of(board.inputs(DEAD)))
    await asyncio.sleep(0.05)
    other.machine.dead = {1, 3}  # a second death: a new epoch
    async with asyncio.timeout(2):
        assert await task is None


async def test_an_unusable_share_is_computed_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    plan = _plan()
    solves = _Solves(monkeypatch)
    board = _board(plan)
    inputs = board.inputs(DEAD)
    assert board.on_share(keys.replan_share("m", 0), _share(inputs, digest="0" * 64))
    async with asyncio.timeout(share_wait(3) / 2):  # long before the wait ends
        got = await _runner(plan, board, 2, [])._replan_of(inputs)
    assert got is not None and got[1].startswith(", computed here: robot 0's was made from")
    assert solves.count == 1


def test_the_wait_grows_with_the_fleet() -> None:
    assert share_wait(3) == 10.0
    assert share_wait(99) == pytest.approx(297.0)


# --- what a crowded survivor pulls while it waits for the reports -------------------------


class _CrowdPulls:
    """Records a crowded runner's pulls (agent.offline.runner.CrowdPulls)."""

    def __init__(self) -> None:
        self.turns = 0
        self.asked: list[list[int]] = []

    async def in_turn(self) -> None:
        self.turns += 1

    async def each(self, robots: Any) -> None:
        self.asked.append(list(robots))


def _waiting_runner(plan: Plan, crowd: _CrowdPulls | None,
                    refreshes: list[float]) -> OfflineRunner:
    """Robot 0 after robot 1's death; only robot 2's report has come."""
    board = ReplanBoard(plan, DropCounter(), share_from=3)
    covered = np.zeros(plan.cycle.n, dtype=bool)
    report = ReplanReport(2, 1, DEAD, plan.robots[2].start_index, (), pack_covered(covered), 0.0)
    assert board.on_report(keys.replan("m", 2), report)
    runner = _runner(plan, board, 0, [])
    runner.machine.pending_route = ()  # type: ignore[misc]
    runner.machine.covered = covered
    runner._refresh_period = 30.0  # no second pull within a test, however loaded the host

    async def refresh() -> None:
        refreshes.append(asyncio.get_running_loop().time())

    runner._refresh = refresh
    runner._crowd = crowd
    return runner


async def test_a_crowded_survivor_pulls_only_the_reports_it_lacks_and_not_at_once() -> None:
    plan = _plan()
    refreshes: list[float] = []
    crowd = _CrowdPulls()
    runner = _waiting_runner(plan, crowd, refreshes)
    task = asyncio.create_task(runner._replan())
    await asyncio.sleep(0.2)
    # every survivor has just published its report: nothing pulled yet
    assert crowd.asked == [] and refreshes == []
    runner._refreshed = -float("inf")  # the period is over
    await asyncio.sleep(0.2)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert crowd.asked == [[3]]  # robot 3's report alone is missing (0 is this robot's own)
    assert refreshes == [] and crowd.turns == 0


async def test_a_small_fleets_survivor_pulls_every_state_at_once() -> None:
    plan = _plan()
    refreshes: list[float] = []
    runner = _waiting_runner(plan, None, refreshes)
    task = asyncio.create_task(runner._replan())
    await asyncio.sleep(0.2)
    task.cancel()
    with pytest.raises(asyncio.CancelledError):
        await task
    assert len(refreshes) == 1


def test_pulls_in_turn_ask_every_robot_within_k_over_count_pulls() -> None:
    peers = [r for r in range(100) if r not in (10, 50)]
    turn, asked = 0, []
    for _ in range(4):
        chosen, turn = next_in_turn(peers, turn, 25)
        assert len(chosen) == 25 and len(set(chosen)) == 25
        asked += chosen
    assert set(asked) == set(peers)  # 100 asks of 98 robots: two asked twice
    assert next_in_turn(peers[:7], 40, 25) == (peers[:7], 0)  # fewer than asked: all of them


async def test_a_survivor_that_re_planned_answers_its_report_but_no_longer_repeats_it(
        ) -> None:
    """Every survivor re-publishing its report (~1 kB) each period for the rest of the
    mission flooded a slow link between hosts (docs/operations.md): once re-planned, the
    report is made quiet; a survivor still missing it pulls it (the state query answers
    quiet messages too)."""
    from planner.offline.machine import OfflineRobot

    plan = _plan()
    board = _board(plan, share_from=99)  # below the crowd: each survivor computes
    machine = OfflineRobot(plan, 2, takeover=False)
    machine.on_dead(1)
    announced: list[str] = []
    quieted: list[str] = []

    async def wait_news(timeout: float) -> None:
        await asyncio.sleep(min(timeout, 0.01))

    async def refresh() -> None:
        return None

    runner = OfflineRunner(SimpleNamespace(mission="m", publish=lambda key, msg: None),  # type: ignore[arg-type]
                           SimpleNamespace(state=SimpleNamespace(sim_time=3.0)),  # type: ignore[arg-type]
                           SimpleNamespace(wait_news=wait_news),  # type: ignore[arg-type]
                           machine, 1, refresh=refresh, refresh_period=0.05, board=board,
                           announce=lambda key, msg: announced.append(key),
                           quiet=quieted.append)
    await asyncio.wait_for(runner._replan(), 30)
    assert announced == [keys.replan("m", 2)]  # announced when it stopped ...
    assert quieted == [keys.replan("m", 2)]  # ... and quiet once the re-plan is walked
    assert machine.pending_route, "it has a re-plan to walk"
