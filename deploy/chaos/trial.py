"""One chaos trial: a router of its own, ``mstc up --connect`` to it with the trial's
message faults in the agents' environment, the process faults injected on schedule, and the
verdict from simhw's ground truth (summary.json) and from the recording (``mstc report``).

Verdicts: ``ok``; ``lost`` (ground truth: the mission did not cover everything although a
robot was left); ``gap`` (the mission completed but its recording says otherwise: data lost
on the way, not a failure: what the recorder could not recover is a gap record instead, and
the report fails nothing on it; ``recording_gaps`` lists those records); ``double`` (a
cell owned by two live robots, or a revisit the algorithm promises not to make, in the
recording); ``false_suspicions`` lists robots declared dead that no fault was meant to kill
and none cut off past the lease (``cut_off_deaths``: partitioned, or behind a frozen router,
long enough for the liveliness token to go, as by design).
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import re
import signal
import socket
import subprocess
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from bus.config import DEFAULT_LEASE_MS
from bus.faults import ENV as FAULTS_ENV
from deploy.chaos.inject import Injector, RouterProcess
from deploy.chaos.schedule import TOO_LATE, Trial
from deploy.fleet import ended_with_launcher, mstc_argv
from deploy.fleet_timing import DEFAULT_DEAD_AFTER_S
from deploy.settings import NOT_CARRIED_OUT, KillOrder
from planner.maps import resolve_world

TRIAL_TIMEOUT_S = 120.0
# A trial may last longer on a large world: one survivor covering it alone (most of its team
# killed) at ORMSTC's default claim window covered about 8 sub-cells/s (chaos seed 4247,
# grid30x20, docs/chaos.md), so twice that time per sub-cell.
LONE_ROBOT_S_PER_SUB_CELL = 0.25
# Report invariants that say two robots did the same work (not a gap in the data).
DOUBLE_WORK = ("no sub-cell covered twice", "no cell owned by two", "at most twice")


def trial_timeout(trial: Trial) -> float:
    """Seconds a trial's ``mstc up`` may run before the mission counts as lost."""
    free = int(resolve_world(trial.world).free.sum())
    return max(TRIAL_TIMEOUT_S, LONE_ROBOT_S_PER_SUB_CELL * free)


@dataclass
class Outcome:
    trial: Trial
    verdict: str
    detail: str
    wall_seconds: float
    complete: bool = False
    coverage: float = 0.0
    makespan: int = 0
    planned: int = 0
    robots_lost: list[int] = field(default_factory=list)
    false_suspicions: list[int] = field(default_factory=list)
    cut_off_deaths: list[int] = field(default_factory=list)
    report_failures: list[str] = field(default_factory=list)
    recording_gaps: list[str] = field(default_factory=list)
    injected: list[str] = field(default_factory=list)
    exit_code: int | None = None

    def to_json(self) -> dict[str, Any]:
        data = asdict(self)
        data["trial"] = self.trial.to_json()
        return data


def classify_deaths(outcome: Outcome) -> None:
    """Split the robots lost that no fault was meant to kill into cut-off deaths (by design:
    unreachable past the lease) and false suspicions (the rest)."""
    killed, cut_off = outcome.trial.killed, outcome.trial.cut_off
    unmeant = [r for r in outcome.robots_lost if r not in killed]
    outcome.cut_off_deaths = [r for r in unmeant if r in cut_off]
    outcome.false_suspicions = [r for r in unmeant if r not in cut_off]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def up_argv(trial: Trial, endpoint: str, run_dir: Path, record: Path) -> list[str]:
    deaths = [arg for f in trial.faults if f.by_coverage
              for arg in ("--kill" if f.kind == "kill" else "--kill-hw",
                          f"{f.robot}@progress={f.percent:g}")]
    return mstc_argv(
        "up", "-n", str(trial.robots), "--world", trial.world, "--algo", trial.algo,
        "--seed", str(trial.seed), "--time-scale", "0", "--plain", "--connect", endpoint,
        "--mission", f"chaos-{trial.index}-{trial.seed}", "--run-dir", str(run_dir),
        "--record", str(record), "--linger", "1", "--stall-timeout", "25",
        # the schedule's thresholds (DEATH_HANG_S, LONG_HANG_S) are these timers'; mstc up
        # would lengthen them for a dozen robots at time scale 0 (fleet_timing, flat out)
        "--lease-ms", str(DEFAULT_LEASE_MS), "--dead-after", f"{DEFAULT_DEAD_AFTER_S:g}",
        *deaths)


async def run_trial(trial: Trial, workdir: Path) -> Outcome:
    """Run ``trial`` in ``workdir`` (made here) and judge it."""
    workdir.mkdir(parents=True, exist_ok=True)
    run_dir, record = workdir / "run", workdir / "recording.jsonl"
    router = RouterProcess(f"tcp/127.0.0.1:{free_port()}", workdir / "router.log")
    began = time.monotonic()
    await router.start()
    injector = Injector(router, run_dir, workdir / "up.log")
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env.pop(FAULTS_ENV, None)
    if trial.messages:
        env[FAULTS_ENV] = trial.messages
    try:
        with (workdir / "up.log").open("wb") as out:
            # ended with this process: a campaign killed by SIGTERM left the trial's
            # fleet running (its router, a child of ours, gone with us)
            up = subprocess.Popen(ended_with_launcher(up_argv(trial, router.endpoint, run_dir,
                                                              record)),
                                  stdin=subprocess.DEVNULL, stdout=out,
                                  stderr=subprocess.STDOUT, env=env, start_new_session=True)
        t0 = time.monotonic()
        try:
            async with asyncio.timeout(trial_timeout(trial)), asyncio.TaskGroup() as group:
                for fault in trial.faults:
                    if not fault.by_coverage:  # those are mstc up's (up_argv)
                        group.create_task(_at(t0 + (0.0 if fault.mark else fault.at),
                                              injector, fault))
                code = await asyncio.to_thread(up.wait)
        except TimeoutError:
            await asyncio.to_thread(_stop, up)
            code = None
        except BaseException:  # Ctrl-C or a failed injection: leave no fleet behind
            _stop(up)
            raise
    finally:
        router.kill()
    # In a thread: `mstc report` takes a second or two, and other trials of the campaign
    # may be running on this loop.
    return await asyncio.to_thread(judge, trial, workdir, code, time.monotonic() - began,
                                   injector.done)


async def _at(when: float, injector: Injector, fault: Any) -> None:
    await asyncio.sleep(max(0.0, when - time.monotonic()))
    await injector.apply(fault)


def _stop(up: subprocess.Popen[bytes]) -> None:
    with contextlib.suppress(ProcessLookupError):
        os.killpg(up.pid, signal.SIGTERM)
    try:
        up.wait(15.0)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(up.pid, signal.SIGKILL)
        up.wait(5.0)


def judge(trial: Trial, workdir: Path, code: int | None, wall: float,
          injected: list[str]) -> Outcome:
    """The verdict of a finished trial from its summary.json and its recording."""
    outcome = Outcome(trial, "ok", "", round(wall, 2), exit_code=code,
                      injected=injected + ordered_deaths(trial, _read(workdir / "up.log")))
    summary_path = workdir / "run" / "summary.json"
    if code is None:
        outcome.verdict = "lost"
        outcome.detail = f"mstc up did not end in {trial_timeout(trial):g} s"
        return outcome
    try:
        summary = json.loads(summary_path.read_text())
    except (OSError, ValueError):
        outcome.verdict = "lost"
        outcome.detail = f"no summary.json (mstc up exit {code}): " + _tail(workdir / "up.log")
        return outcome
    outcome.complete = bool(summary["complete"])
    outcome.coverage = float(summary["coverage"])
    outcome.makespan = int(summary["makespan_moves"])
    outcome.planned = int(summary.get("planned_makespan") or 0)
    outcome.robots_lost = sorted(int(r["robot"]) for r in summary["robots_lost"])
    classify_deaths(outcome)
    report = subprocess.run(mstc_argv("report", "--json", str(workdir / "recording.jsonl")),
                            capture_output=True, text=True, check=False)
    try:
        judged = json.loads(report.stdout)
        invariants = judged["invariants"]
    except (ValueError, KeyError):
        judged = {}
        invariants = [{"name": "recording readable", "status": "failed",
                       "detail": report.stderr.strip()[-300:]}]
    outcome.recording_gaps = [f"{g['key']} {g['since']}..{g['until']} s ({g['missed']} lost)"
                              for g in judged.get("gaps", ())]
    outcome.report_failures = [f"{inv['name']}: {inv['detail']}" for inv in invariants
                               if inv["status"] == "failed"]
    if not outcome.complete:
        outcome.verdict = "lost"
        outcome.detail = f"{summary['outcome']} ({outcome.coverage:.1f} %)"
    elif any(any(mark in failure for mark in DOUBLE_WORK)
             for failure in outcome.report_failures):
        outcome.verdict = "double"
        outcome.detail = "; ".join(outcome.report_failures)
    elif outcome.report_failures:
        outcome.verdict = "gap"
        outcome.detail = "; ".join(outcome.report_failures)
    return outcome


def ordered_deaths(trial: Trial, up_log: str) -> list[str]:
    """What ``mstc up`` says of the deaths it was told to order (Fault.by_coverage): done
    (with the coverage it was done at) or not carried out, in the campaign's words."""
    out = []
    for fault in trial.faults:
        if not fault.by_coverage or fault.robot is None:  # make_trial gives these a robot
            continue
        order = KillOrder(fault.robot, percent=fault.percent,
                          hw=fault.kind != "kill").describe()
        lines = up_log.splitlines()
        done = next((line for line in lines if f"{order}: done" in line), None)
        if done is not None:
            said = f"{fault.describe()}: done{done.split(': done', 1)[1]}"
            # Done with every sub-cell covered (a body failure waits for simhw's answer,
            # and a short mission goes on meanwhile): no death was survived.
            at = re.search(r"\(coverage ([\d.]+) %\)", done)
            out.append(said + (f"; {TOO_LATE}" if at and float(at[1]) >= 100.0 else ""))
        elif any(line.strip().startswith(NOT_CARRIED_OUT) and order in line for line in lines):
            out.append(f"{fault.describe()}: not carried out (the mission ended first)")
        else:
            out.append(f"{fault.describe()}: not carried out (mstc up does not say it was)")
    return out


def _read(path: Path) -> str:
    with contextlib.suppress(OSError):
        return path.read_text(errors="replace")
    return ""


def _tail(path: Path, lines: int = 3) -> str:
    with contextlib.suppress(OSError):
        return " | ".join(path.read_text(errors="replace").strip().splitlines()[-lines:])
    return ""
