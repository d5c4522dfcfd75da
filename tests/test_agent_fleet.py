"""The offline-MSTC fleet end to end: a router, ``mstc simhw`` and k ``mstc agent`` processes.

Oracles: the pure planner (the plan the agents must follow, computed here independently),
simhw's ground truth (every sub-cell each body entered, in order) and planner.offline's
lockstep semantics for the robots killed with SIGKILL.
"""

from __future__ import annotations

import asyncio
import itertools
import random
import signal
import subprocess
import time
from collections import defaultdict
from collections.abc import AsyncIterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fleet_helpers import all_heard, mission_bus, mstc, start_simhw, stop_processes, write_room
from takeover_oracle import fit_failures, ordered_walks, run_plan
from waiting import wait_until

from agent.offline.plan import compute_plan
from bus import keys
from bus.bridge import BoundedFifo, Bus, Received
from bus.codec import encode
from bus.config import ConnectionSettings
from bus.messages import (
    AgentState,
    CoverEvent,
    DeathNotice,
    MissionStatus,
    Progress,
    RobotEvent,
    RobotStatus,
    WorldState,
    world_visits,
)
from planner.digest import plan_digest
from planner.grid import work_area
from planner.maps import resolve_world
from planner.offline.lockstep import simulate_failures
from planner.types import Plan, SubCell

pytestmark = pytest.mark.integration

_missions = itertools.count()
K = 4
# A 12 x 12 room with a pillar: n = 136 sub-cells, small enough for seconds-long runs.
ROOM = ["............"] * 5 + ["....##......"] * 2 + ["............"] * 5
STARTS: tuple[SubCell, ...] = ((0, 0), (2, 6), (8, 3), (10, 10))
PROCESS_TIMEOUT = 60.0


@dataclass
class Fleet:
    """Running processes of one mission and what the test heard on the bus."""

    world: Path
    algo: str
    mission: str
    router: str
    plan: Plan
    simhw: subprocess.Popen[str] | None = None
    agents: dict[int, subprocess.Popen[str]] = field(default_factory=dict)
    walks: dict[int, list[SubCell]] = field(default_factory=lambda: defaultdict(list))
    reported: dict[int, int] = field(default_factory=lambda: defaultdict(int))
    events: list[RobotEvent] = field(default_factory=list)
    heard_at: dict[tuple[str, int | None], float] = field(default_factory=dict)
    # (taker, dead) -> the moves the taker had reported when its takeover decision was heard
    decided_after: dict[tuple[int, int | None], int] = field(default_factory=dict)
    deaths: list[DeathNotice] = field(default_factory=list)
    missions: list[MissionStatus] = field(default_factory=list)

    def agent_command(self, robot: int, *extra: str) -> list[str]:
        return mstc("agent", "--id", str(robot), "--algo", self.algo, "--world", str(self.world),
                    "--robots", str(K), "--connect", self.router, "--mission", self.mission,
                    # SIGKILLs are seen through the liveliness token within ~0.1 s and hangs
                    # through the token's lease; a long heartbeat timeout only keeps a loaded
                    # test machine from declaring a slow but live agent dead.
                    "--start-timeout", "30", "--dead-after", "10", "--linger", "0.5",
                    # the papers' takeover semantics are what these tests check
                    "--recovery", "takeover", *extra)

    def start(self, time_scale: float, *agent_args: str) -> None:
        self.simhw = start_simhw(self.world, STARTS, self.router, self.mission, time_scale)
        for robot in range(K):
            self.agents[robot] = subprocess.Popen(
                self.agent_command(robot, *agent_args), stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    async def start_driving(self, time_scale: float) -> None:
        """Start the fleet and wait until every agent drives its plan."""
        self.start(time_scale)
        for robot in range(K):
            await self.wait_line(robot, "driving")

    async def wait_line(self, robot: int, text: str, timeout: float = PROCESS_TIMEOUT) -> None:
        """Read the agent's stdout until a line containing ``text``."""
        stream = self.agents[robot].stdout
        assert stream is not None
        async with asyncio.timeout(timeout):
            while True:
                line = await asyncio.to_thread(stream.readline)
                assert line, f"agent {robot} exited before saying {text!r}"
                if text in line:
                    return

    async def wait_exit(self, robot: int, timeout: float = PROCESS_TIMEOUT) -> int:
        proc = self.agents[robot]
        code = await asyncio.to_thread(proc.wait, timeout)
        return int(code)

    def stop_all(self) -> None:
        stop_processes([*self.agents.values(), *([self.simhw] if self.simhw else [])])

    def stderr_of(self, robot: int) -> str:
        stream = self.agents[robot].stderr
        return stream.read() if stream is not None and self.agents[robot].poll() is not None \
            else ""


def expected_plan(world: Path, algo: str, tree: str = "dfs") -> Plan:
    return compute_plan(resolve_world(str(world)), STARTS, algo, tree, 0)


@pytest.fixture
def world(tmp_path: Path) -> Path:
    return write_room(tmp_path, ROOM)


async def _listen(fleet: Fleet, bus: Bus) -> None:
    m = bus.mission

    def on_cover(key: str, msg: CoverEvent) -> None:
        fleet.walks[msg.robot].append(tuple(msg.cell))  # type: ignore[arg-type]

    def on_progress(key: str, msg: Progress) -> None:
        fleet.reported[msg.robot] = max(fleet.reported[msg.robot], msg.seq)

    bus.subscribe(keys.all_sim_covers(m), CoverEvent, on_cover, BoundedFifo(65536))
    bus.subscribe(keys.all_progress(m), Progress, on_progress, BoundedFifo(65536))
    def on_event(key: str, event: RobotEvent) -> None:
        fleet.events.append(event)
        fleet.heard_at.setdefault((event.kind, event.subject), time.monotonic())
        if event.kind == "takeover_started":
            fleet.decided_after[(event.robot, event.subject)] = fleet.reported[event.robot]

    bus.subscribe(keys.all_events(m), RobotEvent, on_event, BoundedFifo(65536))
    def on_death(key: str, notice: DeathNotice) -> None:
        fleet.deaths.append(notice)
        fleet.heard_at.setdefault(("death", notice.robot), time.monotonic())

    bus.subscribe(keys.all_deaths(m), DeathNotice, on_death, BoundedFifo(65536))
    bus.subscribe(keys.mission_status(m), MissionStatus,
                  lambda k, s: fleet.missions.append(s), BoundedFifo(65536))
    # Let the subscriptions reach the router before anything is published.
    await asyncio.sleep(0.3)


@pytest.fixture
async def fleet_bus(router: str) -> AsyncIterator[Bus]:
    async with mission_bus(router, f"agent{next(_missions)}") as bus:
        yield bus


async def make_fleet(bus: Bus, router: str, world: Path, algo: str,
                     tree: str = "dfs") -> Fleet:
    fleet = Fleet(world=world, algo=algo, mission=bus.mission, router=router,
                  plan=expected_plan(world, algo, tree))
    await _listen(fleet, bus)
    return fleet


def assert_walks_follow(fleet: Fleet, expected: Sequence[Sequence[SubCell]],
                        dead: set[int]) -> None:
    """Ground-truth walks equal the expected ones; a killed robot may have made up to two
    moves more than it reported. Killed while a forward command was in flight, its body
    still completes the motion and nobody hears of it (the taker covers that sub-cell
    again). And the progress report of the move before may be lost with it: progress is a
    STREAM message (DATA priority, bus.qos) and the motion command a CONTROL one
    (INTERACTIVE_LOW), so the command can leave the process first, and SIGKILL then drops
    the report still queued (seen once in four full runs: 7 moves reported, 9 made)."""
    for robot, want in enumerate(expected):
        got = fleet.walks[robot]
        if robot in dead and len(want) < len(got) <= len(want) + 2:
            got = got[:len(want)]
        assert got == list(want), f"robot {robot}: ground truth walk differs from semantics"


def area_mask(world: Path) -> np.ndarray:
    return work_area(resolve_world(str(world)), STARTS).sub_cells


def covered_mask(fleet: Fleet, shape: tuple[int, int]) -> np.ndarray:
    mask = np.zeros(shape, dtype=bool)
    for walk in fleet.walks.values():
        for r, c in walk:
            mask[r, c] = True
    return mask


@pytest.mark.parametrize(("algo", "tree"), [
    pytest.param("nb", "dfs", marks=pytest.mark.slow),
    pytest.param("bt", "dfs", marks=pytest.mark.slow),
    pytest.param("opt", "dfs", marks=pytest.mark.slow),
    # A paper tree (Create Tree needs the starts, which each agent learns by gathering).
    pytest.param("opt", "createtree", marks=pytest.mark.slow)])
async def test_fleet_follows_the_plan_and_covers_everything(
        fleet_bus: Bus, router: str, world: Path, algo: str, tree: str) -> None:
    fleet = await make_fleet(fleet_bus, router, world, algo, tree)
    if tree != "dfs":  # else the test could not tell whether --tree reached the agents
        assert plan_digest(fleet.plan) != plan_digest(expected_plan(world, algo))
    try:
        fleet.start(0, "--tree", tree)
        codes = [await fleet.wait_exit(robot) for robot in range(K)]
        assert codes == [0] * K, [fleet.stderr_of(r) for r in range(K)]
        await all_heard(fleet_bus, fleet.walks)
        plan = fleet.plan
        assert_walks_follow(fleet, [rp.path for rp in plan.robots], dead=set())
        moves = [len(fleet.walks[r]) - 1 for r in range(K)]
        assert max(moves) == plan.makespan
        area = area_mask(world)
        assert np.array_equal(covered_mask(fleet, area.shape), area)
        assert any(s.state == "complete" for s in fleet.missions)
        completed = {e.robot for e in fleet.events if e.kind == "completed"}
        assert completed == set(range(K))
    finally:
        fleet.stop_all()


def lockstep_failures(plan: Plan, moves: dict[int, int]) -> dict[int, int]:
    """Failure times under which planner.offline gives each dead robot ``moves`` moves.

    A robot that died while still on its own walk died at time = its moves; one that died
    later (waiting or taking over) is fitted by search, earlier deaths first."""
    failures: dict[int, int] = {}
    horizon = 4 * plan.n
    for robot in sorted(moves, key=moves.__getitem__):
        for when in range(moves[robot], horizon):
            result = simulate_failures(plan, {**failures, robot: when}, recovery="takeover")
            if len(result.walks[robot]) - 1 == moves[robot]:
                failures[robot] = when
                break
        else:
            raise AssertionError(f"no failure time gives robot {robot} {moves[robot]} moves")
    return failures


@pytest.mark.parametrize(("seed", "algo", "count"), [
    pytest.param(1, "nb", K - 1, marks=pytest.mark.slow),
    pytest.param(2, "bt", 2, marks=pytest.mark.slow),
    pytest.param(3, "opt", 1, marks=pytest.mark.slow)])
async def test_fleet_survives_sigkills_as_the_takeover_semantics_say(
        fleet_bus: Bus, router: str, world: Path, seed: int, algo: str, count: int) -> None:
    rng = random.Random(seed)
    victims = rng.sample(range(K), count)
    fleet = await make_fleet(fleet_bus, router, world, algo)
    try:
        await fleet.start_driving(60)
        killed_at = {}
        for robot in victims:
            await asyncio.sleep(rng.uniform(0.0, 1.0))
            fleet.agents[robot].send_signal(signal.SIGKILL)
            killed_at[robot] = time.monotonic()
        survivors = [r for r in range(K) if r not in victims]
        codes = [await fleet.wait_exit(robot) for robot in survivors]
        assert codes == [0] * len(survivors), [fleet.stderr_of(r) for r in survivors]
        await all_heard(fleet_bus, fleet.walks)
        moves = {robot: fleet.reported[robot] for robot in victims}
        walked = {(e.robot, e.subject) for e in fleet.events
                  if e.kind == "takeover_started" and e.detail.startswith("walking")}

        # Informative only (no timing assertions): SIGKILL -> death notice, and -> the
        # takeover decision (which waits until the taker has finished its own walk).
        def after_kill(kind: str) -> dict[int, float]:
            return {r: round(fleet.heard_at[(kind, r)] - at, 3)
                    for r, at in killed_at.items() if (kind, r) in fleet.heard_at}

        decided = [(e.robot, e.subject, e.detail) for e in fleet.events
                   if e.kind == "takeover_started"]
        print(f"{algo}: killed {moves} (reported moves), kill -> death notice "
              f"{after_kill('death')} s, kill -> takeover {after_kill('takeover_started')} s, "
              f"takeovers {decided}, "
              f"moves {[len(fleet.walks[r]) - 1 for r in range(K)]}, "
              f"plan {[rp.steps for rp in fleet.plan.robots]}")
        area = area_mask(world)
        assert np.array_equal(covered_mask(fleet, area.shape), area)
        semantics = simulate_failures(fleet.plan, lockstep_failures(fleet.plan, moves),
                                      recovery="takeover")
        assert semantics.complete
        assert_walks_follow(fleet, semantics.walks, dead=set(victims))
        # Takeovers that found nothing left depend on timing; those that walked do not —
        # except a victim's takeover decided after its last reported move (it was killed
        # before reporting a step of it, or with the first step in flight): the semantics
        # place its death at that move, before the decision.
        in_flight = {(taker, dead) for taker, dead in walked
                     if taker in victims and fleet.decided_after[(taker, dead)] >= moves[taker]}
        assert walked - in_flight <= {(t.taker, t.dead) for t in semantics.takeovers}
        # The same against the independent oracle (not the agents' own state machine).
        independent = run_plan(fleet.plan, fit_failures(fleet.plan, moves))
        assert independent.complete
        assert_walks_follow(fleet, ordered_walks(fleet.plan, independent), dead=set(victims))
        assert walked - in_flight <= {(taker, dead) for taker, dead, _ in independent.takeovers}
    finally:
        fleet.stop_all()


def garbage(bus: Bus) -> None:
    """Publish malformed and well-formed-but-wrong messages on the agents' keys."""
    m = bus.mission
    raw = [keys.progress(m, 1), keys.status(m, 2), keys.heartbeat(m, 3), keys.death(m, 0),
           keys.mission_status(m)]
    for key in raw:
        bus.session.put(key, b"\x00\xffnot msgpack")
        bus.session.put(key, encode(RobotEvent(1, 1, "started")))  # the wrong kind
    wrong = [
        (keys.progress(m, 9), Progress(9, 1, 1, (0, 1), 0.0)),       # not in the fleet
        (keys.progress(m, 2), Progress(1, 1, 1, (0, 1), 0.0)),       # key names robot 2
        (keys.progress(m, 1), Progress(1, 1, 1, (99, 99), 0.0)),     # off the cycle
        (keys.status(m, 7), RobotStatus(7, 1, (0, 0), "nb", "x", "covering")),
    ]
    for key, msg in wrong:
        bus.publish(key, msg)


@pytest.mark.slow
async def test_garbage_is_counted_and_sigterm_leaves_cleanly(
        fleet_bus: Bus, router: str, world: Path) -> None:
    fleet = await make_fleet(fleet_bus, router, world, "bt")
    try:
        await fleet.start_driving(20)
        garbage(fleet_bus)

        # At least what garbage() sent; the mission key keeps only the newest message, so
        # one of its two may be superseded. Progress not in the fleet or off the cycle fails
        # the agent's checks; progress on a key naming another robot, the bus's check.
        least = {**{f"{kind}.decode": 2 for kind in ("progress", "status", "hb", "death")},
                 "mission.decode": 1, "progress.invalid": 2, "progress.robot_mismatch": 1,
                 "status.invalid": 1}

        async def drops_of_agent_0() -> dict[str, int]:
            replies: list[Received[Any]] = await fleet_bus.query(
                keys.state(fleet_bus.mission, 0), None,
                (AgentState, RobotStatus, DeathNotice, MissionStatus), timeout=2.0)
            states = [rx.msg for rx in replies if isinstance(rx.msg, AgentState)]
            assert states, "agent 0 did not answer its state query"
            return dict(states[0].drops)

        async def all_counted() -> bool:
            drops = await drops_of_agent_0()
            return all(drops.get(key, 0) >= n for key, n in least.items())

        await wait_until(all_counted, 10.0, "agent 0 to count the garbage")
        drops = await drops_of_agent_0()
        for key, n in least.items():
            assert drops.get(key, 0) >= n, (key, drops)
        # Robot 1 is asked to leave mid-mission: exit 0, "leaving" said, section taken over.
        fleet.agents[1].send_signal(signal.SIGTERM)
        assert await fleet.wait_exit(1, timeout=10) == 0
        codes = [await fleet.wait_exit(robot) for robot in (0, 2, 3)]
        assert codes == [0, 0, 0], [fleet.stderr_of(r) for r in (0, 2, 3)]
        await asyncio.sleep(0.2)
        assert any(e.robot == 1 and e.kind == "leaving" for e in fleet.events)
        assert any(d.robot == 1 and d.reason == "leaving" for d in fleet.deaths)
        assert any(e.kind == "takeover_started" and e.subject == 1 for e in fleet.events)
        area = area_mask(world)
        assert np.array_equal(covered_mask(fleet, area.shape), area)
    finally:
        fleet.stop_all()


def test_every_agent_computes_the_same_digest(world: Path) -> None:
    one = plan_digest(expected_plan(world, "opt"))
    assert one == plan_digest(expected_plan(world, "opt"))
    assert one != plan_digest(expected_plan(world, "nb"))


@pytest.mark.slow
async def test_a_hung_robot_declared_dead_is_fenced_when_it_wakes(
        fleet_bus: Bus, router: str, world: Path) -> None:
    fleet = await make_fleet(fleet_bus, router, world, "nb")
    try:
        await fleet.start_driving(10)
        fleet.agents[2].send_signal(signal.SIGSTOP)
        async with asyncio.timeout(PROCESS_TIMEOUT):
            while not any(e.kind == "takeover_started" and e.subject == 2
                          for e in fleet.events):
                await asyncio.sleep(0.05)
        frozen_walk = list(fleet.walks[2])
        fleet.agents[2].send_signal(signal.SIGCONT)
        assert await fleet.wait_exit(2) == 4, fleet.stderr_of(2)
        codes = [await fleet.wait_exit(robot) for robot in (0, 1, 3)]
        assert codes == [0, 0, 0]
        async with asyncio.timeout(10.0):  # its "fenced" event may still be on its way
            while not any(e.robot == 2 and e.kind == "fenced" for e in fleet.events):
                await asyncio.sleep(0.05)
        assert fleet.walks[2] == frozen_walk, "a fenced robot moved after its death"
        area = area_mask(world)
        assert np.array_equal(covered_mask(fleet, area.shape), area)
    finally:
        fleet.stop_all()


@pytest.mark.slow
async def test_a_router_restart_mid_mission_does_not_lose_the_mission(
        world: Path, free_port: int) -> None:
    from bus.router import start_router_process, stop_process

    endpoint = f"tcp/127.0.0.1:{free_port}"
    router = start_router_process(endpoint)
    try:
        async with Bus.connect(ConnectionSettings(connect=(endpoint,),
                                                  mission="restart")) as bus:
            fleet = await make_fleet(bus, endpoint, world, "bt")
            try:
                await fleet.start_driving(10)
                stop_process(router)
                await asyncio.sleep(1.0)
                router = start_router_process(endpoint)
                codes = [await fleet.wait_exit(robot) for robot in range(K)]
                assert codes == [0] * K, [fleet.stderr_of(r) for r in range(K)]
                # The test's own subscriptions missed the outage: ask simhw for the truth.
                truth = await bus.query(keys.world(bus.mission), None, WorldState, timeout=5)
                assert truth, "simhw did not answer"
                area = area_mask(world)
                assert np.array_equal(world_visits(truth[0].msg) > 0, area)
            finally:
                fleet.stop_all()
    finally:
        stop_process(router)


@pytest.mark.slow
async def test_missing_robots_and_digest_mismatch_stop_the_mission_with_clear_errors(
        fleet_bus: Bus, router: str, world: Path) -> None:
    assert plan_digest(compute_plan(resolve_world(str(world)), STARTS[:2], "nb", "dfs", 0)) \
        != plan_digest(compute_plan(resolve_world(str(world)), STARTS[:2], "nb", "bfs", 0))
    m = fleet_bus.mission
    await _listen(fleet := Fleet(world, "nb", m, router, expected_plan(world, "nb")), fleet_bus)
    simhw = start_simhw(world, STARTS[:2], router, m, 0, stdout=subprocess.DEVNULL,
                        stderr=subprocess.DEVNULL)

    def agent(robot: int, *extra: str) -> subprocess.Popen[str]:
        return subprocess.Popen(
            mstc("agent", "--id", str(robot), "--algo", "nb", "--world", str(world),
                 "--robots", "2", "--connect", router, "--mission", m, *extra),
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
            text=True)

    try:
        # Robot 1 never comes: robot 0 names it and gives up.
        alone = agent(0, "--start-timeout", "3")
        _, err = await asyncio.to_thread(alone.communicate, timeout=PROCESS_TIMEOUT)
        assert alone.returncode == 3, err
        assert "robots [1] did not announce their start" in err
        assert len(err.strip().splitlines()) == 1, "one readable line, no traceback"
        # Two robots built different trees: both stop, naming each other's digest. Robot 0
        # starts a new life (its first one left, which simhw fenced).
        pair = [agent(0, "--tree", "dfs", "--incarnation", "2"), agent(1, "--tree", "bfs")]
        errors = [(await asyncio.to_thread(p.communicate, timeout=PROCESS_TIMEOUT))[1]
                  for p in pair]
        assert [p.returncode for p in pair] == [3, 3], errors
        assert all("plan digest mismatch" in e for e in errors), errors
        await asyncio.sleep(0.2)
        assert any(s.state == "failed" and "digest" in s.message for s in fleet.missions)
    finally:
        simhw.send_signal(signal.SIGTERM)
        simhw.wait(10)


def test_user_mistakes_are_one_line_errors(capsys: pytest.CaptureFixture[str]) -> None:
    from deploy.cli import main

    assert main(["agent", "--id", "0", "--algo", "nb", "--robots", "2",
                 "--world", "no-such-world"]) == 2
    assert main(["agent", "--id", "3", "--algo", "nb", "--robots", "2",
                 "--world", "example"]) == 2
    assert main(["agent", "--id", "0", "--algo", "bt", "--robots", "2"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3 and all("error" in line for line in lines), lines
