"""``mstc up`` says no: exit 1 for an incomplete mission, a stall, agents not up, an agent's
failed verdict, the router or simhw dying; the kill orders really kill (summary.json's
robots_lost, the agent's exit), including the README's headline command as written.

Real processes on loopback; every wait is on the launcher's exit (bounded by RUN_LIMIT), no
timing is asserted."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from test_fleet_up import (
    MAIN,
    RUN_LIMIT,
    TOLERANT,
    assert_all_gone,
    run_up,
    start_up,
    wait_for_fleet,
)

from deploy.fleet import RunDir, is_running

pytestmark = pytest.mark.integration


def summary(run_dir: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((run_dir / "summary.json").read_text())
    return data


def lost(run_dir: Path) -> dict[int, str]:
    return {entry["robot"]: entry["why"] for entry in summary(run_dir)["robots_lost"]}


@pytest.mark.slow
def test_up_exits_1_when_every_robot_is_killed(free_port: int, tmp_path: Path) -> None:
    run = tmp_path / "run"
    result = run_up(free_port, run, "--time-scale", "1", "--kill", "0@0", "--kill", "1@0",
                    "--kill", "2@0", "--kill", "3@0")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "every agent has stopped" in result.stdout and "uncovered" in result.stdout
    assert summary(run)["complete"] is False
    assert set(lost(run)) == {0, 1, 2, 3}
    assert "Traceback" not in result.stderr


# Not slow: the fast suite's witness that the stall timeout fires (docs/testing.md).
def test_up_exits_1_when_the_mission_stalls(free_port: int, tmp_path: Path) -> None:
    # 1000 wall seconds per simulated one: no forward step ends within the stall timeout.
    # The agents give up on their bodies 10 s in (they would report "every agent has
    # stopped"), so a launcher that never sees the stall fails this test that soon.
    result = run_up(free_port, tmp_path / "run", "--time-scale", "0.001",
                    "--stall-timeout", "2", "--agent-arg=--hw-timeout=10")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "mission stalled: no new sub-cell covered" in result.stdout
    assert "mission started" in result.stdout, "the stall clock runs only once started"
    assert summary(tmp_path / "run")["complete"] is False


def test_up_exits_1_when_the_agents_are_not_up_in_time(free_port: int,
                                                        tmp_path: Path) -> None:
    result = run_up(free_port, tmp_path / "run", "--time-scale", "0", "--start-timeout",
                    "0.01")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "agents not up after" in result.stdout and "robots not announced" in result.stdout


@pytest.mark.slow
def test_up_exits_1_on_an_agents_failed_verdict(free_port: int, tmp_path: Path) -> None:
    # Agents that give up gathering the others' starts at once declare the mission failed.
    result = run_up(free_port, tmp_path / "run", "--time-scale", "0",
                    "--agent-arg=--start-timeout=0.01")
    assert result.returncode == 1, result.stdout + result.stderr
    assert "an agent declared the mission failed" in result.stdout
    assert "did not announce their start" in result.stdout
    assert summary(tmp_path / "run")["complete"] is False


@pytest.mark.parametrize("victim", ["simhw", pytest.param("router", marks=pytest.mark.slow)])
def test_up_exits_1_when_a_world_process_dies(free_port: int, tmp_path: Path,
                                              victim: str) -> None:
    run = tmp_path / "run"
    proc = start_up(free_port, run, "--time-scale", "1")
    try:
        info = wait_for_fleet(run, proc)
        pid = next(p.pid for p in info.processes if p.name == victim)
        os.kill(pid, signal.SIGKILL)
        out, err = proc.communicate(timeout=RUN_LIMIT)
        assert proc.returncode == 1, out + err
        assert f"INCOMPLETE — {victim} exited early with code -9" in out, out
        assert "Traceback" not in err
        assert_all_gone(info)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.slow
def test_the_readme_headline_command_kills_robot_2(free_port: int, tmp_path: Path) -> None:
    """``mstc up -n 6 --world office --algo opt --kill 2@3`` as written, plus where to
    listen and write (and the tolerant liveness of a loaded machine)."""
    run = tmp_path / "run"
    argv = [sys.executable, *MAIN, "up", "-n", "6", "--world", "office", "--algo", "opt",
            "--kill", "2@3", "--plain", "--listen", f"tcp/127.0.0.1:{free_port}",
            "--run-dir", str(run), *TOLERANT]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        info = wait_for_fleet(run, proc)
        agent = next(p for p in info.processes if p.name == "agent-2")
        out, err = proc.communicate(timeout=4 * RUN_LIMIT)
        assert proc.returncode == 0, out + err
        assert "SIGKILL agent 2 at 3 s: done" in out
        assert lost(run) == {2: "killed by mstc up (SIGKILL)"}
        assert summary(run)["complete"] is True
        assert not is_running(agent)
        # The agent never finished: its log has no completion of its own.
        log = RunDir(run).log_path("agent-2").read_text()
        assert "mission complete" not in log
        # The default recovery: the survivors re-plan together, nobody takes over. On a
        # loaded host the kill at 3 s can come before agent 2 has announced its start (its
        # imports alone took that long beside a chaos campaign); then the others agree on a
        # fleet without it and plan for five from the start. Either story, told once.
        before_start = "robots [2] never announced a start and take no part" in out
        replanned = "re-planned: dead [2]" in out
        assert before_start != replanned, out
        if before_start:  # then it cannot have been in the agreement either
            assert "participants [" not in log, log
        assert summary(run)["takeovers"] == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.slow
def test_kill_at_progress_really_kills(free_port: int, tmp_path: Path) -> None:
    run = tmp_path / "run"
    result = run_up(free_port, run, "--time-scale", "0", "--kill", "2@progress=40")
    assert result.returncode == 0, result.stdout + result.stderr
    assert lost(run) == {2: "killed by mstc up (SIGKILL)"}
    assert "SIGKILL agent 2 at 40 %" in result.stdout
    assert summary(run)["complete"] is True


@pytest.mark.slow
def test_a_sigkilled_launcher_leaves_no_process_of_its_fleet_running(free_port: int,
                                                                    tmp_path: Path) -> None:
    # Children run in sessions of their own (a terminal's hang-up must reach only the
    # launcher, which stops them in order); a launcher killed outright could not, and its
    # router, simhw and agents ran on until `mstc down`. The kernel now ends them with it.
    run = tmp_path / "run"
    proc = start_up(free_port, run, "--time-scale", "1")
    try:
        info = wait_for_fleet(run, proc)
        children = [p for p in info.processes if p.role != "up"]
        assert {p.role for p in children} >= {"router", "simhw", "agent"}
        assert all(is_running(p) for p in children)
        proc.kill()
        proc.wait()
        assert_all_gone(info)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
