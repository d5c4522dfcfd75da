"""Robustness under faults (deploy.chaos): a test per phase of death and per fault kind, on
real fleets (router, simhw, agents on 127.0.0.1), and a CI-sized campaign.

Each trial is judged as ``mstc chaos`` judges it: simhw's ground truth (summary.json) must
say the mission completed, and the recording must pass ``mstc report``'s invariants.
"""

from __future__ import annotations

import asyncio
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agent.core.config import DEFAULT_BOOT_TIMEOUT
from deploy.chaos.campaign import not_injected, rerun_command, table
from deploy.chaos.inject import Injector, RouterProcess
from deploy.chaos.partition import partition_problem, tcp_ports
from deploy.chaos.schedule import SCENARIOS, TOO_LATE, Campaign, Fault, Trial, make_trial
from deploy.chaos.trial import (
    TRIAL_TIMEOUT_S,
    Outcome,
    judge,
    ordered_deaths,
    run_trial,
    trial_timeout,
    up_argv,
)
from deploy.chaos.victims import busy_at, busy_robots
from deploy.cli import build_parser
from deploy.fleet import ProcessRecord, is_running, start_ticks
from planner.maps import BUILTIN_WORLDS, resolve_world


def test_trials_are_a_function_of_the_campaign_and_the_index() -> None:
    campaign = Campaign(seed=5)
    trials = [make_trial(campaign, i) for i in range(len(SCENARIOS) * 3)]
    assert trials == [make_trial(campaign, i) for i in range(len(SCENARIOS) * 3)]
    assert {t.scenario for t in trials} == set(SCENARIOS)
    for trial in trials:
        victims = {f.robot for f in trial.faults if f.kind == "kill"}
        assert len(victims) < max(trial.robots, 2), "one robot at least is left"
    assert make_trial(Campaign(seed=6), 1) != make_trial(campaign, 1)


def test_a_late_death_is_ordered_from_mstc_up_at_a_share_of_the_coverage(
        tmp_path: Path) -> None:
    """Deaths at 20-90 % coverage, whatever the world's size (fault times in seconds all fall
    in a large world's first part): ``mstc up`` orders them (--kill, --kill-hw), the injector
    does not, and the campaign reads from up.log whether they were carried out."""
    campaign = Campaign(seed=9, worlds=("office", "cave"), sizes=(1, 3, 4))
    trials = [make_trial(campaign, i) for i in range(len(SCENARIOS) * 20)]
    late = [t for t in trials if t.scenario == "late-death"]
    assert {t.robots for t in late} >= {1, 3}
    kinds = set()
    for trial in late:
        if trial.robots == 1:
            assert trial.faults == (), "the one robot must live"
            continue
        (fault,) = trial.faults
        assert fault.by_coverage and fault.percent is not None
        assert 20.0 <= fault.percent <= 90.0
        kinds.add(fault.kind)
        assert trial.killed == {fault.robot}, "so its loss is no false suspicion"
        argv = up_argv(trial, "tcp/127.0.0.1:1", tmp_path, tmp_path / "r.jsonl")
        flag = "--kill" if fault.kind == "kill" else "--kill-hw"
        assert argv[argv.index(flag) + 1] == f"{fault.robot}@progress={fault.percent:g}"
        order = build_parser().parse_args(argv[argv.index("up"):])
        assert len(order.kill) + len(order.kill_hw) == 1
    assert kinds == {"kill", "body-fail"}
    assert not any(f.by_coverage for t in trials if t.scenario != "late-death" for f in t.faults)

    kill = Fault("kill", 0.0, 2, percent=45.5)
    fail = Fault("body-fail", 0.0, 1, percent=70.0)
    trial = _trial("opt", 4, kill, fail, scenario="late-death")
    said = ordered_deaths(trial, "[   3.1s] SIGKILL agent 2 at 45.5 %: done (coverage 45.6 %)\n"
                                 "  not carried out (the mission ended first): fail body of 1 at "
                                 "70 %\n")
    assert said == ["kill robot 2 at 45.5 % coverage: done (coverage 45.6 %)",
                    "body-fail robot 1 at 70 % coverage: not carried out (the mission ended "
                    "first)"]
    assert ordered_deaths(trial, "")[0].endswith("not carried out (mstc up does not say it was)")
    # done with every sub-cell covered (seed 6021, trial 13): no death was survived
    after = ordered_deaths(trial, "[   2.0s] SIGKILL agent 2 at 45.5 %: done (coverage 100.0 %)")
    assert after[0] == ("kill robot 2 at 45.5 % coverage: done (coverage 100.0 %); too late: "
                       "the mission was complete")
    assert not_injected(Outcome(trial, "ok", "", 1.0, injected=after[:1]))
    assert not_injected(Outcome(trial, "ok", "", 1.0, injected=said))
    assert not not_injected(Outcome(trial, "ok", "", 1.0, injected=said[:1]))


def test_busy_robots_are_those_with_uncovered_sub_cells_ahead_at_the_ordered_count() -> None:
    # lockstep: step 0 covers the starts, step s each robot's s-th sub-cell
    short = [(0, 0), (0, 1)]
    long = [(5, 0), (5, 1), (5, 2), (5, 3), (5, 4), (5, 5)]
    back = [(9, 0), (9, 1), (9, 2), (9, 1), (9, 0)]  # walks back over its own sub-cells
    assert busy_robots([short, long, back], 3) == (0, 1, 2)  # step 0: all three ahead
    assert busy_robots([short, long, back], 6) == (1, 2)  # step 1: short is done
    assert busy_robots([short, long, back], 7) == (1,)  # step 2: back only walks back
    assert busy_robots([short, long, back], 10) == (1,)  # 10 distinct by step 4
    assert busy_robots([short, long, back], 11) == ()  # the last one: nothing is ahead
    assert busy_robots([short, long, back], 12) == ()  # never that many
    # a sub-cell ahead that another robot covered first is no work left
    crossing = [(5, 5), (5, 4)]
    assert busy_robots([long, crossing], 5) == (0,)


def test_a_late_death_takes_a_robot_that_has_work_left_by_the_plan() -> None:
    """Drawn at random, 8 of 20 late deaths of campaign 6104 and 5 of 20 of 6105 found
    their robot idle. For offline plans the victim is drawn among the robots the plan's
    lockstep replay still has covering at the ordered share."""
    campaign = Campaign(seed=6105, worlds=("office", "cave", "grid30x20"),
                        algos=("nb", "bt", "opt", "balanced", "ormstc"), sizes=(3, 5, 7, 9),
                        scenarios=("late-death",))
    trials = [make_trial(campaign, i) for i in range(24)]
    narrowed = 0
    for trial in trials:
        (fault,) = trial.faults
        assert fault.percent is not None and fault.robot is not None
        busy = busy_at(trial.world, trial.algo, trial.robots, trial.seed, fault.percent)
        if trial.algo == "ormstc":
            assert busy == ()
            continue
        assert fault.robot in busy, trial.describe()
        narrowed += len(busy) < trial.robots
    assert narrowed >= 3, "some plans leave robots idle by then: the draw must avoid them"
    # a mission mstc up refuses is the trial's to record (LOST, with mstc up's message), not
    # a traceback of the campaign's
    (refused,) = make_trial(Campaign(worlds=("maze:5x5:1",), algos=("nb",), sizes=(200,),
                                     scenarios=("late-death",)), 0).faults
    assert refused.robot is not None and 0 <= refused.robot < 200


async def test_no_fault_is_carried_out_once_the_mission_is_covered(tmp_path: Path) -> None:
    """A robot lingers after the mission ends, so its process is there to kill: such a kill
    tested nothing and was recorded as survived (seed 6023, trial 16). Once mstc up says every
    sub-cell is covered, faults are recorded as too late (late faults) and not carried out."""
    up_log = tmp_path / "up.log"
    up_log.write_text("[   0.7s] mission started: all robots up\n")
    (tmp_path / "run" / "pids").mkdir(parents=True)
    lingering = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (tmp_path / "run" / "pids" / "agent-1.pid").write_text(f"{lingering.pid} 0\n")
        injector = Injector(RouterProcess("tcp/127.0.0.1:1", tmp_path / "router.log"),
                            tmp_path / "run", up_log)
        up_log.write_text(up_log.read_text() + "[   3.1s] every reachable sub-cell covered\n")
        await injector.apply(Fault("kill", 0.0, 1))
        await injector.apply(Fault("router-freeze", 0.0, None, 0.5))
        with pytest.raises(subprocess.TimeoutExpired):  # the lingering robot was not killed
            lingering.wait(0.5)
        assert injector.done == ["kill robot 1 at 0.0 s: too late: the mission was complete",
                                 "router-freeze router at 0.0 s for 0.5 s: too late: the "
                                 "mission was complete"]
        assert not_injected(Outcome(_trial("nb", 3), "ok", "", 1.0, injected=injector.done))
    finally:
        lingering.kill()
        lingering.wait()


async def test_a_fault_on_an_ended_or_reused_pid_is_not_carried_out(tmp_path: Path) -> None:
    """An agent's pid file outlives it until the fleet stops: a signal to its pid was lost
    (or would hit whatever process has the pid now) and was recorded as done."""
    (tmp_path / "run" / "pids").mkdir(parents=True)
    ended = subprocess.Popen([sys.executable, "-c", "pass"])
    ended.wait()
    stranger = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        started = start_ticks(stranger.pid)
        assert started is not None
        pids = tmp_path / "run" / "pids"
        (pids / "agent-1.pid").write_text(f"{ended.pid} 0\n")
        # the stranger under a pid file of another process's start: a reused pid
        (pids / "agent-2.pid").write_text(f"{stranger.pid} {started - 1}\n")
        (pids / "agent-3.pid").write_text(f"{stranger.pid} {started}\n")
        injector = Injector(RouterProcess("tcp/127.0.0.1:1", tmp_path / "router.log"),
                            tmp_path / "run")
        await injector.apply(Fault("kill", 0.0, 1))
        await injector.apply(Fault("kill", 0.0, 2))
        with pytest.raises(subprocess.TimeoutExpired):  # the process that has the pid now
            stranger.wait(0.5)                          # was spared
        await injector.apply(Fault("kill", 0.0, 3))
        assert stranger.wait(5.0) == -signal.SIGKILL
        assert injector.done == ["kill robot 1 at 0.0 s: no such process",
                                 "kill robot 2 at 0.0 s: no such process",
                                 "kill robot 3 at 0.0 s"]
    finally:
        stranger.kill()
        stranger.wait()


@pytest.mark.parametrize("world", sorted(BUILTIN_WORLDS))
def test_a_trial_s_limit_leaves_a_lone_survivor_time_to_finish(world: str) -> None:
    """A trial whose team is killed down to one robot is not lost for the campaign's clock:
    one ORMSTC survivor covered about 8 sub-cells/s (chaos seed 4247, grid30x20, where the
    fixed 120 s cut it off at 36 %), so the limit allows it the whole world, and never less
    than the fixed limit."""
    trial = Trial(0, 1, world, "ormstc", 4, "kills", (), "")
    free = int(resolve_world(world).free.sum())
    assert trial_timeout(trial) >= max(TRIAL_TIMEOUT_S, free / 8)
    assert judge(trial, Path("/nonexistent"), None, 1.0, []).detail == \
        f"mstc up did not end in {trial_timeout(trial):g} s"


def test_a_default_campaign_draws_every_grid_fleet_algorithm_the_cli_offers() -> None:
    # the benchmark builds its Campaign without the CLI: one default for both
    offered = build_parser().parse_args(["chaos"])
    assert Campaign().algos == tuple(offered.algos.split(","))
    assert {"nb", "bt", "opt", "balanced", "ormstc"} <= set(Campaign().algos)
    drawn = {make_trial(Campaign(seed=8), i).algo for i in range(200)}
    assert drawn == set(Campaign().algos)


@pytest.mark.parametrize(("args", "says"), [
    (["--worlds", "nosuch"], "--worlds: nosuch: neither a builtin world"),
    (["--worlds", "office,maze:4x4:1"], "--worlds: maze:4x4:1: a maze has odd sides"),
    (["--worlds", ","], "--worlds: name at least one world"),
    (["--trials", "0"], "--trials: at least 1"),
    (["--only", "-1"], "--only: a trial index"),
    (["--algos", "nosuch"], "--algos: 'nosuch' is not a grid fleet algorithm"),
    (["--sizes", "0"], "--sizes: team sizes are >= 1"),
])
def test_a_campaign_s_mistakes_are_said_before_anything_runs(
        args: list[str], says: str, tmp_path: Path) -> None:
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-m", "deploy.cli", "chaos", *args, "--out",
                          str(tmp_path / "out")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2, out.stdout + out.stderr
    assert says in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "out").exists()


def test_a_failing_trial_s_command_re_runs_that_trial_alone(tmp_path: Path) -> None:
    campaign = Campaign(seed=3, algos=("nb", "ormstc"), sizes=(2, 3))
    command = rerun_command(campaign, 7, tmp_path)
    args = build_parser().parse_args(command.split()[1:])
    assert args.only == 7 and args.seed == 3 and args.algos == "nb,ormstc"
    outcome = Outcome(make_trial(campaign, 7), "lost", "stalled", 1.0)
    assert "lost" in table([outcome]).splitlines()[0]


def test_a_campaign_names_its_failures_then_its_false_suspicions_each_with_a_re_run(
        tmp_path: Path) -> None:
    from deploy.chaos.campaign import closing_lines

    campaign = Campaign(seed=3, algos=("nb", "ormstc"), sizes=(2, 3))
    clean = Outcome(make_trial(campaign, 1), "ok", "", 1.0)
    suspected = Outcome(make_trial(campaign, 2), "ok", "", 1.0, robots_lost=[0],
                        false_suspicions=[0])
    lost = Outcome(make_trial(campaign, 5), "lost", "stalled", 1.0)
    lines = closing_lines(campaign, [clean, suspected, lost], tmp_path)
    assert len(lines) == 4
    assert lines[0].startswith("LOST trial 5 (") and lines[0].endswith(": stalled")
    assert lines[2].startswith("FALSE SUSPICION in trial 2 (") and "robots [0]" in lines[2]
    assert str(tmp_path / "trial-2" / "run" / "summary.json") in lines[2]
    for line, index in ((lines[1], 5), (lines[3], 2)):
        args = build_parser().parse_args(line.split("re-run: ")[1].split()[1:])
        assert args.only == index and args.seed == 3
    assert closing_lines(campaign, [clean], tmp_path) == []


async def test_a_campaign_runs_at_most_jobs_trials_at_once_and_a_host_starver_alone(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import asyncio

    from deploy.chaos import campaign as campaign_module

    running: list[Trial] = []
    seen: list[tuple[int, bool]] = []  # (trials running, a host starver among them)

    async def fake_trial(trial: Trial, workdir: Path) -> Outcome:
        running.append(trial)
        seen.append((len(running), any(campaign_module.exclusive(t) for t in running)))
        # Long enough that the next trials are started before this one ends (each is made
        # in a thread: a late death's trial plans its mission).
        await asyncio.sleep(0.2)
        running.remove(trial)
        return Outcome(trial, "ok", "", 0.0)

    monkeypatch.setattr(campaign_module, "run_trial", fake_trial)
    campaign = Campaign(seed=4, scenarios=("none", "kill", "hang", "starve-host"))
    lines: list[str] = []
    outcomes = await campaign_module.run_campaign(campaign, range(12), tmp_path, lines.append,
                                                  jobs=3)
    assert sorted(o.trial.index for o in outcomes) == list(range(12)) and len(lines) == 12
    assert (tmp_path / "trials.jsonl").read_text().count("\n") == 12
    assert max(n for n, _ in seen) == 3, seen  # side by side, never more than three
    assert all(n == 1 for n, starver in seen if starver), seen  # the starver alone
    assert sum(starver for _, starver in seen) == 3


@pytest.mark.integration
@pytest.mark.skipif(shutil.which("setpriv") is None, reason="no setpriv (util-linux) here")
def test_a_killed_campaign_leaves_no_busy_process_spinning() -> None:
    # The campaign's process is killed (SIGKILL: no cleanup runs) during a starve-host fault.
    script = ("import sys, time\n"
              "from deploy.chaos.inject import busy_processes\n"
              "print(*(p.pid for p in busy_processes(2)), flush=True)\n"
              "time.sleep(60)\n")
    campaign = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                                text=True)
    assert campaign.stdout is not None
    hogs = [ProcessRecord(f"busy-{pid}", "busy", int(pid), start_ticks(int(pid)))
            for pid in campaign.stdout.readline().split()]
    try:
        assert len(hogs) == 2 and all(is_running(hog) for hog in hogs)
        campaign.kill()
        campaign.wait(10)
        deadline = time.monotonic() + 10.0
        while any(is_running(hog) for hog in hogs) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not any(is_running(hog) for hog in hogs), "a busy process outlived the campaign"
    finally:
        campaign.kill()
        for hog in hogs:
            if is_running(hog):
                os.kill(hog.pid, signal.SIGKILL)


def test_a_robot_cut_off_past_the_lease_is_no_false_suspicion(tmp_path: Path) -> None:
    import json

    from deploy.chaos.campaign import load_outcomes
    from deploy.chaos.schedule import DEATH_HANG_S
    from deploy.chaos.trial import classify_deaths

    short, long = DEATH_HANG_S - 0.05, DEATH_HANG_S + 0.05
    cases = [  # faults, robots declared dead -> (false suspicions, cut-off deaths)
        ((Fault("partition", 1.0, 1, long),), [1], ([], [1])),
        ((Fault("partition", 1.0, 1, short),), [1], ([1], [])),
        ((Fault("partition", 1.0, 1, long),), [0], ([0], [])),  # only the one cut off
        ((Fault("router-freeze", 1.0, None, long),), [0, 2], ([], [0, 2])),
        ((Fault("router-freeze", 1.0, None, short),), [2], ([2], [])),
        ((Fault("router-kill", 1.0, None, long),), [2], ([2], [])),  # sessions come back
        ((Fault("kill", 1.0, 0), Fault("partition", 1.0, 0, long)), [0], ([], [])),
        ((Fault("hang", 1.0, 2, long),), [2], ([], [])),
    ]
    lines = []
    for faults, lost, (false, cut_off) in cases:
        outcome = Outcome(_trial("bt", 3, *faults), "ok", "", 1.0, robots_lost=lost)
        classify_deaths(outcome)
        assert (outcome.false_suspicions, outcome.cut_off_deaths) == (false, cut_off), faults
        # a file written by the older rule (everything not killed was a false suspicion)
        # is tabulated by today's
        old = outcome.to_json()
        old.pop("cut_off_deaths")
        old["false_suspicions"] = [r for r in lost if r not in outcome.trial.killed]
        lines.append(json.dumps(old))
    (tmp_path / "trials.jsonl").write_text("\n".join(lines) + "\n")
    loaded = load_outcomes(tmp_path / "trials.jsonl")
    assert [(o.false_suspicions, o.cut_off_deaths) for o in loaded] == [c[2] for c in cases]
    header, *_, total = table(loaded).splitlines()
    names = [name.strip() for name in header.split("  ") if name.strip()]
    columns = dict(zip(names, total.split(), strict=True))
    assert (columns["false susp."], columns["cut-off deaths"]) == ("4", "3"), columns


def test_a_completed_mission_whose_recording_has_a_gap_record_is_ok(tmp_path: Path) -> None:
    import json

    from test_monitor_fixtures import M, open_room, run_mission, two_robot_walks

    from bus import keys
    from bus.messages import SCHEMA_VERSION, CoverEvent
    from deploy.monitor.recorder import RecordWriter
    from deploy.monitor.types import Gap, Header, Record

    records = run_mission(open_room(), two_robot_walks()).records
    covers = [i for i, r in enumerate(records)
              if isinstance(r.msg, CoverEvent) and r.msg.robot == 1]
    kept = [r for i, r in enumerate(records) if i not in covers[3:6]]
    gap = Gap(keys.sim_cover(M, 1), "sim/cover", 3, records[covers[2]].t, records[covers[6]].t)
    with RecordWriter(tmp_path / "recording.jsonl", Header(M, 0.0, "up", SCHEMA_VERSION)) as w:
        for record in [*kept, Record(gap.until, gap.key, gap, "gap")]:
            w.write(record)
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "summary.json").write_text(json.dumps({
        "complete": True, "coverage": 100.0, "makespan_moves": 15, "planned_makespan": 15,
        "robots_lost": [], "outcome": "complete"}))
    outcome = judge(_trial("nb", 2), tmp_path, 0, 1.0, [])
    assert outcome.verdict == "ok", outcome.report_failures
    assert outcome.recording_gaps == [f"{gap.key} {gap.since}..{gap.until} s (3 lost)"]
    header = table([outcome]).splitlines()[0].split("  ")
    assert "gap records" in header


def small_world(tmp_path: Path) -> str:
    """A 16 x 12 map with one wall: an ORMSTC mission of three robots is short on it."""
    world = tmp_path / "small.txt"
    world.write_text("\n".join(["................"] * 4 + ["....####........"] * 2
                               + ["................"] * 6) + "\n")
    return str(world)


def _trial(algo: str, k: int, *faults: Fault, messages: str = "",
           scenario: str = "test", world: str = "example") -> Trial:
    return Trial(0, 11, world, algo, k, scenario, faults, messages)


async def _judged(trial: Trial, tmp_path: Path, *, late_ok: bool = False) -> Outcome:
    outcome = await run_trial(trial, tmp_path / "trial")
    assert outcome.verdict == "ok", (outcome.detail, outcome.injected,
                                     (tmp_path / "trial" / "up.log").read_text()[-2000:])
    assert len(outcome.injected) == len(trial.faults), outcome.injected
    assert not any("no such process" in f or "never came" in f
                   or (TOO_LATE in f and not late_ok) for f in outcome.injected), \
        outcome.injected
    return outcome


PHASES = {
    # killed before its process could say anything: it never boots
    "before-announcing": Fault("kill", 0.0, 1),
    "while-gathering": Fault("kill", 0.0, 1, mark="gathering"),
    "while-planning": Fault("kill", 0.0, 1, mark="participants"),
    "while-moving": Fault("kill", 0.5, 1, mark="driving"),
    "after-completing": Fault("kill", 0.0, 1, mark="completed after"),
}


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.parametrize("phase", list(PHASES))
async def test_a_death_at_any_phase_is_survived(phase: str, tmp_path: Path) -> None:
    # An offline robot says "completed" once the whole area is covered (until then it
    # watches the robot ahead, to take over), so a kill at that line races the launcher's
    # own "every reachable sub-cell covered": alone, 3 of 8 runs of this phase found the
    # mission complete first (`a23b1fb`). Either way the verdict must be ok.
    outcome = await _judged(_trial("nb", 3, PHASES[phase]), tmp_path,
                            late_ok=phase == "after-completing")
    if phase == "after-completing" and not any(TOO_LATE in f for f in outcome.injected):
        assert 1 in outcome.robots_lost, outcome  # killed after it completed: no harm


@pytest.mark.integration
@pytest.mark.slow
async def test_a_death_while_taking_over_is_survived(tmp_path: Path) -> None:
    await _judged(_trial("bt", 3, Fault("kill", 0.3, 2, mark="driving"),
                         Fault("kill", 1.0, 1, mark="driving")), tmp_path)


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.parametrize(("kind", "algo"), [("kill", "balanced"), ("body-fail", "ormstc")])
async def test_a_death_at_a_share_of_the_coverage_is_survived(kind: str, algo: str,
                                                               tmp_path: Path) -> None:
    # ORMSTC walks `example` for 40 s; the share of the coverage is the subject, not the walk
    world = small_world(tmp_path) if algo == "ormstc" else "example"
    outcome = await _judged(_trial(algo, 3, Fault(kind, 0.0, 1, percent=60.0),
                                   scenario="late-death", world=world), tmp_path)
    (said,) = outcome.injected
    assert said.startswith(f"{kind} robot 1 at 60 % coverage: done (coverage "), said
    assert outcome.robots_lost == [1] and outcome.false_suspicions == []


@pytest.mark.integration
@pytest.mark.slow
async def test_ormstc_survives_a_robot_that_never_boots(tmp_path: Path) -> None:
    # The agreement is the subject, not the walk: a small world keeps the ORMSTC mission short
    # (two robots on `example` walk for 25 s after the 10 s boot timeout).
    outcome = await _judged(_trial("ormstc", 3, Fault("kill", 0.0, 2),
                                   world=small_world(tmp_path)), tmp_path)
    logs = (tmp_path / "trial" / "run" / "logs" / "agent-0.log").read_text()
    assert "robots [2] never announced a start and take no part" in logs
    assert "never announced a start" in (tmp_path / "trial" / "up.log").read_text(), \
        "the launcher says so too"
    assert outcome.complete


FAULTS = {
    "hang": (Fault("hang", 0.5, 1, 0.4, mark="driving"),),
    "long-hang": (Fault("hang", 0.3, 1, 4.5, mark="driving"),),
    "router-restart": (Fault("router-kill", 3.0, None, 0.8),),
    "router-freeze": (Fault("router-freeze", 3.0, None, 0.8),),
    # a robot let run 10 ms of every 100 ms for 3 s while it drives
    "starve": (Fault("starve", 0.3, 1, 3.0, mark="driving", share=0.1),),
}


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.parametrize("kind", list(FAULTS))
async def test_a_process_fault_is_survived(kind: str, tmp_path: Path) -> None:
    outcome = await run_trial(_trial("opt", 3, *FAULTS[kind]), tmp_path / "trial")
    # The mission completes by simhw's ground truth, and its recording, cut off by a router
    # fault, recovers what it missed (or marks it as a gap): no false failure.
    assert outcome.complete and outcome.verdict == "ok", outcome.detail
    assert outcome.injected, "the fault was carried out"


@pytest.mark.integration
@pytest.mark.slow
@pytest.mark.parametrize("algo", ["nb"])
async def test_message_loss_duplication_delay_and_reordering_are_survived(
        algo: str, tmp_path: Path) -> None:
    # ORMSTC under heavier loss (30 % of its messages, no double work, one owner per cell)
    # is tests/test_ormstc_fleet.py::test_lost_claims_and_edges_cause_no_double_work, and
    # the campaign's `loss` scenario (docs/chaos.md): a third run here cost CI 46 s.
    spec = "seed=4;*.drop=0.05;*.lose=0.05;*.dup=0.1;*.delay=0.05;*.reorder=0.1;window=0.1"
    await _judged(_trial(algo, 3, messages=spec), tmp_path)


@pytest.mark.integration
@pytest.mark.slow
async def test_a_partitioned_robot_heals_and_the_mission_completes(tmp_path: Path) -> None:
    problem = partition_problem()
    if problem is not None:
        pytest.skip(problem)
    outcome = await run_trial(_trial("nb", 3, Fault("partition", 0.5, 1, 1.5, mark="driving")),
                              tmp_path / "trial")
    assert outcome.complete, outcome.detail
    assert any("ports [" in line and "ports []" not in line for line in outcome.injected), \
        outcome.injected


# A robot's session to the router, as an agent holds one (bus.config: its lease, its
# reconnection pace), until killed.
_CLIENT = """
import sys, time
time.sleep(float(sys.argv[2]))
from bus.config import ConnectionSettings, open_session
with open_session(ConnectionSettings(connect=(sys.argv[1],))):
    print("connected", flush=True)
    time.sleep(600)
"""


async def _router_for_cuts(endpoint: str, tmp_path: Path) -> RouterProcess:
    """A router on ``endpoint``, started, for a partition test (skipped where iptables
    cannot be used)."""
    problem = partition_problem()
    if problem is not None:
        pytest.skip(problem)
    router = RouterProcess(endpoint, tmp_path / "router.log")
    await router.start()
    return router


@pytest.mark.integration
@pytest.mark.slow
async def test_a_partition_outlasts_the_lease_and_heals(tmp_path: Path, free_port: int) -> None:
    """The client gives up the cut link after its lease and connects again from a new
    port; the cut refuses that too, so no new connection exists while it lasts (a new one
    came 1.2 s into the cut before), and one comes soon after the heal."""
    endpoint = f"tcp/127.0.0.1:{free_port}"
    router = await _router_for_cuts(endpoint, tmp_path)
    client = subprocess.Popen([sys.executable, "-c", _CLIENT, endpoint, "0"],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert client.stdout is not None
        assert await asyncio.to_thread(client.stdout.readline) == "connected\n"
        pids = tmp_path / "run" / "pids"
        pids.mkdir(parents=True)
        (pids / "agent-1.pid").write_text(f"{client.pid} 0\n")
        first = tcp_ports(client.pid, free_port)
        assert first
        injector = Injector(router, tmp_path / "run")
        seen: list[tuple[float, list[int]]] = []
        loop = asyncio.get_running_loop()
        cut_at = loop.time()

        async def watch() -> None:
            while loop.time() - cut_at < 7.0:
                seen.append((loop.time() - cut_at, tcp_ports(client.pid, free_port)))
                await asyncio.sleep(0.05)

        async with asyncio.TaskGroup() as group:
            group.create_task(injector.apply(Fault("partition", 0.0, 1, 3.0)))
            group.create_task(watch())
        assert injector.done == [f"partition robot 1 at 0.0 s for 3.0 s: ports {first}"]
        during = [ports for t, ports in seen if 1.5 <= t <= 2.9]
        assert during and all(set(ports) <= set(first) for ports in during), seen
        later = [ports for t, ports in seen if t >= 3.1 and set(ports) - set(first)]
        assert later, f"no new connection after the heal: {seen[-5:]}"
        assert not [line for line in _rules() if "mstc-partition-" in line]
    finally:
        client.kill()
        client.wait()
        router.kill()


@pytest.mark.integration
@pytest.mark.slow
async def test_a_partition_of_a_booting_robot_waits_for_its_connection(
        tmp_path: Path, free_port: int) -> None:
    """A robot with no connection yet is cut once it has one, and the record says how long
    that took; one that ends without ever connecting is recorded as not cut (counted among
    the late faults), never as cut (it was: "ports []")."""
    endpoint = f"tcp/127.0.0.1:{free_port}"
    router = await _router_for_cuts(endpoint, tmp_path)
    pids = tmp_path / "run" / "pids"
    pids.mkdir(parents=True)
    booting = subprocess.Popen([sys.executable, "-c", _CLIENT, endpoint, "1.0"],
                               stdout=subprocess.DEVNULL)
    never = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(0.5)"])
    try:
        (pids / "agent-1.pid").write_text(f"{booting.pid} 0\n")
        (pids / "agent-2.pid").write_text(f"{never.pid} 0\n")
        injector = Injector(router, tmp_path / "run")
        async with asyncio.TaskGroup() as group:
            group.create_task(injector.apply(Fault("partition", 0.0, 1, 0.5)))
            group.create_task(injector.apply(Fault("partition", 0.0, 2, 0.5)))
        cut, missed = sorted(injector.done)
        assert re.fullmatch(r"partition robot 1 at 0\.0 s for 0\.5 s: ports \[\d+\], "
                            r"after [1-9]\.\d s waiting for its connection", cut), cut
        assert missed == ("partition robot 2 at 0.0 s for 0.5 s: not carried out: robot 2 "
                          "had no connection to the router")
    finally:
        for process in (booting, never):
            process.kill()
            process.wait()
        router.kill()


def _rules() -> list[str]:
    return subprocess.run(["iptables", "-S"], capture_output=True, text=True,
                          check=True).stdout.splitlines()


@pytest.mark.integration
@pytest.mark.slow
async def test_a_ci_sized_campaign_loses_no_mission(tmp_path: Path) -> None:
    from deploy.chaos.campaign import run_campaign

    # Every scenario has a fixed test above except "kills" and "mixed"; the campaign adds
    # those, and the faults most often at fault before (deaths from start-up on, loss, a
    # router restart, a hang past the lease) at random times, robots and algorithms. The
    # whole list (host-wide starvation too) is benchmarks/bench_chaos.py's (docs/chaos.md):
    # a trial of each here made this the suite's longest test (77 s in a CI rehearsal).
    scenarios = ("kills", "mixed", "early-kill", "loss", "router-restart", "long-hang")
    assert set(scenarios) <= set(SCENARIOS)
    campaign = Campaign(seed=2, algos=("nb", "bt", "opt"), sizes=(2, 3), scenarios=scenarios)
    lines: list[str] = []
    # two at a time, as operators run it (docs/chaos.md): its trials share the host with
    # each other and with the other test worker
    outcomes = await run_campaign(campaign, range(6), tmp_path, lines.append, jobs=2)
    assert len(lines) == 6 and (tmp_path / "trials.jsonl").read_text().count("\n") == 6
    assert {o.trial.scenario for o in outcomes} == set(scenarios)
    lost = [(o.trial.describe(), o.detail) for o in outcomes if o.verdict in ("lost", "double")]
    assert not lost, lost


@pytest.mark.integration
@pytest.mark.slow
async def test_a_robot_heard_after_the_agreement_takes_no_part(tmp_path: Path) -> None:
    # Robot 2 is stopped as it boots, past the others' boot timeout: they agree without it
    # and declare its first life dead; when it wakes it stands down (or fences itself).
    # The others' boot clock starts once each is connected, up to a few seconds after robot
    # 2 was stopped on a loaded machine, and robot 2 needs ~0.5 s after waking to announce:
    # a hang of 10.5 s (boot timeout + 0.5) let it be heard in time in one full run
    # (participants [0, 1, 2]), so the stop outlasts the timeout by 3 s.
    hang = DEFAULT_BOOT_TIMEOUT + 3.0
    outcome = await _judged(_trial("bt", 3, Fault("hang", 0.0, 2, hang)), tmp_path)
    logs = tmp_path / "trial" / "run" / "logs"
    assert "robots [2] never announced a start" in (logs / "agent-0.log").read_text()
    late = (logs / "agent-2.log").read_text()
    # it may not even have reached the bus before the mission ended
    assert "driving" not in late, late
    if "body at" in late:
        assert "stands down" in late or "declared dead" in late, late
    assert outcome.complete
