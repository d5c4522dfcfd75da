"""Which mission `mstc monitor` watches when it is not told (deploy.monitor.discovery): the
live runs (run directories whose launcher runs, robots on the router), the newest chosen
and all of them listed, a newer run followed, a judged mission's robots coming back seen as
a new run."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bus import keys
from bus.messages import MissionStatus
from deploy.fleet import LAUNCHER, FleetInfo, ProcessRecord, RunDir, start_ticks
from deploy.monitor.app import NullScreen, Watcher
from deploy.monitor.discovery import LiveRun, choose, ended_run, live_runs, newer_run
from deploy.monitor.types import Record, TokenChange


def _run_dir(root: Path, name: str, mission: str, created: float, live: bool) -> Path:
    pid = os.getpid() if live else _dead_pid()
    started = start_ticks(pid) if live else 1
    rd = RunDir(root / name).create()
    rd.write_fleet(FleetInfo(mission=mission, endpoint="tcp/127.0.0.1:7447", own_router=True,
                             world="office", algo="nb", robots=3, starts=(), time_scale=1.0,
                             created=created,
                             processes=(ProcessRecord(LAUNCHER, LAUNCHER, pid, started),)))
    return rd.path


def _dead_pid() -> int:
    proc = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    return int(proc.stdout)


def test_only_runs_whose_launcher_runs_are_live_newest_first(tmp_path: Path) -> None:
    _run_dir(tmp_path, "a", "old-finished", 100.0, live=False)
    b = _run_dir(tmp_path, "b", "m1", 200.0, live=True)
    c = _run_dir(tmp_path, "c", "m2", 300.0, live=True)
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "fleet.json").write_text("{")  # being written
    runs = live_runs(tmp_path)
    assert [(r.mission, r.run_dir) for r in runs] == [("m2", c), ("m1", b)]
    assert live_runs(tmp_path / "nowhere") == []
    assert ended_run(tmp_path) is not None and ended_run(tmp_path / "nowhere") is None


def test_a_finished_run_is_not_watched(tmp_path: Path) -> None:
    """The monitor started before `mstc up` used to stay on the last finished run."""
    _run_dir(tmp_path, "a", "finished", 100.0, live=False)
    assert choose(live_runs(tmp_path)) == (None, [])


def test_several_live_missions_are_listed_and_the_newest_watched() -> None:
    one = LiveRun("m1", Path("runs/a"), 1.0, 3, "nb")
    assert choose([one]) == (one, [])
    two = LiveRun("m2", None, 0.0, 5)
    chosen, lines = choose([one, two])
    assert chosen == one
    assert lines[0] == "2 live missions:"
    assert "mission m1 (3 robots, nb; run dir runs/a)" in lines[1]
    assert "mission m2 (5 robots; on the router)" in lines[2]
    assert "--run-dir" in lines[-1] and "--mission" in lines[-1]


def test_a_newer_run_is_followed_of_the_same_mission_when_one_was_named() -> None:
    current = LiveRun("m", Path("runs/a"), 10.0)
    other = LiveRun("x", Path("runs/b"), 20.0)
    again = LiveRun("m", Path("runs/c"), 30.0)
    assert newer_run(current, [current], same_mission=False) is None
    assert newer_run(current, [other, current], same_mission=False) == other
    assert newer_run(current, [other, current], same_mission=True) is None
    assert newer_run(current, [again, other, current], same_mission=True) == again


def test_robots_coming_back_after_the_verdict_are_a_new_run() -> None:
    watcher = Watcher(NullScreen())
    token = keys.alive("m", 0, 1)
    watcher.feed([Record(0.0, keys.alive("m", 1, 1), TokenChange(1, 1, True), "token")])
    watcher.feed([Record(0.0, token, TokenChange(0, 1, True), "token")])
    watcher.feed([Record(1.0, token, TokenChange(0, 1, False), "token")])
    watcher.feed([Record(1.5, token, TokenChange(0, 1, True), "token")])
    assert not watcher.new_run  # a token back before any verdict: the same run
    watcher.feed([Record(2.0, token, TokenChange(0, 1, False), "token"),
                  Record(2.1, keys.mission_status("m"), MissionStatus("complete", "done"))])
    assert watcher.verdict is not None and not watcher.new_run
    watcher.feed([Record(9.0, token, TokenChange(0, 1, True), "token")])
    assert watcher.new_run


@pytest.mark.slow
@pytest.mark.integration
def test_the_missions_on_a_router_are_listed_and_one_watched(router: str,
                                                             tmp_path: Path) -> None:
    """A monitor started where no run directory is finds the missions by their robots'
    liveliness tokens on the router (it used to watch mission "default" and show nothing)."""
    import asyncio

    from bus.bridge import Bus
    from bus.config import ConnectionSettings

    async def main() -> subprocess.CompletedProcess[str]:
        async with Bus.connect(ConnectionSettings(connect=(router,), mission="big")) as big, \
                Bus.connect(ConnectionSettings(connect=(router,), mission="small")) as small:
            for robot in range(3):
                big.declare_token(keys.alive("big", robot, 1))
            small.declare_token(keys.alive("small", 0, 1))
            env = {k: v for k, v in os.environ.items() if not k.startswith("MSTC_")}
            return await asyncio.to_thread(subprocess.run, [
                sys.executable, "-m", "deploy.cli", "monitor", "--plain", "--duration", "4",
                "--connect", router], cwd=tmp_path, capture_output=True, text=True,
                timeout=60, env=env)

    done = asyncio.run(main())
    assert done.returncode == 0, done.stderr
    assert "2 live missions:" in done.stderr, done.stderr
    assert "mission big (3 robots; on the router)" in done.stderr
    assert "watching mission big (3 robots; on the router)" in done.stderr


def test_with_no_live_run_and_no_router_the_monitor_says_what_it_waits_for_and_gives_up(
        tmp_path: Path, free_port: int) -> None:
    _run_dir(tmp_path / "runs", "a", "finished", 100.0, live=False)
    env = {k: v for k, v in os.environ.items() if not k.startswith("MSTC_")}
    done = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "monitor", "--plain", "--exit-when-done",
         "--connect", f"tcp/127.0.0.1:{free_port}", "--connect-timeout", "2"],
        cwd=tmp_path, capture_output=True, text=True, timeout=60, env=env)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.splitlines()
    assert lines[0] == (f"mstc monitor: no live run under runs/ (the latest, runs/a, has "
                        f"ended); waiting up to 2 s for a fleet to start (mstc up) or for "
                        f"robots on the router at tcp/127.0.0.1:{free_port}")
    assert lines[-1].startswith("mstc monitor: error: no live mission within 2 s"), lines


def test_viewers_follow_the_running_fleet_before_a_newer_finished_one(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """mstc foxglove and ros-bridge share the follower: a run whose launcher runs wins over
    a later run directory that has ended."""
    import argparse

    from bus.config import DEFAULT_MISSION, ConnectionSettings
    from deploy.cmd_monitor import follow_run_dir

    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MSTC_MISSION", raising=False)
    monkeypatch.delenv("MSTC_CREDENTIALS", raising=False)
    _run_dir(Path("runs"), "a", "running", 100.0, live=True)
    _run_dir(Path("runs"), "b", "ended", 200.0, live=False)
    args = argparse.Namespace(mission=DEFAULT_MISSION, run_dir=None)
    assert follow_run_dir(args, ConnectionSettings()).mission == "running"
