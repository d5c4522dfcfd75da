"""The launcher's verdict once every agent has stopped (deploy/launch.py), without processes:
what it heard may lag what simhw saw, so simhw's world decides whether the area was covered."""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from bus.inbox import Received
from bus.messages import CoverEvent, RobotTruth, WorldState, make_world_state
from deploy.fleet import RunDir
from deploy.launch import AGENT_DONE, Launcher, Outcome
from deploy.settings import MissionSetup, UpSettings
from planner.maps import resolve_world

SHAPE = (4, 4)


@dataclass
class StoppedAgent:
    name: str
    robot: int
    returncode: int | None = AGENT_DONE


class Silent:
    def event(self, text: str) -> None:
        return None

    def update(self, tracker: object, elapsed: float) -> None:
        return None

    def close(self) -> None:
        return None


class World:
    """A bus whose only queryable is simhw's world, covered up to ``covered`` sub-cells."""

    def __init__(self, covered: int) -> None:
        visits = np.zeros(SHAPE, dtype=np.int64)
        visits.ravel()[:covered] = 1
        self.state = make_world_state("four", np.ones(SHAPE, dtype=bool), visits,
                                      (RobotTruth(robot=0, pose=(0, 0, 0), alive=False,
                                                  frozen=False, failed=False,
                                                  covered=covered),), 1.0, 0.0)
        self.queries = 0

    async def query(self, key: str, request: object, expected: object, *,
                    timeout: float = 2.0) -> list[Received[WorldState]]:
        self.queries += 1
        return [Received(key, self.state)]


def _verdict(tmp_path: Path, heard: int, world: World) -> Outcome:
    setup = MissionSetup(world="office", cell_size=None, grid=resolve_world("office"),
                         starts=((0, 0),), algo="opt", tree="dfs", seed=0, time_scale=0.0,
                         reachable=np.ones(SHAPE, dtype=bool), planned_makespan=1)
    settings = UpSettings(robots=1, world="office", run_dir=tmp_path, linger=0.0,
                          mission="verdict")
    launcher = Launcher(setup, settings, "tcp/127.0.0.1:1", RunDir(tmp_path).create(),
                        Silent())
    launcher.agents.append(StoppedAgent("agent-0", 0))  # type: ignore[arg-type]
    for i in range(heard):  # the covers heard so far
        launcher.tracker.on_cover(CoverEvent(robot=0, cell=divmod(i, SHAPE[1]), sim_time=0.0,
                                             visits=1), 0.0)
    assert launcher.tracker.covered == heard
    launcher.tracker.heard.add(0)  # the agent announced itself: the mission started
    return asyncio.run(asyncio.wait_for(launcher.watch(world), 10))  # type: ignore[arg-type]


def test_a_mission_simhw_saw_covered_is_complete_though_its_last_covers_were_not_heard(
        tmp_path: Path) -> None:
    world = World(covered=16)
    outcome = _verdict(tmp_path, heard=5, world=world)
    assert outcome.code == 0, outcome.message
    assert outcome.message == "every reachable free sub-cell was covered"
    assert world.queries >= 1


@pytest.mark.parametrize("heard", [0, 5])
def test_a_mission_simhw_saw_uncovered_fails_with_what_is_left(tmp_path: Path,
                                                               heard: int) -> None:
    outcome = _verdict(tmp_path, heard=heard, world=World(covered=12))
    assert outcome.code == 1
    # simhw's count, not the launcher's: 4 of 16 left, whatever was heard before
    assert outcome.message.startswith("every agent has stopped; 4 reachable sub-cells "
                                      "uncovered"), outcome.message


def _stall(tmp_path: Path, plan_allowance: float, moved: bool) -> tuple[Outcome, float]:
    """A running agent that covers nothing: (the outcome, seconds it took)."""
    setup = MissionSetup(world="office", cell_size=None, grid=resolve_world("office"),
                         starts=((0, 0),), algo="opt", tree="dfs", seed=0, time_scale=0.0,
                         reachable=np.ones(SHAPE, dtype=bool), planned_makespan=1)
    settings = UpSettings(robots=1, world="office", run_dir=tmp_path, linger=0.0,
                          mission="stall", stall_timeout=0.3, plan_allowance=plan_allowance)
    launcher = Launcher(setup, settings, "tcp/127.0.0.1:1", RunDir(tmp_path).create(),
                        Silent())
    launcher.agents.append(StoppedAgent("agent-0", 0, returncode=None))  # type: ignore
    launcher.tracker.heard.add(0)

    async def watched() -> Outcome:
        task = asyncio.create_task(launcher.watch(World(covered=0)))  # type: ignore[arg-type]
        if moved:  # the first move once the mission started: planning is over
            await asyncio.sleep(0.05)
            launcher.tracker.on_cover(CoverEvent(robot=0, cell=(0, 0), sim_time=0.0, visits=1),
                                      asyncio.get_running_loop().time())
        return await task

    loop = asyncio.new_event_loop()
    try:
        began = loop.time()
        outcome = loop.run_until_complete(asyncio.wait_for(watched(), 10))
        return outcome, loop.time() - began
    finally:
        loop.close()


def test_the_first_plan_has_its_allowance_before_the_first_move_only(tmp_path: Path) -> None:
    """rooms:120x120:1 with 20 balanced robots planned for 30 s or more and the default
    stall timeout failed it before a move: until the first move it allows for the plan."""
    outcome, took = _stall(tmp_path / "a", plan_allowance=1.0, moved=False)
    assert outcome.code == 1 and "mission stalled" in outcome.message
    assert took >= 1.3  # the stall timeout and the plan's allowance
    outcome, took = _stall(tmp_path / "b", plan_allowance=0.0, moved=False)
    assert outcome.code == 1 and "mission stalled" in outcome.message and took < 1.3
    outcome, took = _stall(tmp_path / "c", plan_allowance=5.0, moved=True)
    assert outcome.code == 1 and "mission stalled" in outcome.message and took < 5.0
