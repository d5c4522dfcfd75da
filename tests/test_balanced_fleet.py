"""``mstc up --algo balanced`` with real processes on loopback: the agents plan the balanced
regions themselves (digest-checked), walk them with BalancedRobot, and finish a dead robot's
region; coverage is checked against simhw's ground truth (summary.json)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest
from test_fleet_up import check_complete, up_argv

pytestmark = [pytest.mark.integration, pytest.mark.slow]

RUN_LIMIT = 180.0


def run_balanced(port: int, run_dir: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    argv = up_argv(port, run_dir, "--time-scale", "0", *extra, robots=5)
    argv[argv.index("--algo") + 1] = "balanced"
    return subprocess.run(argv, capture_output=True, text=True, timeout=RUN_LIMIT)


def test_a_balanced_fleet_covers_everything(free_port: int, tmp_path: Path) -> None:
    result = run_balanced(free_port, tmp_path / "run")
    summary = check_complete(result, tmp_path / "run")
    assert summary["robots_lost"] == []
    assert "algo balanced" in result.stdout


def test_a_balanced_fleet_finishes_a_killed_robots_region(free_port: int,
                                                          tmp_path: Path) -> None:
    result = run_balanced(free_port, tmp_path / "run", "--kill", "2@progress=30")
    summary = check_complete(result, tmp_path / "run")
    assert [lost["robot"] for lost in summary["robots_lost"]] == [2]
    assert "takes over robot 2" in result.stdout
