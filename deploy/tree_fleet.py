"""The launcher behind ``mstc tree-fleet``: router, radio and K tree agents on loopback.

Processes are started by a deploy.supervisor.Supervisor (their own sessions, logs and PID
files in the run directory, fleet.json for mstc kill / down / monitor) in the order router,
launcher's bus session (so no report is missed), radio, agents; the launcher then watches every
outbox through a TeamObserver and the agents' exit codes until all agents are done, one fails,
or nothing moves for ``stall_timeout`` seconds. Whatever ended the run, the supervisor stops
the agents first, then the radio, then the router.

An agent killed by a signal from outside (``mstc kill``) is a fail-stop robot like one of
``--kill``: the survivors repair the trail, and the run is judged against the lockstep run
with the same deaths.
"""

from __future__ import annotations

import asyncio
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import ConnectionSettings
from bus.messages import MissionStatus, RadioStats, TreeReport
from bus.router import READY_MARK as ROUTER_READY
from deploy.errors import FleetError
from deploy.fleet import Child, FleetInfo, RunDir, mstc_argv
from deploy.monitor.types import RecorderLink
from deploy.security import FleetSecurity
from deploy.settings import KillOrder
from deploy.supervisor import KillSchedule, Supervisor
from deploy.tree_observer import ObservedRun, TeamObserver
from planner.treecover.trees import tree_from_spec
from simhw.radio import READY_MARK as RADIO_READY

TICK_S = 0.1
SETTLE_S = 2.0
RECORDER_WAIT_S = 20.0  # as long as the router may take to say it is ready
# The router stays up at the end while a recorder that lags behind the launcher (it shares
# the launcher's loop and writes every message to disk) keeps writing, or until it has
# written nothing for this long.
RECORDER_CATCH_UP_S = 20.0


@dataclass(frozen=True)
class TreeFleetOptions:
    tree: str
    robots: int
    algo: str
    run_dir: Path
    mission: str
    endpoint: str | None = None  # None: a free port on 127.0.0.1
    lease_ms: int = 5000
    step_timeout: float = 10.0
    stall_timeout: float = 30.0
    dead_after: float = 5.0
    settle: float = 1.0  # how long a dead robot's last report may still be on its way
    kills: tuple[KillOrder, ...] = ()  # by step: SIGKILL the agent once that step is complete
    credentials: Path | None = None  # the mission's credentials (deploy.security); None: insecure


@dataclass(frozen=True)
class TreeFleetOutcome:
    ok: bool
    message: str
    observed: ObservedRun
    radio: RadioStats | None
    wall_seconds: float  # start-up of every process included
    mission_seconds: float | None  # first report to the report that completed coverage
    kills_left: tuple[str, ...] = ()  # --kill orders never carried out (ROBOT@STEP)


def free_endpoint() -> str:
    """A tcp endpoint on 127.0.0.1 whose port the OS says is free right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


class TreeFleet:
    """Starts, watches and stops one tree-coverage fleet."""

    def __init__(self, options: TreeFleetOptions, say: Callable[[str], None],
                 recorder: RecorderLink | None = None) -> None:
        self.options = options
        self.say = say
        # The launcher's recorder. Tree reports have no publisher cache (the radio relays
        # them), so a recorder that joined after the first step, or that the router left
        # before it caught up, would miss reports for good: the robots start only once it
        # listens, and the router stops only once it has written every report we heard.
        self.recorder = recorder
        self.endpoint = options.endpoint or free_endpoint()
        self.run_dir = RunDir(options.run_dir).create()
        self.supervisor = Supervisor(self.run_dir)
        self.kills = KillSchedule(options.kills)
        self.security = FleetSecurity(options.credentials)
        self.observer = TeamObserver(tree_from_spec(options.tree), options.robots)
        self.router: Child | None = None
        self.radio: Child | None = None
        self.agents: list[Child] = []
        self.killed: list[str] = []
        self.kill_ordered: list[int] = []  # robots killed by a --kill order, in order
        self.t0 = time.monotonic()
        self.first_report: float | None = None
        self.covered_at: float | None = None

    def _spawn(self, name: str, role: str, argv: list[str], robot: int | None = None) -> Child:
        return self.supervisor.spawn(name, role, argv, robot)

    def _connection(self) -> list[str]:
        o = self.options
        return ["--connect", self.endpoint, "--mission", o.mission, "--lease-ms",
                str(o.lease_ms), *self.security.child_args()]

    async def run(self) -> TreeFleetOutcome:
        o = self.options
        with self.supervisor.signals_stop():
            try:
                return await self._run(o)
            finally:
                self.supervisor.shutdown()

    async def _run(self, o: TreeFleetOptions) -> TreeFleetOutcome:
        self.router = self._spawn("router", "router", mstc_argv(
            "router", "--listen", self.endpoint, "--lease-ms", str(o.lease_ms),
            "--exit-with-parent", *self.security.child_args()))
        await self.supervisor.wait_ready(self.router, ROUTER_READY, 20.0)
        if self.recorder is not None:
            try:
                async with asyncio.timeout(RECORDER_WAIT_S):
                    await self.recorder.subscribed.wait()
            except TimeoutError:
                raise FleetError(f"the recorder did not connect to {self.endpoint} within "
                                 f"{RECORDER_WAIT_S:g} s") from None
        settings = self.security.operator(ConnectionSettings(
            connect=(self.endpoint,), mission=o.mission, lease_ms=o.lease_ms))
        async with Bus.connect(settings) as bus:
            bus.subscribe(keys.all_tree_outboxes(o.mission), TreeReport,
                          lambda _k, r: self._on_transmission(r),
                          BoundedFifo(1 << 20))
            await self._start(o)
            ok, message = await self._watch(lambda: self._announce(bus))
            self._announce(bus)  # once more: a short run may end before a recorder joined
            replies = await bus.query(keys.tree_radio(o.mission), None, RadioStats,
                                      timeout=2.0)
            await self._until_recorded()
        radio = replies[0].msg if replies else None
        mission = None if self.covered_at is None or self.first_report is None else \
            self.covered_at - self.first_report
        return TreeFleetOutcome(ok, message, self.observer.run(), radio,
                                time.monotonic() - self.t0, mission,
                                tuple(f"{k.robot}@{k.step}" for k in self.kills.pending))

    async def _until_recorded(self) -> None:
        """Keep the router up until the recorder has written every outbox report this
        launcher heard (both hear the same router), or say what the recording lacks."""
        if self.recorder is None:
            return
        heard, family = self.observer.transmissions, keys.kind_of(keys.tree_outbox("m", 0))
        # A recorder on a busy host can be tens of thousands of records behind (it shares
        # this process's loop): wait as long as it keeps writing, not a fixed time.
        written, progress_at = self.recorder.written[family], time.monotonic()
        while written < heard and time.monotonic() - progress_at < RECORDER_CATCH_UP_S:
            await asyncio.sleep(TICK_S)
            if self.recorder.written[family] > written:
                written, progress_at = self.recorder.written[family], time.monotonic()
        if written < heard:
            self.say(f"the recording has {written} of the {heard} reports the launcher heard "
                     f"(it wrote none for {RECORDER_CATCH_UP_S:g} s)")

    def _on_transmission(self, report: TreeReport) -> None:
        now = time.monotonic()
        if self.first_report is None:
            self.first_report = now
        self.observer.on_transmission(report)
        if self.covered_at is None and self.observer.coverage_time is not None:
            self.covered_at = now

    async def _start(self, o: TreeFleetOptions) -> None:
        common = ["--tree", o.tree, "--robots", str(o.robots)]
        self.radio = self._spawn("radio", "radio", mstc_argv("radio", *common,
                                                             *self._connection()))
        await self.supervisor.wait_ready(self.radio, RADIO_READY, 20.0)
        for robot in range(o.robots):
            self.agents.append(self._spawn(f"agent-{robot}", "agent", mstc_argv(
                "tree-agent", "--id", str(robot), *common, "--algo", o.algo,
                "--step-timeout", str(o.step_timeout), "--dead-after", str(o.dead_after),
                "--settle", str(o.settle), *self._connection()), robot))
        self.supervisor.write_fleet(FleetInfo(
            mission=o.mission, endpoint=self.endpoint, own_router=True, world=o.tree,
            algo=o.algo, robots=o.robots, starts=(), time_scale=0.0, created=time.time(),
            kind="tree", credentials=None if o.credentials is None else str(o.credentials)))
        self.say(f"fleet up: mission {o.mission} on {self.endpoint}, radio and {o.robots} "
                 f"agents ({o.algo}), run dir {self.run_dir.path}")

    def _announce(self, bus: Bus) -> None:
        """The mission's set-up as its status, repeated: a recording or a monitor that joins
        late learns which tree the robots cover (``mstc report`` judges the run with it)."""
        o = self.options
        bus.publish(keys.mission_status(o.mission), MissionStatus(
            "running", "tree coverage", {"tree": o.tree, "algo": o.algo, "robots": o.robots}))

    async def _watch(self, announce: Callable[[], None]) -> tuple[bool, str]:
        """Until every agent has ended, something failed, or no step completes for long."""
        o, seen = self.options, self.observer
        last_step, last_change, last_print = -1, time.monotonic(), 0.0
        while True:
            now = time.monotonic()
            if self.supervisor.stopped_by is not None:
                return False, f"stopped by {self.supervisor.stopped_by}"
            self._maybe_kill()
            failure = self._failed_child()
            if failure is not None:
                return False, failure
            if all(a.returncode is not None for a in self.agents):
                await self._settle()
                if self.kills.pending:  # their step never came, or a kill before was not seen
                    self.say("kill orders not carried out, the mission ended first: " + ", ".join(
                        f"robot {k.robot} at step {k.step}" for k in self.kills.pending))
                return True, "every agent finished" + "".join(f"; {k}" for k in self.killed)
            if seen.complete != last_step:
                last_step, last_change = seen.complete, now
            elif now - last_change > o.stall_timeout:
                return False, (f"no step completed for {o.stall_timeout:g} s (last step "
                               f"{last_step}); agent logs in {self.run_dir.logs}")
            if now - last_print >= 1.0:
                last_print = now
                announce()
                self.say(f"[{now - self.t0:6.1f}s] step {max(last_step, 0)}: visited "
                         f"{seen.visited}/{len(seen.seen)} nodes, "
                         f"{seen.transmissions} transmissions")
            await asyncio.sleep(TICK_S)

    def _failed_child(self) -> str | None:
        """Why the run failed, if the router or radio ended or an agent we did not kill
        failed (the survivors of a kill repair the trail and carry on)."""
        for child in self.supervisor.children:
            code = child.returncode
            if code is None:
                continue
            if child.role == "agent" and code < 0 and not child.expected_exit:
                child.expected_exit = True  # killed from outside, e.g. by mstc kill
                self.killed.append(f"robot {child.robot} killed by signal {-code}")
                self.say(f"[{time.monotonic() - self.t0:6.1f}s] {self.killed[-1]}")
                continue
            if child.role != "agent" or (code != 0 and not child.expected_exit):
                return (f"{child.name} exited with code {code}; last lines of {child.log}:\n"
                        f"{child.tail(6)}")
        return None

    def _maybe_kill(self) -> None:
        # Orders for different steps are carried out one death at a time: a later order waits
        # until the team has removed the robot of the earlier one. A launcher that looks late
        # (a loaded machine) would otherwise kill both in one tick, inside one settle period,
        # which is the case docs/treecover.md ("Trail repair") does not cover.
        if any(robot not in self.observer.deaths for robot in self.kill_ordered):
            return
        for order in self.kills.due_earliest_step(self.observer.complete):
            self.kill_ordered.append(order.robot)
            self.supervisor.kill_agent(order.robot)
            self.killed.append(f"robot {order.robot} killed (SIGKILL) after step "
                               f"{self.observer.complete}")
            self.say(f"[{time.monotonic() - self.t0:6.1f}s] {self.killed[-1]}")

    async def _settle(self) -> None:
        """Let the last reports, already sent by agents that have exited, reach us."""
        deadline = time.monotonic() + SETTLE_S
        killed = [a.robot for a in self.agents if a.expected_exit and a.robot is not None]
        while self.observer.coverage_time is None and time.monotonic() < deadline:
            await asyncio.sleep(TICK_S)
            self.observer.finish(killed)
