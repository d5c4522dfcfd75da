"""``mstc up --algo balanced`` and ``--recovery rebalance`` with real processes on loopback:
the agents plan the balanced regions themselves (digest-checked), walk them with
BalancedRobot, and finish a dead robot's region, by the takeover or by re-planning together;
coverage is checked against simhw's ground truth (summary.json)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from test_fleet_up import check_complete, up_argv

pytestmark = [pytest.mark.integration, pytest.mark.slow]

RUN_LIMIT = 180.0


def run_balanced(port: int, run_dir: Path, *extra: str,
                 algo: str = "balanced") -> subprocess.CompletedProcess[str]:
    argv = up_argv(port, run_dir, "--time-scale", "0", *extra, robots=5)
    argv[argv.index("--algo") + 1] = algo
    return subprocess.run(argv, capture_output=True, text=True, timeout=RUN_LIMIT)


def test_a_balanced_fleet_covers_everything(free_port: int, tmp_path: Path) -> None:
    result = run_balanced(free_port, tmp_path / "run")
    summary = check_complete(result, tmp_path / "run")
    assert summary["robots_lost"] == []
    assert "algo balanced" in result.stdout


def test_a_balanced_fleet_finishes_a_killed_robots_region(free_port: int,
                                                          tmp_path: Path) -> None:
    # at full speed the kill can land after robot 2 finished its region; 100 x keeps it
    # mid-mission, so its region is left half done for the takeover
    result = run_balanced(free_port, tmp_path / "run", "--kill", "2@progress=30",
                          "--time-scale", "100")
    summary = check_complete(result, tmp_path / "run")
    assert [lost["robot"] for lost in summary["robots_lost"]] == [2]
    assert "takes over robot 2" in result.stdout


def replans(stdout: str) -> dict[str, set[str]]:
    """Digests of the re-plan reports each survivor used, by the deaths it re-planned for."""
    out: dict[str, set[str]] = {}
    for dead, digest in re.findall(r"re-planned: dead (\[[\d, ]*\]), digest (\w+)", stdout):
        out.setdefault(dead, set()).add(digest)
    return out


@pytest.mark.parametrize(("algo", "kills"), [("balanced", ("2@progress=30",)),
                                             ("opt", ("1@progress=20", "3@progress=40"))])
def test_survivors_re_plan_together_and_finish(free_port: int, tmp_path: Path, algo: str,
                                               kills: tuple[str, ...]) -> None:
    flags = [flag for kill in kills for flag in ("--kill", kill)]
    # at full speed a kill can land after the last sub-cell; 100 x keeps it mid-mission
    result = run_balanced(free_port, tmp_path / "run", "--recovery", "rebalance", *flags,
                          "--time-scale", "100", algo=algo)
    summary = check_complete(result, tmp_path / "run")
    lost = {entry["robot"]: entry["why"] for entry in summary["robots_lost"]}
    killed = {int(kill.split("@")[0]) for kill in kills}
    assert killed <= set(lost), lost
    # Re-plan walks can still meet another robot's body head-on: there is no deconfliction of
    # walks yet (issue 14, item 6), so such a robot gives up on its bumped step and the others
    # finish its work (seen in one CI rehearsal of the two-kill case). Any loss beyond the kills
    # must be exactly that, never a false death.
    for robot, why in lost.items():
        if robot not in killed:
            log = (tmp_path / "run" / "logs" / f"agent-{robot}.log").read_text()
            assert why == "agent exited with code 1" and "bumped into body" in log, (why, log)
    assert "takes over" not in result.stdout
    plans = replans(result.stdout)
    assert plans, result.stdout
    # every survivor that re-planned for the same deaths used the same reports
    assert all(len(digests) == 1 for digests in plans.values()), plans
