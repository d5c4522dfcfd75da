"""Starting and stopping fleet processes (router aside: see conftest.router) for the
end-to-end tests of the offline and ORMSTC agents."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import AsyncIterator, Iterable, Sequence
from contextlib import asynccontextmanager
from pathlib import Path
from typing import IO

from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.router import stop_process
from planner.types import SubCell


def mstc(*argv: str) -> list[str]:
    """The command line of ``mstc ARGV...`` run by this interpreter."""
    return [sys.executable, "-m", "deploy.cli", *argv]


def robots_arg(starts: Sequence[SubCell]) -> str:
    return ";".join(f"{r},{c}" for r, c in starts)


def write_room(directory: Path, rows: Sequence[str]) -> Path:
    """An ASCII map file of ``rows`` ('.' free, '#' blocked)."""
    path = directory / "room.txt"
    path.write_text("\n".join(rows) + "\n")
    return path


def start_simhw(world: Path, starts: Sequence[SubCell], router: str, mission: str,
                time_scale: float, *extra: str, stdout: int | IO[str] | None = subprocess.PIPE,
                stderr: int | IO[str] | None = subprocess.PIPE) -> subprocess.Popen[str]:
    return subprocess.Popen(
        mstc("simhw", "--world", str(world), "--robots", robots_arg(starts),
             "--time-scale", str(time_scale), *extra, "--connect", router,
             "--mission", mission),
        stdin=subprocess.DEVNULL, stdout=stdout, stderr=stderr, text=True)


def stop_processes(procs: Iterable[subprocess.Popen[str]]) -> None:
    """Stop each process still running (SIGTERM, SIGKILL after 10 s) and close its pipes."""
    for proc in procs:
        stop_process(proc, timeout=10.0)


@asynccontextmanager
async def mission_bus(router: str, mission: str) -> AsyncIterator[Bus]:
    """The test's own session on ``mission``, through ``router``."""
    async with Bus.connect(ConnectionSettings(connect=(router,), mission=mission)) as bus:
        yield bus
