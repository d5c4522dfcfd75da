"""Robots failed part-way through their work, over seeds (issues 3 and 4): a real router,
simhw and agents on loopback, every victim and kill point drawn from the test's seed so that a
failing id reproduces the scenario.

- Offline MSTC: 1..k-1 agents SIGKILLed part-way through their sections; simhw's ground truth
  is compared with planner.offline's lockstep semantics for the same failures.
- ORMSTC: 1..k-1 agents SIGKILLed; every sub-cell the survivors can reach around the dead
  bodies is covered and each victim's cells are taken over; the same through
  ``mstc up --algo ormstc --kill``.
- ``mstc up --kill-hw R@progress=P`` and ``mstc kill R --hw`` on the robot with the longest
  section, which still has most of it to walk when its body fails.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import random
import re
import signal
import subprocess
from collections.abc import AsyncIterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fleet_helpers import (
    Heard,
    LocalFleet,
    all_heard,
    fail_when,
    listen,
    mission_bus,
    mstc,
    stop_processes,
    write_room,
)
from ormstc_oracles import must_cover
from takeover_oracle import fit_failures, ordered_walks, run_plan
from test_agent_fleet import lockstep_failures
from test_fleet_unit import reachable_oracle
from waiting import through_router

from agent.offline.plan import compute_plan
from bus import keys
from bus.bridge import Bus
from bus.messages import WorldState, world_visits
from deploy.kill_orders import covered_for
from planner.algorithms import Family, algorithm
from planner.maps import resolve_world
from planner.offline.lockstep import TakeoverResult, simulate_failures
from planner.types import OccupancyGrid, Plan, SubCell

pytestmark = pytest.mark.integration

_missions = itertools.count()
# 12 x 12 sub-cells, a pillar filling cell (2, 2): 140 free sub-cells. Whole-cell obstacles
# suit ORMSTC's thin sonar too (docs/ormstc.md, sensing).
ROOM = ["............"] * 4 + ["....##......"] * 2 + ["............"] * 6
# 8 x 12 sub-cells, a pillar filling cell (1, 3): 92 free sub-cells, for the ORMSTC runs in
# which k - 1 robots die and one survivor claims cell after cell (0.25 s of wall time each).
SMALL_ROOM = ["............"] * 2 + ["......##...."] * 2 + ["............"] * 4
K = 4
OFFLINE_ALGOS = ("nb", "bt", "opt")
MIN_SECTION = 8  # only robots planned to walk this far are victims: they die with work left
TIMEOUT = 60.0  # a guard against a hung test on a loaded machine, not a timing assertion
# SIGKILLs are seen through the closed link whatever these are; long heartbeat timeouts and
# leases keep a CPU-starved but live agent from being declared dead (docs/operations.md).
AGENT_ARGS = ("--start-timeout", "30", "--dead-after", "10", "--linger", "0.5")
UP_ARGS = ("--plain", "--stall-timeout", "30", "--lease-ms", "5000", "--dead-after", "5")
# The offline cases check the papers' takeover semantics: they name that recovery.
TAKEOVER = ("--recovery", "takeover")


# ---- scenarios --------------------------------------------------------------------------


def pick_starts(grid: OccupancyGrid, k: int, rng: random.Random) -> tuple[SubCell, ...]:
    """``k`` starts in distinct free cells (all of the room's free cells are connected)."""
    h, w = grid.shape
    cells = [(r, c) for r in range(h // 2) for c in range(w // 2)
             if grid.free[2 * r:2 * r + 2, 2 * c:2 * c + 2].all()]
    return tuple((2 * r + rng.randrange(2), 2 * c + rng.randrange(2))
                 for r, c in rng.sample(cells, k))


@dataclass(frozen=True)
class OfflineCase:
    """An offline mission drawn from a seed: algo, starts and the plan every agent computes."""

    algo: str
    starts: tuple[SubCell, ...]
    plan: Plan

    @property
    def steps(self) -> dict[int, int]:
        return {rp.robot: rp.steps for rp in self.plan.robots}

    @property
    def long_sections(self) -> list[int]:
        """Robots planned to walk at least MIN_SECTION moves, the longest first."""
        steps = self.steps
        return sorted((r for r in steps if steps[r] >= MIN_SECTION), key=lambda r: -steps[r])

    @classmethod
    def draw(cls, rng: random.Random, grid: OccupancyGrid) -> OfflineCase:
        """A random algo and random starts in which some robot has a long section."""
        while True:
            starts = pick_starts(grid, K, rng)
            algo = rng.choice(OFFLINE_ALGOS)
            case = cls(algo, starts, compute_plan(grid, starts, algo, "dfs", 0))
            if case.long_sections:
                return case


@pytest.fixture
async def bus(router: str) -> AsyncIterator[Bus]:
    async with mission_bus(router, f"failures{next(_missions)}") as opened:
        yield opened


# ---- oracles ----------------------------------------------------------------------------


def reachable(grid: OccupancyGrid, starts: Sequence[SubCell]) -> np.ndarray:
    return reachable_oracle(grid.free, list(starts))


def check_offline(heard: Heard, case: OfflineCase, grid: OccupancyGrid,
                  victims: set[int]) -> TakeoverResult:
    """Ground truth against the lockstep semantics of the same failures; every reachable
    sub-cell covered; every victim that had work left taken over by a walking robot."""
    area = reachable(grid, case.starts)
    assert np.array_equal(heard.covered(area.shape), area), "a reachable sub-cell is missed"
    moves = {v: heard.reported[v] for v in victims}
    semantics = simulate_failures(case.plan, lockstep_failures(case.plan, moves),
                                  recovery="takeover")
    assert semantics.complete
    for robot, want in zip(semantics.robots, semantics.walks, strict=True):
        got = heard.walks[robot]
        # A victim killed with a forward command in flight still completes that move, which
        # it never reported (its taker covers that sub-cell again).
        if robot in victims and len(got) == len(want) + 1:
            got = got[:-1]
        assert got == list(want), f"robot {robot}: ground truth walk differs from semantics"
    walked = heard.walking_takeovers()
    # A victim killed as it took a dead robot's section over, with only its unreported move
    # in flight: the semantics place its death just before that decision.
    in_flight = {(taker, dead) for taker, dead in walked
                 if taker in victims and len(heard.walks[taker]) - 1 == moves[taker] + 1}
    assert walked - in_flight <= {(t.taker, t.dead) for t in semantics.takeovers}
    # The same against the independent oracle (not the agents' own state machine).
    independent = run_plan(case.plan, fit_failures(case.plan, moves))
    assert independent.complete
    for robot, expected in enumerate(ordered_walks(case.plan, independent)):
        got = heard.walks[case.plan.robots[robot].robot]
        if case.plan.robots[robot].robot in victims and len(got) == len(expected) + 1:
            got = got[:-1]
        assert got == expected, f"robot {robot}: ground truth walk differs from the oracle"
    assert walked - in_flight <= {(taker, dead) for taker, dead, _ in independent.takeovers}
    print(f"{case.algo}: killed {moves} (reported moves), plan {case.steps}, "
          f"moves {[len(heard.walks[r]) - 1 for r in range(K)]}, walked takeovers {walked}")
    had_work = {v for v in victims if moves[v] < case.steps[v]}
    assert had_work, f"every victim had finished its section: {moves}, plan {case.steps}"
    assert had_work <= {dead for _, dead in walked}, (had_work, walked)
    return semantics


def check_ormstc(visits: np.ndarray, grid: OccupancyGrid, starts: Sequence[SubCell],
                 heard: Heard, victims: set[int], bodies: Sequence[SubCell]) -> None:
    """Every sub-cell the survivors can reach around the dead bodies was covered; no cell
    has two live owners; a survivor freed each victim's cells and took one of them."""
    alive = [s for i, s in enumerate(starts) if i not in victims]
    missed = must_cover(grid, alive, bodies) & (visits == 0)
    assert not missed.any(), f"uncovered sub-cells {np.argwhere(missed)[:10].tolist()}"
    assert heard.owners, "no ORMSTC start or tree edge was heard"
    for cell, robots in heard.owners.items():
        assert len(robots - victims) <= 1, f"cell {cell} owned by live robots {robots}"
    survivors = set(range(len(starts))) - victims
    print(f"ormstc: victims {sorted(victims)} bodies {list(bodies)}, moves "
          f"{[len(heard.walks[r]) - 1 for r in range(len(starts))]}, takeovers "
          f"{ {v: sorted(heard.takeovers_of(v)) for v in victims} }")
    for victim in victims:
        assert heard.takeovers_of(victim) & survivors, f"nobody freed robot {victim}'s cells"
        taken = [cell for cell, robots in heard.owners.items()
                 if victim in robots and robots & survivors]
        assert taken, f"no survivor took over a cell of robot {victim}"


async def world_state(bus: Bus) -> WorldState:
    replies = await bus.query(keys.world(bus.mission), None, WorldState, timeout=5.0)
    assert replies, "simhw did not answer the world query"
    return replies[0].msg


# ---- agents started by the test ---------------------------------------------------------


# Seed 3: opt, k - 1 = 3 robots killed; 16: bt, 2 killed; 21: nb, 1 killed.
@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 16, 21])
async def test_offline_fleet_survives_seeded_sigkills_as_the_semantics_say(
        bus: Bus, router: str, tmp_path: Path, seed: int) -> None:
    world = write_room(tmp_path, ROOM)
    grid = resolve_world(str(world))
    rng = random.Random(seed)
    case = OfflineCase.draw(rng, grid)
    candidates = sorted(case.long_sections)
    victims = set(rng.sample(candidates, rng.randint(1, min(K - 1, len(candidates)))))
    # Reported moves after which each victim is SIGKILLed: within the first half of its
    # section, so that it dies with work left whatever the delay of the kill.
    due = {v: rng.randint(1, case.steps[v] // 2) for v in sorted(victims)}
    fleet = LocalFleet(world, case.starts, router, bus.mission, tmp_path)
    fail_when(bus, "progress", due, fleet.kill)
    heard = Heard()
    await listen(bus, heard)
    try:
        fleet.start(case.algo, 120, *AGENT_ARGS, *TAKEOVER)
        await fleet.finish(set(range(K)) - victims, TIMEOUT)
        assert not due, f"robots {sorted(due)} never reached their kill point"
        assert all(fleet.agents[v].wait(5) == -signal.SIGKILL for v in victims)
        await all_heard(bus, heard.walks)
        check_offline(heard, case, grid, victims)
        dead = {d.robot for d in heard.deaths if d.reason != "leaving"}
        assert victims <= dead, "a SIGKILLed robot was never declared dead"
    finally:
        fleet.stop()


# Seeds 42: k - 1 = 2 of 3 robots killed; 41: 1 killed.
@pytest.mark.slow
@pytest.mark.parametrize("seed", [42, 41])
async def test_ormstc_fleet_survives_seeded_sigkills(bus: Bus, router: str, tmp_path: Path,
                                                     seed: int) -> None:
    world = write_room(tmp_path, SMALL_ROOM)
    grid = resolve_world(str(world))
    rng = random.Random(seed)
    k = 3
    starts = pick_starts(grid, k, rng)
    victims = set(rng.sample(range(k), rng.randint(1, k - 1)))
    # Sub-cells entered (start included) before the kill: past its start cell, so that it
    # owns a cell to take over, and well before it could be done.
    due = {v: rng.randint(8, 14) for v in sorted(victims)}
    fleet = LocalFleet(world, starts, router, bus.mission, tmp_path)
    fail_when(bus, "cover", due, fleet.kill)
    heard = Heard()
    await listen(bus, heard)
    try:
        fleet.start("ormstc", 0, *AGENT_ARGS)
        await fleet.finish(set(range(k)) - victims, TIMEOUT)
        assert not due, f"robots {sorted(due)} never reached their kill point"
        await through_router(bus, router)  # the last published tree edges
        state = await world_state(bus)
        bodies = [(t.pose[0], t.pose[1]) for t in state.robots if t.robot in victims]
        check_ormstc(world_visits(state), grid, starts, heard, victims, bodies)
    finally:
        fleet.stop()


# ---- through mstc up and mstc kill ------------------------------------------------------


def up_argv(world: Path, starts: Sequence[SubCell], algo: str, router: str, mission: str,
            run_dir: Path, time_scale: float, *extra: str) -> list[str]:
    return mstc("up", "-n", str(len(starts)), "--world", str(world), "--algo", algo,
                "--starts", ";".join(f"{r},{c}" for r, c in starts),
                "--time-scale", str(time_scale), "--connect", router, "--mission", mission,
                "--run-dir", str(run_dir), *UP_ARGS,
                *(TAKEOVER if algorithm(algo).family is Family.OFFLINE else ()), *extra)


def start_up(argv: list[str]) -> subprocess.Popen[str]:
    return subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


async def finish_up(proc: subprocess.Popen[str], heard: Heard,
                    run_dir: Path) -> tuple[int, str]:
    """`mstc up`'s exit code and output, once the test's session has heard as many body moves
    as the launcher's summary counts (ground truth still in flight when the launcher exits);
    at most 5 s more, after which the checks see what was heard."""
    out, err = await asyncio.to_thread(proc.communicate, timeout=2 * TIMEOUT)
    summary = run_dir / "summary.json"
    if summary.exists():
        total = json.loads(summary.read_text()).get("total_moves", 0)
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(5.0):
                while sum(max(len(w) - 1, 0) for w in heard.walks.values()) < total:
                    await asyncio.sleep(0.02)
    return proc.returncode, out + err


def summary_of(run_dir: Path, grid: OccupancyGrid,
               starts: Sequence[SubCell]) -> dict[str, Any]:
    summary: dict[str, Any] = json.loads((run_dir / "summary.json").read_text())
    assert summary["complete"] is True
    assert summary["covered"] == summary["reachable"] == int(reachable(grid, starts).sum())
    return summary


@pytest.mark.slow
@pytest.mark.parametrize("seed", [51])
async def test_up_ormstc_with_a_robot_killed_mid_mission(bus: Bus, router: str,
                                                         tmp_path: Path, seed: int) -> None:
    world = write_room(tmp_path, ROOM)
    grid = resolve_world(str(world))
    rng = random.Random(seed)
    starts = pick_starts(grid, 3, rng)
    victim, percent = rng.randrange(3), rng.randint(20, 40)
    heard = Heard()
    await listen(bus, heard)
    proc = start_up(up_argv(world, starts, "ormstc", router, bus.mission, tmp_path / "run", 0,
                            "--kill", f"{victim}@progress={percent}"))
    try:
        code, output = await finish_up(proc, heard, tmp_path / "run")
    finally:
        stop_processes([proc])
    assert code == 0, output
    summary = summary_of(tmp_path / "run", grid, starts)
    assert [lost["robot"] for lost in summary["robots_lost"]] == [victim]
    # simhw held the world at the order's coverage until the launcher had killed the agent
    held = covered_for(float(percent), summary["reachable"])
    log = (tmp_path / "run" / "logs" / "simhw.log").read_text()
    assert f"every body held at {held} covered sub-cells" in log, log
    said = f"{100 * held / summary['reachable']:.1f}"
    assert f"SIGKILL agent {victim} at {percent} %: done (coverage {said} %)" in output, output
    visits = np.zeros(grid.shape, dtype=np.int64)
    for walk in heard.walks.values():
        for r, c in walk:
            visits[r, c] += 1
    check_ormstc(visits, grid, starts, heard, {victim}, [heard.walks[victim][-1]])


def check_body_failure(heard: Heard, case: OfflineCase, grid: OccupancyGrid, victim: int,
                       run_dir: Path, code: int, output: str) -> None:
    """``victim``'s body failed while it still had work: the launcher lost it, a survivor
    walked the rest of its section, and the mission completed as the lockstep semantics
    say."""
    assert code == 0, output
    summary = summary_of(run_dir, grid, case.starts)
    lost = {item["robot"]: item["why"] for item in summary["robots_lost"]}
    assert list(lost) == [victim], lost
    assert "body failed" in lost[victim] or "exited with code 1" in lost[victim], lost
    entered = len(heard.walks[victim]) - 1
    assert entered < case.steps[victim], \
        f"robot {victim} walked {entered} of {case.steps[victim]} moves: not mid-section"
    check_offline(heard, case, grid, {victim})


@pytest.mark.slow
@pytest.mark.parametrize("seed", [10])  # nb; robot 2 plans 45 moves, the others 6-44
async def test_up_kill_hw_at_a_percentage_fails_a_robot_mid_section(
        bus: Bus, router: str, tmp_path: Path, seed: int) -> None:
    world = write_room(tmp_path, ROOM)
    grid = resolve_world(str(world))
    case = OfflineCase.draw(random.Random(seed), grid)
    victim = case.long_sections[0]
    heard = Heard()
    await listen(bus, heard)
    proc = start_up(up_argv(world, case.starts, case.algo, router, bus.mission,
                            tmp_path / "run", 60, "--kill-hw", f"{victim}@progress=30"))
    try:
        code, output = await finish_up(proc, heard, tmp_path / "run")
    finally:
        stop_processes([proc])
    assert f"fail body of {victim} at 30 %: done" in output, output
    check_body_failure(heard, case, grid, victim, tmp_path / "run", code, output)
    # simhw carried it out itself, right after the step that brought the coverage to 30 %
    reachable = json.loads((tmp_path / "run" / "summary.json").read_text())["reachable"]
    log = (tmp_path / "run" / "logs" / "simhw.log").read_text()
    fired = re.search(rf"robot {victim}'s body failed as armed, at (\d+) covered", log)
    assert fired is not None, log
    assert int(fired[1]) == covered_for(30.0, reachable)
    assert 100 * (int(fired[1]) - 1) / reachable < 30 <= 100 * int(fired[1]) / reachable


@pytest.mark.slow
async def test_mstc_kill_hw_fails_a_running_robot_mid_section(bus: Bus, router: str,
                                                              tmp_path: Path) -> None:
    world = write_room(tmp_path, ROOM)
    grid = resolve_world(str(world))
    case = OfflineCase.draw(random.Random(13), grid)  # bt; robot 0 plans 52 moves
    victim = case.long_sections[0]
    heard = Heard()
    await listen(bus, heard)
    run_dir = tmp_path / "run"
    proc = start_up(up_argv(world, case.starts, case.algo, router, bus.mission, run_dir, 30))
    try:
        # A few moves in: `mstc kill` itself takes a second or two to start and connect.
        async with asyncio.timeout(TIMEOUT):
            while len(heard.walks[victim]) <= 3:
                assert proc.poll() is None, proc.communicate()
                await asyncio.sleep(0.05)
        kill = await asyncio.to_thread(
            subprocess.run, mstc("kill", str(victim), "--hw", "--run-dir", str(run_dir)),
            capture_output=True, text=True, timeout=TIMEOUT)
        assert kill.returncode == 0, kill.stderr
        assert f"mission {bus.mission}" in kill.stdout, kill.stdout
        code, output = await finish_up(proc, heard, run_dir)
    finally:
        stop_processes([proc])
    check_body_failure(heard, case, grid, victim, run_dir, code, output)
    # told as what happened, not as a crash with a log dump
    assert f"robot {victim} lost: body failed in simhw by an operator" in output, output
    assert "agent exited with code" not in output and "last lines of" not in output, output
