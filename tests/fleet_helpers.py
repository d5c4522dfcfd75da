"""Starting and stopping fleet processes (router aside: see conftest.router) for the
end-to-end tests of the offline and ORMSTC agents."""

from __future__ import annotations

import asyncio
import signal
import subprocess
import sys
from collections import defaultdict
from collections.abc import AsyncIterator, Callable, Iterable, Sequence
from contextlib import asynccontextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Literal

import numpy as np
from waiting import through_router, wait_until

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import ConnectionSettings
from bus.messages import CoverEvent, DeathNotice, Progress, RobotEvent, WorldState
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
        mstc("simhw", "--world", str(world), "--starts", robots_arg(starts),
             "--time-scale", str(time_scale), *extra, "--connect", router,
             "--mission", mission),
        stdin=subprocess.DEVNULL, stdout=stdout, stderr=stderr, text=True)


def stop_processes(procs: Iterable[subprocess.Popen[str]]) -> None:
    """Stop each process still running (SIGTERM, SIGKILL after 10 s) and close its pipes."""
    for proc in procs:
        stop_process(proc, timeout=10.0)


# The router of each open mission_bus, by mission: listen() probes through it.
_routers: dict[str, str] = {}


@asynccontextmanager
async def mission_bus(router: str, mission: str) -> AsyncIterator[Bus]:
    """The test's own session on ``mission``, through ``router``."""
    async with Bus.connect(ConnectionSettings(connect=(router,), mission=mission)) as bus:
        _routers[mission] = router
        try:
            yield bus
        finally:
            del _routers[mission]


async def all_heard(bus: Bus, walks: dict[int, list[SubCell]], timeout: float = 10.0) -> None:
    """Wait until ``walks`` (filled from the mission's CoverEvents) holds every sub-cell
    entry simhw logged, then until the router has passed on whatever else came before."""
    async def every_cover() -> bool:
        replies = await bus.query(keys.world(bus.mission), None, WorldState, timeout=5.0)
        return bool(replies) and all(len(walks.get(t.robot, ())) >= t.covered
                                     for t in replies[0].msg.robots)

    await wait_until(every_cover, timeout, "simhw's last cover events")
    await through_router(bus, _routers[bus.mission], timeout)


@dataclass
class Heard:
    """What a test heard on a mission's bus: simhw's ground truth (every sub-cell each body
    entered, in order) and the agents' progress, events, death notices and ORMSTC owners."""

    walks: dict[int, list[SubCell]] = field(default_factory=lambda: defaultdict(list))
    reported: dict[int, int] = field(default_factory=lambda: defaultdict(int))
    events: list[RobotEvent] = field(default_factory=list)
    deaths: list[DeathNotice] = field(default_factory=list)
    owners: dict[tuple[int, int], set[int]] = field(default_factory=lambda: defaultdict(set))

    def walking_takeovers(self) -> set[tuple[int, int | None]]:
        """(taker, dead) of every offline takeover that found sub-cells left to cover."""
        return {(e.robot, e.subject) for e in self.events
                if e.kind == "takeover_started" and e.detail.startswith("walking")}

    def takeovers_of(self, dead: int) -> set[int]:
        """Robots that announced a takeover (of any kind) of ``dead``."""
        return {e.robot for e in self.events if e.kind == "takeover_started"
                and e.subject == dead}

    def covered(self, shape: tuple[int, int]) -> np.ndarray:
        mask = np.zeros(shape, dtype=bool)
        for walk in self.walks.values():
            for r, c in walk:
                mask[r, c] = True
        return mask


async def listen(bus: Bus, heard: Heard) -> None:
    """Subscribe ``heard`` to its mission's ground truth and agent reports (call it before
    any fleet process starts)."""
    # Imported here so that the offline tests do not depend on the ORMSTC agent's modules.
    from agent.ormstc.wire import WIRE_TYPES
    from bus.messages import OrmstcStart, OrmstcTreeEdge, OrmstcWire

    m = bus.mission

    def on_cover(_key: str, msg: CoverEvent) -> None:
        heard.walks[msg.robot].append((msg.cell[0], msg.cell[1]))

    def on_progress(_key: str, msg: Progress) -> None:
        heard.reported[msg.robot] = max(heard.reported[msg.robot], msg.seq)

    def on_ormstc(_key: str, wire: OrmstcWire) -> None:
        if isinstance(wire, OrmstcTreeEdge):
            heard.owners[(wire.child[0], wire.child[1])].add(wire.robot)
        elif isinstance(wire, OrmstcStart):
            heard.owners[(wire.sub[0] // 2, wire.sub[1] // 2)].add(wire.robot)

    bus.subscribe(keys.all_sim_covers(m), CoverEvent, on_cover, BoundedFifo(65536))
    bus.subscribe(keys.all_progress(m), Progress, on_progress, BoundedFifo(65536))
    bus.subscribe(keys.all_events(m), RobotEvent, lambda _k, e: heard.events.append(e),
                  BoundedFifo(65536))
    bus.subscribe(keys.all_deaths(m), DeathNotice, lambda _k, d: heard.deaths.append(d),
                  BoundedFifo(65536))
    bus.subscribe(keys.all_ormstc(m), WIRE_TYPES, on_ormstc, BoundedFifo(65536))
    await through_router(bus, _routers[bus.mission])  # before anything is published


@dataclass
class LocalFleet:
    """simhw and one ``mstc agent`` per start, started by a test (the router is the test
    module's ``router`` fixture); each agent's stderr goes to ``logs/agent-<r>.err``."""

    world: Path
    starts: tuple[SubCell, ...]
    router: str
    mission: str
    logs: Path
    simhw: subprocess.Popen[str] | None = None
    agents: dict[int, subprocess.Popen[str]] = field(default_factory=dict)

    def start(self, algo: str, time_scale: float, *agent_args: str) -> None:
        self.simhw = start_simhw(self.world, self.starts, self.router, self.mission,
                                 time_scale, stdout=subprocess.DEVNULL,
                                 stderr=subprocess.DEVNULL)
        for robot in range(len(self.starts)):
            with self.stderr_path(robot).open("w") as err:
                self.agents[robot] = subprocess.Popen(
                    mstc("agent", "--id", str(robot), "--algo", algo, "--world",
                         str(self.world), "--robots", str(len(self.starts)),
                         "--connect", self.router, "--mission", self.mission, *agent_args),
                    stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err, text=True)

    def stderr_path(self, robot: int) -> Path:
        return self.logs / f"agent-{robot}.err"

    def kill(self, robot: int) -> None:
        """SIGKILL robot's agent: a fail-stop robot."""
        self.agents[robot].send_signal(signal.SIGKILL)

    async def finish(self, robots: Iterable[int], timeout: float) -> None:
        """Wait for ``robots`` to exit; every one must exit 0."""
        robots = list(robots)
        codes = [await asyncio.to_thread(self.agents[r].wait, timeout) for r in robots]
        assert codes == [0] * len(robots), {
            r: self.stderr_path(r).read_text()[-2000:] for r in robots}

    def stop(self) -> None:
        stop_processes([*self.agents.values(), *([self.simhw] if self.simhw else [])])


def fail_when(bus: Bus, count: Literal["progress", "cover"], due: dict[int, int],
              fail: Callable[[int], None]) -> None:
    """Call ``fail(robot)`` as soon as robot's ``count`` reaches ``due[robot]``, and remove
    it from ``due``. ``count`` is "progress" (the moves the agent reported) or "cover" (the
    sub-cells its body entered, start included, per simhw's ground truth). Call it before
    the fleet starts."""
    counts: dict[int, int] = dict.fromkeys(due, 0)

    def check(robot: int, reached: int) -> None:
        if robot in due and reached >= due[robot]:
            del due[robot]
            fail(robot)

    def on_progress(_key: str, msg: Progress) -> None:
        check(msg.robot, msg.seq)

    def on_cover(_key: str, msg: CoverEvent) -> None:
        if msg.robot in counts:
            counts[msg.robot] += 1
            check(msg.robot, counts[msg.robot])

    if count == "progress":
        bus.subscribe(keys.all_progress(bus.mission), Progress, on_progress, BoundedFifo(65536))
    elif count == "cover":
        bus.subscribe(keys.all_sim_covers(bus.mission), CoverEvent, on_cover,
                      BoundedFifo(65536))
    else:
        raise ValueError(f"count is 'progress' or 'cover', not {count!r}")
