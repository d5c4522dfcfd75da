"""Which mission a monitor watches when it is not told: the runs that are live now.

Two sources, both asked again until one answers:
- run directories (``runs/*/fleet.json``): a run is live while its launcher process runs; a
  finished run (the one a monitor started before ``mstc up`` used to stay on) is not;
- the router: the robots' liveliness tokens (``mstc/<mission>/alive/<robot>/<life>``, the
  schema table's ``alive`` family) of every mission it carries, for a monitor started where
  no run directory is (another host, another directory). A router that enforces the
  credentials of one mission lets only that mission's roles in; there the run directory (or
  ``--credentials``) is what names the mission.

The newest live run is chosen; when there are several, they are listed so that the user
can pick another with ``--run-dir`` or ``--mission``.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass
from pathlib import Path

import zenoh

from bus import keys
from deploy.errors import FleetError
from deploy.fleet import LAUNCHER, RUNS_ROOT, FleetInfo, RunDir, is_running

LIVELINESS_TIMEOUT_S = 1.0


@dataclass(frozen=True)
class LiveRun:
    """A mission that is running: from a run directory, or heard on the router only."""

    mission: str
    run_dir: Path | None = None
    created: float = 0.0  # Unix time the launcher wrote fleet.json (0: heard on the router)
    robots: int = 0
    algo: str = ""

    def describe(self) -> str:
        where = f"run dir {self.run_dir}" if self.run_dir is not None else "on the router"
        what = f"{self.robots} robots" + (f", {self.algo}" if self.algo else "")
        return f"mission {self.mission} ({what}; {where})"


def run_of(run_dir: Path, info: FleetInfo) -> LiveRun:
    return LiveRun(info.mission, run_dir, info.created, info.robots, info.algo)


def live_runs(root: Path = RUNS_ROOT) -> list[LiveRun]:
    """The run directories under ``root`` whose launcher still runs, newest first."""
    runs = []
    for fleet_file in root.glob("*/fleet.json") if root.is_dir() else ():
        try:
            info = RunDir(fleet_file.parent).read_fleet()
        except FleetError:
            continue  # being written, or not a fleet's
        if any(p.role == LAUNCHER and is_running(p) for p in info.processes):
            runs.append(run_of(fleet_file.parent, info))
    return sorted(runs, key=lambda r: r.created, reverse=True)


def ended_run(root: Path = RUNS_ROOT) -> Path | None:
    """The newest run directory under ``root`` (live or not), to name what has ended."""
    fleets = list(root.glob("*/fleet.json")) if root.is_dir() else []
    return max(fleets, key=lambda p: p.stat().st_mtime).parent if fleets else None


def missions_on_router(session: zenoh.Session,
                       timeout: float = LIVELINESS_TIMEOUT_S) -> list[LiveRun]:
    """The missions whose robots hold liveliness tokens on the router (blocking: call it in
    a thread), the most robots first."""
    robots: dict[str, set[int]] = {}
    for reply in session.liveliness().get(keys.alive_in_every_mission(), timeout=timeout):
        sample = reply.ok
        parsed = None if sample is None else keys.parse(str(sample.key_expr))
        if parsed is not None and parsed.kind == "alive" and parsed.robot is not None:
            robots.setdefault(parsed.mission, set()).add(parsed.robot)
    return [LiveRun(mission, robots=len(ids))
            for mission, ids in sorted(robots.items(), key=lambda m: (-len(m[1]), m[0]))]


async def router_missions(session: zenoh.Session) -> list[LiveRun]:
    return await asyncio.to_thread(missions_on_router, session)


def choose(runs: list[LiveRun]) -> tuple[LiveRun | None, list[str]]:
    """The run to watch (the first: the newest, or the most robots) and, when there are
    several, lines that list them all."""
    if not runs:
        return None, []
    if len(runs) == 1:
        return runs[0], []
    lines = [f"{len(runs)} live missions:"] + [f"  {r.describe()}" for r in runs]
    lines.append(f"watching {runs[0].mission}; pick another with --run-dir DIR or "
                 f"--mission NAME")
    return runs[0], lines


def newer_run(current: LiveRun, runs: list[LiveRun], same_mission: bool) -> LiveRun | None:
    """A run started after ``current`` (of the same mission when ``same_mission``), to follow
    instead: the monitor stays with the newest run."""
    for run in runs:
        if run.run_dir != current.run_dir and run.created > current.created and (
                not same_mission or run.mission == current.mission):
            return run
    return None
