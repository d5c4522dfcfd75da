"""Launcher pieces without Zenoh: kill orders, coverage tracking, run dirs, PID identity,
``mstc kill``/``mstc down`` on stand-in processes, the plain progress view."""

from __future__ import annotations

import argparse
import dataclasses
import io
import math
import signal
import socket
import subprocess
import sys
import threading
import time
from collections import deque
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from agent.offline.plan import compute_plan
from bus import argtypes, keys
from bus.messages import (
    CoverEvent,
    DeathNotice,
    RobotEvent,
    RobotStatus,
    RobotTruth,
    make_world_state,
)
from deploy import cmd_down, cmd_kill, cmd_up
from deploy.cli import main as cli_main
from deploy.errors import FleetError
from deploy.fleet import (
    FleetInfo,
    ProcessRecord,
    RunDir,
    check_port_free,
    is_running,
    latest_run_dir,
    router_answers_within,
    start_ticks,
)
from deploy.fleet_timing import fleet_timing
from deploy.monitor.coverage import reachable_sub_cells
from deploy.progress import PlainProgress
from deploy.settings import (
    KillOrder,
    MissionSetup,
    UpSettings,
    parse_kill,
    plan_allowance,
    replan_allowance,
    stall_timeout,
    with_allowances,
    with_replan_allowance,
)
from deploy.summary import MissionTracker, format_summary, summarize
from planner.digest import plan_digest
from planner.types import OccupancyGrid

# --- kill orders ----------------------------------------------------------------------------


@pytest.mark.parametrize(("text", "order"), [
    ("2@3", KillOrder(2, seconds=3.0)),
    ("0@1.5s", KillOrder(0, seconds=1.5)),
    ("4@progress=40", KillOrder(4, percent=40.0)),
    ("1@25%", KillOrder(1, percent=25.0)),
])
def test_parse_kill_accepts_seconds_and_percent(text: str, order: KillOrder) -> None:
    assert parse_kill(text) == order
    assert parse_kill(text, hw=True).hw


@pytest.mark.parametrize("text", ["2", "@3", "x@3", "2@", "2@-1", "2@progress=140", "2@3m"])
def test_parse_kill_rejects_malformed(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        parse_kill(text)


@pytest.mark.parametrize(("extra", "message"), [
    (["--world", "no-such-world"], "neither a builtin world, a generated world nor an existing"),
    (["--world", "maze:14x9:1"], "a maze has odd sides"),
    (["--kill", "5@1"], "robots are 0..1"),
    (["--starts", "0,0"], "--starts gives 1 robots"),
    (["--starts", "0,0;0,0"], "robots 0 and 1 both start"),
])
def test_up_rejects_mistakes_in_one_line_before_starting(tmp_path: Path, extra: list[str],
                                                        message: str) -> None:
    # run as `python -m deploy.cli`: the entry module is then __main__, a second copy of it,
    # and the commands' errors must still be printed as one line
    result = subprocess.run(
        [sys.executable, "-m", "deploy.cli", "up", "-n", "2", "--world", "open-room",
         "--run-dir", str(tmp_path / "run"), *extra],
        capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "run").exists()


# --- shared option types (bus.argtypes) and the mission set-up ------------------------------


def _float_or_none(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


@settings(max_examples=200, deadline=None)
@given(st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                 st.integers(-5, 50).map(str), st.sampled_from(["²", "٣", "1e3", "+2", ""]),
                 st.text(max_size=4)))
def test_option_types_accept_exactly_their_ranges(text: str) -> None:
    value = _float_or_none(text)
    cases = [
        (argtypes.positive, value is not None and math.isfinite(value) and value > 0),
        (argtypes.seconds, value is not None and math.isfinite(value) and value > 0),
        (argtypes.non_negative, value is not None and math.isfinite(value) and value >= 0),
        (argtypes.time_scale, value is not None and not math.isnan(value) and value >= 0),
        (argtypes.positive_int, text.isascii() and text.isdigit() and int(text) >= 1),
        (argtypes.index, text.isascii() and text.isdigit()),
    ]
    for parse, ok in cases:
        if ok:
            assert parse(text) == (int(text) if parse in (argtypes.positive_int,
                                                          argtypes.index) else value)
        else:
            with pytest.raises(argparse.ArgumentTypeError):
                parse(text)


def test_up_plans_paper_trees_from_the_robots_starts() -> None:
    """Create Tree needs the start cells: without them build_tree refuses to plan."""
    parser = argparse.ArgumentParser()
    cmd_up.add_arguments(parser)
    args = parser.parse_args(["-n", "3", "--world", "open-room", "--tree", "createtree",
                              "--seed", "2"])
    setup = MissionSetup.plan(cmd_up.up_settings(args))
    agents = compute_plan(setup.grid, setup.starts, "opt", "createtree", 2)
    assert setup.planned_makespan == agents.makespan
    assert plan_digest(agents) != plan_digest(
        compute_plan(setup.grid, setup.starts, "opt", "dfs", 2))


def test_default_stall_timeout_allows_100_moves_of_wall_time() -> None:
    def timeout(scale: float, given: float | None = None) -> float:
        return stall_timeout(scale, given)

    assert timeout(0.0) == timeout(float("inf")) == 20.0
    assert timeout(1.0) == pytest.approx(20.0 + 100 * 2.5)
    assert timeout(40.0) < timeout(10.0)
    assert timeout(1.0, given=7.0) == 7.0


def test_a_crowded_fleets_stall_timeout_allows_for_the_survivors_replan() -> None:
    assert stall_timeout(0.0, robots=12, cores=2) == 20.0  # not crowded: the default
    assert stall_timeout(0.0, robots=40, cores=2) == pytest.approx(20.0 + 6.0 * 40 / 2)
    assert stall_timeout(0.0, robots=100, cores=2) == pytest.approx(320.0)
    assert stall_timeout(0.0, robots=40, cores=8) == 20.0
    assert stall_timeout(1.0, robots=40, cores=2) == pytest.approx(140.0 + 100 * 2.5)
    assert stall_timeout(0.0, given=30.0, robots=100, cores=2) == 30.0


def test_the_stall_timeout_allows_for_a_large_maps_replan_unless_given() -> None:
    """12 robots on city 120 x 120 (40 392 sub-cells), one killed at 30 %, stalled out after
    the default 26 s at time scale 40 while the 11 survivors each re-planned (62-67 s on
    2 cores once the stall timeout let them); one computes it for all there now."""
    settings = UpSettings(robots=12, world="city:120x120:1", time_scale=40.0,
                          stall_timeout=stall_timeout(40.0, robots=12, cores=2))
    assert settings.stall_timeout == pytest.approx(26.25)
    one = 0.5e-3 * 40_392  # one survivor computing it, on one core
    longer = with_replan_allowance(settings, None, 40_392, cores=2)
    assert longer.stall_timeout == pytest.approx(26.25 + one)
    assert longer.stall_timeout > 7.2 * 5  # five times the re-plan's CPU alone
    assert with_replan_allowance(settings, 26.25, 40_392, cores=2) == settings  # given: kept
    # a small map: each survivor computes it, on the cores there are
    assert replan_allowance(884, 6, cores=2) == pytest.approx(0.5e-3 * 884 * 5 / 2)
    assert replan_allowance(884, 6, cores=2) < 1.5  # the office: nothing to notice
    assert replan_allowance(884, 13, cores=2) == pytest.approx(0.5e-3 * 884 * 12 / 2)
    assert replan_allowance(884, 14, cores=2) == pytest.approx(0.5e-3 * 884)  # a crowd
    # one computes for all on a large map from 3 survivors, on one core whatever the host has
    assert replan_allowance(40_392, 14, cores=2) == replan_allowance(40_392, 100, cores=2)
    assert replan_allowance(40_392, 14, cores=8) == pytest.approx(one)
    assert replan_allowance(40_392, 4, cores=8) == pytest.approx(one)
    assert replan_allowance(40_392, 3, cores=2) == pytest.approx(one)  # 2 survivors, 2 cores
    assert replan_allowance(40_392, 3, cores=1) == pytest.approx(2 * one)
    assert replan_allowance(40_392, 1, cores=2) == 0.0


def test_the_first_plans_allowance_follows_who_computes_it() -> None:
    # a large map: one agent computes it for all (from 3), on one core
    assert plan_allowance(30.0, 45_420, 20, cores=2) == pytest.approx(3 * 30.0)
    assert plan_allowance(30.0, 45_420, 2, cores=2) == pytest.approx(3 * 30.0)  # side by side
    assert plan_allowance(30.0, 45_420, 2, cores=1) == pytest.approx(2 * 3 * 30.0)
    # the office: every agent computes it, on the cores there are
    assert plan_allowance(0.2, 884, 6, cores=2) == pytest.approx(3 * 0.2 * 6 / 2)
    parser = argparse.ArgumentParser()
    cmd_up.add_arguments(parser)
    office = MissionSetup.plan(cmd_up.up_settings(parser.parse_args(["-n", "6"])))
    assert office.plan_cpu_s > 0 and int(office.reachable.sum()) == 884
    online = MissionSetup.plan(cmd_up.up_settings(parser.parse_args(
        ["-n", "3", "--algo", "ormstc"])))
    assert online.plan_cpu_s == 0.0  # its agents plan nothing: no allowance, no "planned in"
    setup = dataclasses.replace(office, plan_cpu_s=2.0)
    settings = UpSettings(robots=6, world="office", stall_timeout=26.25)
    longer = with_allowances(settings, None, setup, cores=2)
    assert longer.plan_allowance == pytest.approx(plan_allowance(2.0, 884, 6, cores=2))
    assert longer.stall_timeout > settings.stall_timeout  # and the re-plan's
    given = with_allowances(settings, 30.0, setup, cores=2)
    # a given stall timeout is kept; the plan's allowance is not a stall's, given or not
    assert given.stall_timeout == settings.stall_timeout
    assert given.plan_allowance == longer.plan_allowance > 0


def test_crowded_fleets_get_long_liveness_timers_unless_told() -> None:
    def settings(robots: int, cores: int, lease_ms: int | None = None,
                 dead_after: float | None = None) -> tuple[float, float]:
        timing = fleet_timing(robots, cores, lease_ms=lease_ms, dead_after=dead_after)
        return timing.lease_ms, timing.dead_after

    assert settings(12, 2) == (1000, 3.0)
    assert settings(13, 2) == (5000, 6.5)  # 1 s per agent per core (deploy.settings)
    assert settings(100, 2) == (20000, 50.0)
    assert settings(30, 8) == (1000, 3.0)
    assert settings(30, 2, lease_ms=800, dead_after=2.0) == (800, 2.0)


def test_a_dozen_robots_flat_out_get_the_crowded_lease_and_timeout() -> None:
    # time scale 0 makes every agent a CPU-bound process: 12 on 2 cores starved the links'
    # threads past a 1 s lease (deploy.fleet_timing.FLAT_OUT_AGENTS_PER_CORE)
    def timers(robots: int, cores: int, **given: float) -> tuple[float, float]:
        timing = fleet_timing(robots, cores, flat_out=True, **given)  # type: ignore[arg-type]
        return timing.lease_ms, timing.dead_after

    assert timers(12, 2) == (5000, 5.0)
    assert timers(9, 2) == (5000, 5.0)
    assert timers(8, 2) == (1000, 3.0)  # up to 4 per core: the agents' own defaults
    assert timers(12, 4) == (1000, 3.0)
    assert timers(12, 2, lease_ms=700, dead_after=2.0) == (700, 2.0)  # given: kept
    assert fleet_timing(30, 2, flat_out=True) == fleet_timing(30, 2)  # crowded: its own rule
    parser = argparse.ArgumentParser()
    cmd_up.add_arguments(parser)
    flat = cmd_up.up_settings(parser.parse_args(["-n", "12", "--time-scale", "0"]), cores=2)
    paced = cmd_up.up_settings(parser.parse_args(["-n", "12"]), cores=2)
    assert (flat.lease_ms, flat.dead_after) == (5000, 5.0)
    assert (paced.lease_ms, paced.dead_after) == (1000, 3.0)


# --- reachable sub-cells: brute-force oracle ------------------------------------------------

def reachable_oracle(free: np.ndarray, starts: list[tuple[int, int]]) -> np.ndarray:
    """BFS over 2x2 blocks whose four sub-cells are all free, from each start's block."""
    h, w = free.shape
    block_free = {(r, c) for r in range(h // 2) for c in range(w // 2)
                  if free[2 * r:2 * r + 2, 2 * c:2 * c + 2].all()}
    seen: set[tuple[int, int]] = set()
    queue = deque((r // 2, c // 2) for r, c in starts if (r // 2, c // 2) in block_free)
    seen.update(queue)
    while queue:
        r, c = queue.popleft()
        for nb in ((r + 1, c), (r - 1, c), (r, c + 1), (r, c - 1)):
            if nb in block_free and nb not in seen:
                seen.add(nb)
                queue.append(nb)
    out = np.zeros_like(free)
    for r, c in seen:
        out[2 * r:2 * r + 2, 2 * c:2 * c + 2] = True
    return out


@settings(max_examples=60, deadline=None)
@given(st.integers(3, 12), st.integers(3, 12), st.integers(0, 2**31), st.integers(1, 3))
def test_reachable_matches_bfs(h: int, w: int, seed: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    free = rng.random((h, w)) > 0.2
    grid = OccupancyGrid(free, name="t")
    candidates = np.argwhere(free)
    if len(candidates) == 0:
        return
    starts = [tuple(int(v) for v in candidates[i])
              for i in rng.choice(len(candidates), size=min(k, len(candidates)), replace=False)]
    got = reachable_sub_cells(grid, tuple(starts))  # type: ignore[arg-type]
    assert np.array_equal(got, reachable_oracle(free, starts))  # type: ignore[arg-type]


# --- mission tracker ------------------------------------------------------------------------

def _open_grid(h: int = 6, w: int = 8) -> OccupancyGrid:
    return OccupancyGrid(np.ones((h, w), dtype=bool), name="open")


def test_tracker_counts_distinct_reachable_covers_and_completes() -> None:
    grid = _open_grid()
    tracker = MissionTracker(reachable_sub_cells(grid, ((0, 0),)), robots=2)
    rng = np.random.default_rng(3)
    seen: set[tuple[int, int]] = set()
    visits: dict[tuple[int, int], int] = {}
    for step in range(200):
        cell = (int(rng.integers(0, 6)), int(rng.integers(0, 8)))
        visits[cell] = visits.get(cell, 0) + 1
        new = tracker.on_cover(CoverEvent(step % 2, cell, float(step), visits[cell]), step)
        assert new == (cell not in seen)
        seen.add(cell)
        assert tracker.covered == len(seen)
    assert tracker.complete == (len(seen) == 48)
    for r in range(6):
        for c in range(8):
            tracker.on_cover(CoverEvent(0, (r, c), 500.0, 1), 500.0)
    assert tracker.complete and tracker.coverage == 100.0 and tracker.uncovered() == []


def test_tracker_ignores_unreachable_and_out_of_map_covers() -> None:
    free = np.ones((4, 8), dtype=bool)
    free[:, 4] = False  # splits the map: cells in columns 4..7 are another component
    tracker = MissionTracker(reachable_sub_cells(OccupancyGrid(free), ((0, 0),)), robots=1)
    assert tracker.total == 16
    assert not tracker.on_cover(CoverEvent(0, (0, 6), 1.0, 1), 1.0)
    assert not tracker.on_cover(CoverEvent(0, (9, 9), 1.0, 1), 1.0)
    assert tracker.covered == 0


def test_world_state_is_the_authority_for_moves_and_failed_bodies() -> None:
    grid = _open_grid(4, 4)
    tracker = MissionTracker(reachable_sub_cells(grid, ((0, 0),)), robots=2)
    visits = np.zeros((4, 4), dtype=np.int64)
    visits[:2, :] = 1
    visits[0, 0] = 2
    robots = (RobotTruth(0, (0, 0, 1), True, False, False, covered=6),
              RobotTruth(1, (1, 3, 0), False, False, True, covered=4))
    state = make_world_state("open", grid.free, visits, robots, 12.0, 0.0)
    tracker.observe(1.0, keys.world("m"), state, "query")  # as the launcher does
    assert tracker.on_world(state, now=1.0)
    assert tracker.covered == 8
    assert [v.moves for v in tracker.views] == [5, 3]
    assert tracker.views[1].lost == "body failed in simhw by an operator (mstc kill --hw)"
    summary = summarize(tracker, mission="m", world="open", algo="opt", wall_seconds=1.0,
                        planned_makespan=5, outcome="test")
    assert summary.makespan_moves == 5 and summary.total_moves == 8
    assert summary.revisited == 1 and not summary.complete
    assert summary.robots_lost == ((1, "body failed in simhw by an operator (mstc kill --hw)"),)
    assert "50.0 %" in format_summary(summary)


def test_tracker_count_follows_covers_and_world_answers_interleaved() -> None:
    # The launcher counts covers as they come and recounts at each world answer (both are
    # asked at every cover it hears): the count must be the brute-force one at every step.
    free = np.ones((6, 8), dtype=bool)
    free[:, 4:6] = False  # columns 6..7 are a component no robot starts in
    grid = OccupancyGrid(free)
    tracker = MissionTracker(reachable_sub_cells(grid, ((0, 0),)), robots=2)
    rng = np.random.default_rng(11)
    truth = np.zeros((6, 8), dtype=np.int64)
    for step in range(300):
        cell = (int(rng.integers(0, 7)), int(rng.integers(0, 9)))  # some off the map
        if rng.random() < 0.1:  # a world answer holding covers never heard
            truth[rng.integers(0, 6, size=3), rng.integers(0, 8, size=3)] += 1
            tracker.on_world(make_world_state("m", free, truth, (), float(step), 0.0), step)
        elif cell[0] < 6 and cell[1] < 8:
            truth[cell] += 1
            tracker.on_cover(CoverEvent(0, cell, float(step), int(truth[cell])), step)
        else:
            assert not tracker.on_cover(CoverEvent(0, cell, float(step), 1), step)
        assert tracker.covered == int(((truth > 0) & tracker.reachable).sum())
    assert tracker.total == 24


def test_world_state_of_another_map_is_refused() -> None:
    tracker = MissionTracker(reachable_sub_cells(_open_grid(4, 4), ((0, 0),)), robots=1)
    free = np.zeros((4, 4), dtype=bool)
    state = make_world_state("other", free, np.zeros((4, 4), dtype=np.int64), (), 0.0, 0.0)
    with pytest.raises(ValueError, match="disagrees"):
        tracker.on_world(state, 0.0)


def test_robot_events_deaths_and_statuses() -> None:
    tracker = MissionTracker(reachable_sub_cells(_open_grid(), ((0, 0),)), robots=3)
    tracker.on_status(RobotStatus(0, 1, (0, 0), "opt", "d", "covering"))
    tracker.on_status(RobotStatus(7, 1, (0, 0), "opt", "d", "covering"))  # foreign id
    assert tracker.announced == 1 and tracker.views[0].state == "covering"
    for _ in range(2):  # a re-announced event counts once
        tracker.on_event(RobotEvent(0, 1, "takeover_started", subject=2))
    tracker.on_event(RobotEvent(1, 1, "completed"))
    _death(tracker, DeathNotice(2, 1, detected_by=0, reason="token", detected_at=1.0))
    _death(tracker, DeathNotice(2, 1, detected_by=1, reason="heartbeat", detected_at=1.1))
    _death(tracker, DeathNotice(1, 1, detected_by=1, reason="leaving", detected_at=1.2))
    assert len(tracker.takeovers) == 1
    assert tracker.views[1].completed and not tracker.views[1].lost  # left cleanly
    assert tracker.views[2].lost == "declared dead by robot 0 (token)"
    assert tracker.alive == 2
    assert sum("lost" in line for line in tracker.log) == 1


def _death(tracker: MissionTracker, notice: DeathNotice) -> bool:
    """As the launcher hands a death notice on: to the model first, then to the tracker."""
    tracker.observe(notice.detected_at, keys.death("m", notice.robot), notice)
    return tracker.on_death(notice)


def test_a_dead_robots_verdicts_on_live_ones_do_not_lose_them() -> None:
    """Chaos seed 4249, trial 23: robot 3, stopped 1.4 s, is declared dead by robot 1; woken,
    its session lost, it sees no peer's token and declares robots 0, 1 and 2 dead. The agents
    refuse those verdicts (their detector is dead) and simhw fences robot 3; the launcher
    took them, showed "robots alive 0/4" for the rest of a mission that completed, and its
    summary listed all four robots lost."""
    tracker = MissionTracker(reachable_sub_cells(_open_grid(), ((0, 0),)), robots=4)
    for robot in range(4):
        tracker.observe(0.0, keys.status("m", robot),
                        RobotStatus(robot, 1, (0, robot), "ormstc", "d", "covering"))
    assert _death(tracker, DeathNotice(3, 1, detected_by=1, reason="token", detected_at=3.4))
    for robot in (2, 1, 0, 2):
        assert not _death(tracker, DeathNotice(robot, 1, detected_by=3, reason="token",
                                               detected_at=3.9))
    assert [v.robot for v in tracker.views if v.lost] == [3] and tracker.alive == 3
    refused = [line for line in tracker.log if "not taken" in line]
    assert len(refused) == 3  # once per verdict, however often it is heard
    assert "robot 2 declared dead by robot 3 (token): not taken, robot 3 was declared dead " \
           "itself" in refused
    # a live robot's verdict on the same robot is taken
    assert _death(tracker, DeathNotice(2, 1, detected_by=0, reason="token", detected_at=4.8))
    assert tracker.views[2].lost == "declared dead by robot 0 (token)"


def test_plain_progress_prints_events_and_changed_status_lines() -> None:
    out = io.StringIO()
    view = PlainProgress(out, period=0.0)
    tracker = MissionTracker(reachable_sub_cells(_open_grid(), ((0, 0),)), robots=1)
    view.event("hello")
    view.update(tracker, 1.0)
    view.update(tracker, 2.0)  # nothing changed: no second line
    tracker.on_cover(CoverEvent(0, (0, 0), 1.0, 1), 1.0)
    view.update(tracker, 3.0)
    lines = out.getvalue().splitlines()
    assert lines[0] == "hello"
    assert len(lines) == 3 and "(1/48)" in lines[2]


# --- run directory, PID identity ------------------------------------------------------------

def _info(processes: tuple[ProcessRecord, ...] = ()) -> FleetInfo:
    return FleetInfo(mission="m", endpoint="tcp/127.0.0.1:1", own_router=True, world="w",
                     algo="opt", robots=2, starts=((0, 0), (2, 2)), time_scale=0.0,
                     created=0.0, processes=processes)


def test_fleet_json_round_trip_and_latest(tmp_path: Path) -> None:
    record = ProcessRecord("agent-1", "agent", 123, 456, "log", robot=1)
    older, newer = RunDir(tmp_path / "a").create(), RunDir(tmp_path / "b").create()
    older.write_fleet(_info())
    time.sleep(0.01)
    newer.write_fleet(_info((record,)))
    assert newer.read_fleet() == _info((record,))
    assert newer.read_fleet().agent(1) == record
    with pytest.raises(FleetError, match="no agent for robot 0"):
        newer.read_fleet().agent(0)
    assert latest_run_dir(tmp_path) == newer.path
    with pytest.raises(FleetError, match="no fleet run directory"):
        latest_run_dir(tmp_path / "none")
    with pytest.raises(FleetError, match="not a fleet run directory"):
        RunDir(tmp_path / "none").read_fleet()


def _sleeper(ignore_term: bool = False) -> subprocess.Popen[bytes]:
    code = ("import signal, time\n"
            + ("signal.signal(signal.SIGTERM, signal.SIG_IGN)\n" if ignore_term else "")
            + "print('ready', flush=True)\ntime.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
    assert proc.stdout is not None and proc.stdout.readline() == b"ready\n"
    return proc


def _record(proc: subprocess.Popen[bytes], name: str, role: str,
            robot: int | None = None) -> ProcessRecord:
    return ProcessRecord(name, role, proc.pid, start_ticks(proc.pid), robot=robot)


def test_pid_identity_survives_only_for_the_same_process() -> None:
    proc = _sleeper()
    try:
        record = _record(proc, "x", "agent")
        assert is_running(record)
        reused = ProcessRecord("x", "agent", proc.pid, (record.started or 0) + 1)
        assert not is_running(reused)  # same pid, another start time: not ours
    finally:
        proc.kill()
        proc.wait()
    assert not is_running(record)


def test_check_port_free_sees_a_listener() -> None:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        sock.listen()
        port = sock.getsockname()[1]
        with pytest.raises(FleetError, match="already in use"):
            check_port_free(f"tcp/127.0.0.1:{port}")
    check_port_free(f"tcp/127.0.0.1:{port}")


def test_kill_and_down_on_stand_in_processes(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    agent0, agent1, stubborn = _sleeper(), _sleeper(), _sleeper(ignore_term=True)
    procs = [agent0, agent1, stubborn]
    try:
        run_dir = RunDir(tmp_path).create()
        run_dir.write_fleet(_info((_record(agent0, "agent-0", "agent", 0),
                                   _record(agent1, "agent-1", "agent", 1),
                                   _record(stubborn, "simhw", "simhw"))))
        args = argparse.Namespace(robot=1, hw=False, run_dir=tmp_path)
        assert cmd_kill.run(args) == 0
        assert agent1.wait(10) == -signal.SIGKILL
        # already gone: a one-line error from the dispatcher
        assert cli_main(["kill", "1", "--run-dir", str(tmp_path)]) == 2
        assert "not running" in capsys.readouterr().err
        assert cmd_down.run(argparse.Namespace(run_dir=tmp_path, timeout=1.0)) == 0
        assert agent0.wait(10) == -signal.SIGTERM
        assert stubborn.wait(10) == -signal.SIGKILL
        assert "needed SIGKILL: ['simhw']" in capsys.readouterr().out
        assert cmd_down.run(argparse.Namespace(run_dir=tmp_path, timeout=1.0)) == 0
        assert "not running" in capsys.readouterr().out
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()


def test_a_router_that_starts_late_is_waited_for_and_a_missing_one_is_not_forever(
        free_port: int) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port}"
    waits: list[float] = []
    started = time.monotonic()
    assert not router_answers_within(endpoint, 0.6, lambda: waits.append(time.monotonic()))
    assert len(waits) == 1 and waits[0] - started < 0.5  # said at once, once
    assert time.monotonic() - started >= 0.6

    listener = socket.socket()
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)

    def listen_late() -> None:
        time.sleep(0.5)
        listener.bind(("127.0.0.1", free_port))
        listener.listen()

    late = threading.Thread(target=listen_late)
    late.start()
    try:
        waits.clear()
        assert router_answers_within(endpoint, 10.0, lambda: waits.append(time.monotonic()))
        assert len(waits) == 1
    finally:
        late.join()
        listener.close()
