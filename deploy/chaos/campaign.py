"""A campaign: trials one after another, a progress line each, a table at the end, one JSON
line per trial, and the one command that re-runs each failing trial alone."""

from __future__ import annotations

import asyncio
import functools
import json
import shlex
import statistics
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TextIO

from deploy.chaos.schedule import TOO_LATE, Campaign, Fault, Trial, make_trial
from deploy.chaos.trial import Outcome, classify_deaths, run_trial

VERDICTS = ("ok", "lost", "gap", "double")


def rerun_command(campaign: Campaign, index: int, out: Path) -> str:
    """The command line that runs trial ``index`` of ``campaign`` alone."""
    argv = ["mstc", "chaos", "--seed", str(campaign.seed), "--worlds", ",".join(campaign.worlds),
            "--algos", ",".join(campaign.algos),
            "--sizes", ",".join(str(k) for k in campaign.sizes),
            "--scenarios", ",".join(campaign.scenarios), "--only", str(index),
            "--out", str(out / f"rerun-{index}")]
    return shlex.join(argv)


def exclusive(trial: Trial) -> bool:
    """A trial that loads the whole host (one busy process per core) runs alone: beside other
    trials it would starve their fleets too, and its figures would not be its own."""
    return any(f.kind == "starve" and f.robot is None for f in trial.faults)


async def run_campaign(campaign: Campaign, indices: Iterable[int], out: Path,
                       say: Callable[[str], None], *, jobs: int = 1) -> list[Outcome]:
    """Run the trials, up to ``jobs`` at a time (each its own router, port and directory;
    a host-starving trial alone), appending each outcome to ``out/trials.jsonl`` as it ends."""
    if jobs < 1:
        raise ValueError("jobs must be >= 1")
    out.mkdir(parents=True, exist_ok=True)
    outcomes: list[Outcome] = []
    indices = list(indices)
    slots = asyncio.Condition()
    running = 0

    def fits(weight: int) -> bool:
        return running + weight <= jobs

    async def one(index: int, trial: Trial, weight: int, jsonl: TextIO) -> None:
        nonlocal running
        try:
            outcome = await run_trial(trial, out / f"trial-{index}")
        finally:
            async with slots:
                running -= weight
                slots.notify_all()
        outcomes.append(outcome)
        jsonl.write(json.dumps(outcome.to_json(), sort_keys=True) + "\n")
        jsonl.flush()
        lost = sum(o.verdict != "ok" for o in outcomes)
        say(f"[{len(outcomes)}/{len(indices)}] trial {index}: {trial.algo} k={trial.robots} "
            f"{trial.world} {trial.scenario}: {outcome.verdict.upper()} "
            f"({outcome.wall_seconds:.1f} s{'; ' + outcome.detail if outcome.detail else ''})"
            f" — {lost} not ok so far")

    with (out / "trials.jsonl").open("a") as jsonl:
        async with asyncio.TaskGroup() as group:
            for index in indices:
                # in a thread: a late death's trial plans its mission (deploy/chaos/victims.py),
                # seconds on a large world, while the loop injects the running trials' faults
                trial = await asyncio.to_thread(make_trial, campaign, index)
                weight = jobs if exclusive(trial) else 1
                async with slots:
                    await slots.wait_for(functools.partial(fits, weight))
                    running += weight
                group.create_task(one(index, trial, weight, jsonl))
    return outcomes


def closing_lines(campaign: Campaign, outcomes: list[Outcome], out: Path) -> list[str]:
    """What a campaign says after its table: each trial that was not ok, then each ok one
    with a false suspicion (not a lost mission, but what a campaign is there to find too),
    each with the command that re-runs it alone."""
    lines = []
    for o in sorted(outcomes, key=lambda o: (o.verdict == "ok", o.trial.index)):
        what = f"trial {o.trial.index} ({o.trial.algo} k={o.trial.robots} {o.trial.world}, " \
               f"{o.trial.describe()})"
        if o.verdict != "ok":
            lines.append(f"{o.verdict.upper()} {what}: {o.detail}")
        elif o.false_suspicions:
            summary = out / f"trial-{o.trial.index}" / "run" / "summary.json"
            lines.append(f"FALSE SUSPICION in {what}: robots {o.false_suspicions} declared "
                         f"dead though no fault was meant to kill or cut them off (who "
                         f"declared them: {summary})")
        else:
            continue
        lines.append(f"  re-run: {rerun_command(campaign, o.trial.index, out)}")
    return lines


def not_injected(outcome: Outcome) -> bool:
    """A fault fell after the mission's end (its target was gone, or every sub-cell was
    covered): the trial ran without it."""
    return any(mark in line for line in outcome.injected
               for mark in ("no such process", "never came", "not carried out", TOO_LATE))


def table(outcomes: list[Outcome]) -> str:
    """Per scenario and in all: trials, missions lost, recordings failing an invariant
    although the mission completed (gaps), double work, recordings holding gap records
    (what the recorder could not recover), false suspicions, robots declared dead while
    cut off past the lease (by design, not false suspicions), the makespan against the
    fault-free plan (median ratio) and trials whose faults fell after the mission had ended."""
    rows: list[tuple[str, ...]] = [
        ("scenario", "trials", "lost", "gaps", "double", "gap records", "false susp.",
         "cut-off deaths", "makespan/plan", "late faults")]
    by_scenario: dict[str, list[Outcome]] = {}
    by_algo: dict[str, list[Outcome]] = {}
    for o in outcomes:
        by_scenario.setdefault(o.trial.scenario, []).append(o)
        by_algo.setdefault(f"algo {o.trial.algo}", []).append(o)
    groups = {**by_scenario, **dict(sorted(by_algo.items())), "all": outcomes}
    for name, group in groups.items():
        ratios = [o.makespan / o.planned for o in group if o.complete and o.planned]
        rows.append((name, str(len(group)),
                     *(str(sum(o.verdict == v for o in group)) for v in VERDICTS[1:]),
                     str(sum(bool(o.recording_gaps) for o in group)),
                     str(sum(len(o.false_suspicions) for o in group)),
                     str(sum(len(o.cut_off_deaths) for o in group)),
                     f"{statistics.median(ratios):.2f}" if ratios else "-",
                     str(sum(not_injected(o) for o in group))))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(w) if i == 0 else cell.rjust(w)
                               for i, (cell, w) in enumerate(zip(row, widths, strict=True)))
                     for row in rows)


def load_outcomes(path: Path) -> list[Outcome]:
    """The outcomes of a trials.jsonl (to tabulate a campaign that was cut short)."""
    outcomes = []
    for line in path.read_text().splitlines():
        if not line.strip():
            continue
        data = json.loads(line)
        trial = dict(data.pop("trial"))
        trial["faults"] = tuple(Fault(**f) for f in trial["faults"])
        outcome = Outcome(trial=Trial(**trial), **data)
        classify_deaths(outcome)  # by today's rule, also for files written before it
        outcomes.append(outcome)
    return outcomes
