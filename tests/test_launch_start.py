"""The launcher's paced start-up (deploy/launch.py) without processes: what it says while a
crowded fleet starts, and that it starts each agent only when the last ones were heard."""

from __future__ import annotations

import asyncio
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

from deploy import launch
from deploy.fleet import RunDir
from deploy.launch import Launcher
from deploy.settings import MissionSetup, UpSettings
from planner.maps import resolve_world


@dataclass
class FakeChild:
    name: str
    robot: int | None
    returncode: int | None = None


@dataclass
class Lines:
    events: list[str] = field(default_factory=list)

    def event(self, text: str) -> None:
        self.events.append(text)

    def update(self, tracker: object, elapsed: float) -> None:
        return None

    def close(self) -> None:
        return None


def _launcher(tmp_path: Path, k: int, booting: int) -> tuple[Launcher, Lines]:
    grid = resolve_world("office")
    setup = MissionSetup(world="office", cell_size=None, grid=grid,
                         starts=tuple((2 * i, 2) for i in range(k)), algo="opt", tree="dfs",
                         seed=0, time_scale=0.0, reachable=np.ones((4, 4), dtype=bool),
                         planned_makespan=1)
    settings = UpSettings(robots=k, world="office", booting=booting, run_dir=tmp_path)
    lines = Lines()
    return Launcher(setup, settings, "tcp/127.0.0.1:1", RunDir(tmp_path).create(), lines), lines


@pytest.mark.parametrize("booting", [0, 3])
def test_a_paced_start_says_how_far_it_is_and_waits_to_hear_the_agents(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, booting: int) -> None:
    launcher, lines = _launcher(tmp_path, 10, booting)
    most_booting = 0

    def spawn(name: str, role: str, argv: list[str], robot: int | None = None) -> FakeChild:
        nonlocal most_booting
        child = FakeChild(name, robot)
        if role == "agent":
            launcher.agents.append(child)  # type: ignore[arg-type]
            most_booting = max(most_booting, launcher._booting())
            launcher.agents.pop()
        return child

    async def hear_them() -> None:  # the agents announce themselves one by one
        while len(launcher.tracker.heard) < 10:
            await asyncio.sleep(0.01)
            started = {c.robot for c in launcher.agents if c.robot is not None}
            launcher.tracker.heard.update(sorted(started - launcher.tracker.heard)[:1])

    async def ready(child: object, mark: str, timeout: float) -> None:
        return None

    async def main() -> None:
        async with asyncio.TaskGroup() as group:
            group.create_task(hear_them())
            await launcher.start_fleet()
            launcher.tracker.heard.update(range(10))

    monkeypatch.setattr(launcher, "_spawn", spawn)
    monkeypatch.setattr(launcher, "_wait_ready", ready)
    monkeypatch.setattr(launcher, "write_fleet", lambda: None)
    monkeypatch.setattr(launch, "START_LINE_S", 0.0)  # a line at every agent
    asyncio.run(main())
    assert len(launcher.agents) == 10
    assert lines.events[-1].startswith("fleet up: mission")
    progress = [e for e in lines.events if "starting agents" in e]
    if booting:
        assert lines.events[0].startswith("fleet starting:") and "3 at a time" in lines.events[0]
        assert most_booting <= booting  # never more started and unheard than the pace allows
        found = [re.search(r"(\d+)/10 started, (\d+) heard", e) for e in progress]
        counts = [(int(m.group(1)), int(m.group(2))) for m in found if m is not None]
        assert len(counts) == len(progress)
        assert [started for started, _ in counts] == list(range(10))
        assert all(started - heard <= booting for started, heard in counts)
    else:  # no pace: every agent is started before any is heard
        assert not lines.events[0].startswith("fleet starting:")
        assert most_booting == 10
