"""``mstc up`` / ``mstc down`` / SIGTERM with real processes on loopback: router, simhw and
agents, each its own process. Coverage is checked against the ground truth simhw reports
(summary.json) and against an independent BFS of the reachable sub-cells."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest
from test_fleet_unit import reachable_oracle

from deploy.fleet import FleetInfo, RunDir, is_running
from planner.maps import resolve_world

pytestmark = pytest.mark.integration

WORLD = "open-room"
MAIN = ("-m", "deploy.cli")
# Generous guards against a hung test on a loaded machine; not timing assertions.
RUN_LIMIT = 120.0
# CPU-starved agents on a busy 2-core machine can miss 1 s heartbeats and be falsely declared
# dead (docs/operations.md); a SIGKILL is still detected at once through the closed link.
TOLERANT = ("--lease-ms", "5000", "--dead-after", "5")


def up_argv(port: int, run_dir: Path, *extra: str, robots: int = 4) -> list[str]:
    return [sys.executable, *MAIN, "up", "-n", str(robots), "--world", WORLD,
            "--algo", "opt", "--plain", "--listen", f"tcp/127.0.0.1:{port}",
            "--run-dir", str(run_dir), "--stall-timeout", "30", *TOLERANT, *extra]


def run_up(port: int, run_dir: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(up_argv(port, run_dir, *extra), capture_output=True, text=True,
                          timeout=RUN_LIMIT)


def start_up(port: int, run_dir: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(up_argv(port, run_dir, *extra), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def wait_for_fleet(run_dir: Path, proc: subprocess.Popen[str]) -> FleetInfo:
    """The fleet.json of a background ``mstc up`` once its agents are started."""
    deadline = time.monotonic() + RUN_LIMIT
    while time.monotonic() < deadline:
        if (run_dir / "fleet.json").exists():
            return RunDir(run_dir).read_fleet()
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.1)
    raise AssertionError("mstc up never wrote fleet.json")


def assert_all_gone(info: FleetInfo) -> None:
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline and any(is_running(p) for p in info.processes):
        time.sleep(0.1)
    left = [p.name for p in info.processes if is_running(p)]
    assert not left, f"processes left running: {left}"


def expected_reachable(info: FleetInfo) -> int:
    grid = resolve_world(info.world)
    return int(reachable_oracle(grid.free, list(info.starts)).sum())


def log_tails(run_dir: Path, lines: int = 12) -> str:
    """The last lines of every process's log of a run: what a failed fleet test prints, as
    the run directory is gone when pytest's temporary directories rotate (a CI rehearsal's
    stall left no evidence, 2026-12-05)."""
    out = []
    for log in sorted((run_dir / "logs").glob("*.log")):
        tail = log.read_text(errors="replace").splitlines()[-lines:]
        out.append(f"--- {log.name} (last {len(tail)} lines)\n" + "\n".join(tail))
    return "\n".join(out)


def check_complete(result: subprocess.CompletedProcess[str], run_dir: Path) -> dict[str, Any]:
    assert result.returncode == 0, "\n".join((result.stdout, result.stderr, log_tails(run_dir)))
    info = RunDir(run_dir).read_fleet()
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["complete"] is True, log_tails(run_dir)
    assert summary["covered"] == summary["reachable"] == expected_reachable(info)
    assert "100.0 %" in result.stdout
    # Every robot of a run without failures walks at least its planned share.
    assert summary["makespan_moves"] >= summary["reachable"] / info.robots - 1
    assert_all_gone(info)
    return summary


def test_up_covers_everything(free_port: int, tmp_path: Path) -> None:
    result = run_up(free_port, tmp_path / "run", "--time-scale", "0")
    summary = check_complete(result, tmp_path / "run")
    assert summary["robots_lost"] == []
    for name in ("router", "simhw", "agent-0", "agent-3"):
        assert (tmp_path / "run" / "logs" / f"{name}.log").exists()


@pytest.mark.slow
def test_up_with_a_robot_killed_mid_mission(free_port: int, tmp_path: Path) -> None:
    # The second order's moment never comes, and the third's comes with the last sub-cell
    # covered, when a death tests nothing (it was carried out then, and counted by chaos
    # campaigns as a death survived): the summary says neither was carried out.
    result = run_up(free_port, tmp_path / "run", "--time-scale", "0",
                    "--kill", "1@progress=30", "--kill", "2@9999", "--kill", "3@progress=100")
    summary = check_complete(result, tmp_path / "run")
    assert [lost["robot"] for lost in summary["robots_lost"]] == [1]
    assert "SIGKILL agent 1 at 30 %" in result.stdout
    assert ("not carried out (the mission ended first): SIGKILL agent 2 at 9999 s, "
            "SIGKILL agent 3 at 100 %" in result.stdout), result.stdout


@pytest.mark.slow
def test_second_fleet_on_same_port_fails_then_down_stops_first(free_port: int,
                                                              tmp_path: Path) -> None:
    first = start_up(free_port, tmp_path / "first", "--time-scale", "1")
    try:
        info = wait_for_fleet(tmp_path / "first", first)
        second = run_up(free_port, tmp_path / "second")
        assert second.returncode == 2
        assert "already in use" in second.stderr and "Traceback" not in second.stderr
        assert len(second.stderr.strip().splitlines()) == 1
        assert not (tmp_path / "second").exists()
        assert first.poll() is None  # the first fleet is untouched
        down = subprocess.run([sys.executable, *MAIN, "down", "--run-dir",
                               str(tmp_path / "first")], capture_output=True, text=True,
                              timeout=RUN_LIMIT)
        assert down.returncode == 0, down.stderr
        assert first.wait(RUN_LIMIT) == 128 + signal.SIGTERM
        assert "stopped by SIGTERM" in first.communicate()[0]
        assert_all_gone(info)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()


@pytest.mark.parametrize("sig", [pytest.param(signal.SIGTERM, marks=pytest.mark.slow),
                                 signal.SIGHUP])
def test_a_signal_stops_everything_cleanly(free_port: int, tmp_path: Path,
                                           sig: signal.Signals) -> None:
    """SIGTERM from `mstc down`, SIGHUP from a closed terminal: no child is left behind."""
    proc = start_up(free_port, tmp_path / "run", "--time-scale", "1")
    try:
        info = wait_for_fleet(tmp_path / "run", proc)
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=RUN_LIMIT)
        assert proc.returncode == 128 + sig, err
        assert "Traceback" not in err
        assert "INCOMPLETE" in out and f"stopped by {sig.name}" in out
        assert_all_gone(info)
        assert not list((tmp_path / "run" / "pids").iterdir())
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
