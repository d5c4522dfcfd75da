"""``mstc up --algo balanced`` and ``--recovery rebalance`` with real processes on loopback:
the agents plan the balanced regions themselves (digest-checked), walk them with
BalancedRobot, and finish a dead robot's region, by the takeover or by re-planning together;
coverage is checked against simhw's ground truth (summary.json)."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest
from test_fleet_up import check_complete, up_argv

from bus.faults import ENV as FAULTS_ENV

pytestmark = [pytest.mark.integration, pytest.mark.slow]

RUN_LIMIT = 180.0


def run_balanced(port: int, run_dir: Path, *extra: str, algo: str = "balanced",
                 faults: str = "") -> subprocess.CompletedProcess[str]:
    argv = up_argv(port, run_dir, "--time-scale", "0", *extra, robots=5)
    argv[argv.index("--algo") + 1] = algo
    env = {**os.environ, FAULTS_ENV: faults} if faults else None
    return subprocess.run(argv, capture_output=True, text=True, timeout=RUN_LIMIT, env=env)


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
                          "--time-scale", "100", "--recovery", "takeover")
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
    # (rebalance is the default recovery)
    result = run_balanced(free_port, tmp_path / "run", *flags, "--time-scale", "100",
                          algo=algo)
    summary = check_complete(result, tmp_path / "run")
    lost = {entry["robot"]: entry["why"] for entry in summary["robots_lost"]}
    killed = {int(kill.split("@")[0]) for kill in kills}
    # walks that meet another body wait or step aside (planner.offline.traffic): nobody
    # but the killed robots is lost
    assert set(lost) == killed, lost
    assert "takes over" not in result.stdout
    plans = replans(result.stdout)
    assert plans, result.stdout
    # every survivor that re-planned for the same deaths used the same reports
    assert all(len(digests) == 1 for digests in plans.values()), plans


def test_robots_starting_in_one_row_cross_each_other_and_finish(free_port: int,
                                                                tmp_path: Path) -> None:
    """Five robots start side by side in the top row: their balanced walk-outs to their
    regions cross each other's, and after robot 2's death the survivors' re-plan walks cross
    again. Everyone but the killed robot completes and states its waits, detours and
    bumps; the crossing is not vacuous: some robot had to wait or was refused a step."""
    result = run_balanced(free_port, tmp_path / "run", "--starts", "0,0;0,1;0,2;0,3;0,4",
                          "--kill", "2@progress=30", "--time-scale", "100")
    summary = check_complete(result, tmp_path / "run")
    assert [lost["robot"] for lost in summary["robots_lost"]] == [2]
    waits, _detours, bumps, robots = summary["traffic"]
    assert robots == 4, summary["traffic"]
    assert waits + bumps > 0, summary["traffic"]
    assert re.search(r"traffic +\d+ waits, \d+ detours, \d+ bumps", result.stdout)


def test_a_crowd_walks_the_re_plan_its_lowest_survivor_shares(free_port: int,
                                                               tmp_path: Path) -> None:
    """With sharing from 2 survivors on (a crowd of 100 shares from 13), each death's re-plan
    is computed by the lowest survivor alone and walked by the others as shared; every share
    is dropped on the wire: the others pull it from the sharer's announcer."""
    result = run_balanced(free_port, tmp_path / "run", "--kill", "1@progress=20",
                          "--kill", "3@progress=40", "--time-scale", "100",
                          "--agent-arg=--replan-share-from=2", algo="opt",
                          faults="seed=3;replanned.drop=1")
    summary = check_complete(result, tmp_path / "run")
    assert {entry["robot"] for entry in summary["robots_lost"]} == {1, 3}
    lines = re.findall(r"robot (\d+) re-planned: dead (\[[\d, ]*\]), digest (\w+), "
                       r"\d+ moves to walk(.*) \(reports [\d.]+ s, re-plan [\d.]+ s\)",
                       result.stdout)
    assert lines, result.stdout
    by_epoch: dict[str, list[tuple[int, str, str]]] = {}
    for robot, dead, digest, how in lines:
        by_epoch.setdefault(dead, []).append((int(robot), digest, how))
    walked_a_share = 0
    for dead, said in by_epoch.items():
        assert len({digest for _, digest, _ in said}) == 1, said
        # robot 0 survives both deaths: it computes, everyone else walks its share
        hows = {robot: how for robot, _, how in said}
        assert hows.pop(0) == ", shared with the fleet", (dead, said)
        assert set(hows.values()) <= {", shared by robot 0"}, (dead, said)
        walked_a_share += len(hows)
    assert walked_a_share, lines  # not only the sharer re-planned


def test_a_crowd_flies_the_first_plan_its_lowest_robot_shares(free_port: int,
                                                              tmp_path: Path) -> None:
    """With sharing from 2 participants on (a crowd shares from 26), robot 0 alone computes
    the balanced plan and the others fly it as shared; every share is dropped on the wire,
    so the others pull it from robot 0's announcer. The digests agree and the fleet covers
    the map."""
    result = run_balanced(free_port, tmp_path / "run", "--agent-arg=--plan-share-from=2",
                          faults="seed=5;planned.drop=1")
    check_complete(result, tmp_path / "run")
    said: dict[int, tuple[str, str]] = {}
    for log in (tmp_path / "run" / "logs").glob("agent-*.log"):
        for digest, how in re.findall(r"plan (\w{12}) makespan \d+ moves, mine \d+(.*?) \[",
                                      log.read_text()):
            said[int(log.stem.split("-")[1])] = (digest, how)
    assert sorted(said) == [0, 1, 2, 3, 4], said
    assert len({digest for digest, _ in said.values()}) == 1, said
    assert said.pop(0)[1] == ", shared with the fleet", said
    assert {how for _, how in said.values()} == {", shared by robot 0"}, said
