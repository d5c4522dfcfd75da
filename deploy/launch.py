"""The launcher behind ``mstc up``: starts the processes, supervises the mission, stops all.

One asyncio loop and one TaskGroup (world poller + watcher). The bus session of the launcher
is opened before simhw and the agents start, so no start-up message is missed; coverage is
the simhw ground truth (live CoverEvents, and the WorldState query every POLL_S as the
authority). The processes, signals, kill schedule, fleet.json and the ordered shutdown are
deploy.supervisor's, shared with ``mstc tree-fleet``.
"""

from __future__ import annotations

import asyncio
import contextlib
import signal
import time
from dataclasses import dataclass

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import ConnectionSettings
from bus.messages import (
    MESSAGE_TYPES,
    CoverEvent,
    DeathNotice,
    MissionStatus,
    RobotEvent,
    RobotStatus,
    WorldState,
)
from bus.router import READY_MARK as ROUTER_READY
from deploy.errors import FleetError
from deploy.fleet import Child, FleetInfo, RunDir, mstc_argv, niced
from deploy.kill_orders import KillOrders
from deploy.progress import ProgressView, make_progress
from deploy.security import FleetSecurity
from deploy.settings import MISSION_COVERED, NOT_CARRIED_OUT, MissionSetup, UpSettings
from deploy.summary import MissionTracker, format_summary, summarize
from deploy.supervisor import Supervisor
from planner.offline.rebalance import DEFAULT_RECOVERY

SIMHW_READY = "simhw ready"
SUB_BUFFER = 65536  # messages of every kind, as a monitor's feed (deploy.monitor.live)
POLL_S = 0.5
PACE_TICK_S = 0.02
PACE_PATIENCE_S = 15.0
TICK_S = 0.1
# How often a paced start-up says how far it is: at 100 robots on 2 cores it lasts about a
# minute, before the first coverage line (docs/operations.md, "Fleet scale").
START_LINE_S = 5.0
# A plan at least this long (CPU seconds, the launcher's own) is named in the "fleet up" line:
# the agents spend as long before their first move, and the view would look stuck.
LONG_PLAN_S = 2.0
# Agent exit codes (agent/main.py): 0 done or left, 4 fenced; anything else is a failure.
AGENT_DONE, AGENT_FENCED = 0, 4


@dataclass(frozen=True)
class Outcome:
    code: int
    message: str


class Launcher:
    """Starts, supervises and stops one fleet."""

    def __init__(self, setup: MissionSetup, settings: UpSettings, endpoint: str,
                 run_dir: RunDir, view: ProgressView) -> None:
        self.setup = setup
        self.endpoint = endpoint
        self.mission = settings.mission
        self.run_dir = run_dir
        self.supervisor = Supervisor(run_dir)
        self.settings = settings
        self.view = view
        self.own_router = settings.own_router
        self.security = FleetSecurity(settings.credentials)
        self.router: Child | None = None
        self.simhw: Child | None = None
        self.agents: list[Child] = []
        self.tracker = MissionTracker(setup.reachable, setup.k)
        self.t0 = time.monotonic()
        self.kills = KillOrders(settings.kills, self.mission, self.tracker, self.supervisor,
                                self._say)
        # set when a percent-triggered kill may be due (and by a stopping signal)
        self.wake = self.supervisor.wake
        self.failed_verdict = ""
        self._reported: set[str] = set()
        self._logged = 0

    # --- processes -------------------------------------------------------------------------

    def _connection(self) -> list[str]:
        return ["--mode", "client", "--connect", self.endpoint, "--mission", self.mission,
                "--lease-ms", str(self.settings.lease_ms), *self.security.child_args()]

    def _spawn(self, name: str, role: str, argv: list[str], robot: int | None = None) -> Child:
        return self.supervisor.spawn(name, role, argv, robot)

    async def _wait_ready(self, child: Child, mark: str, timeout: float) -> None:
        await self.supervisor.wait_ready(child, mark, timeout)

    @property
    def stop(self) -> asyncio.Event:
        return self.supervisor.stop

    async def start_router(self) -> None:
        if self.own_router:
            self.router = self._spawn("router", "router", mstc_argv(
                "router", "--listen", self.endpoint, "--lease-ms", str(self.settings.lease_ms),
                *self.security.child_args()))
            await self._wait_ready(self.router, ROUTER_READY, 20.0)

    async def start_fleet(self) -> None:
        s = self.setup
        starts = ";".join(f"{r},{c}" for r, c in s.starts)
        world = ["--world", s.world] + ([] if s.cell_size is None else
                                        ["--cell-size", str(s.cell_size)])
        self.simhw = self._spawn("simhw", "simhw", mstc_argv(
            "simhw", *world, "--starts", starts, "--seed", str(s.seed),
            "--time-scale", str(s.time_scale), *self._connection(), *self.settings.simhw_args))
        await self._wait_ready(self.simhw, SIMHW_READY, 30.0)
        if self.stop.is_set():
            return
        if self.settings.booting:
            self.view.event(f"fleet starting: mission {self.mission}, {s.k} agents, "
                            f"{self.settings.booting} at a time (each heard before the next "
                            f"starts), world {s.world}, algo {s.algo}, run dir "
                            f"{self.run_dir.path}")
        next_line = time.monotonic() + START_LINE_S
        for robot in range(s.k):
            await self._pace()
            now = time.monotonic()
            if now >= next_line:
                next_line = now + START_LINE_S
                self.view.event(f"[{now - self.t0:6.1f}s] starting agents: "
                                f"{len(self.agents)}/{s.k} started, "
                                f"{len(self.tracker.heard)} heard")
            if self.stop.is_set():
                return
            self.agents.append(self._spawn(f"agent-{robot}", "agent", niced(mstc_argv(
                "agent", "--id", str(robot), "--algo", s.algo, *world, "--tree", s.tree,
                "--seed", str(s.seed), "--robots", str(s.k), "--dead-after",
                str(self.settings.dead_after), *self._recovery(), *self._connection(),
                *self.settings.timing_args, *self.settings.agent_args),
                self.settings.agent_nice), robot))
            if self.settings.booting:
                self.write_fleet()  # a paced start lasts: mstc down must see who runs
        self.write_fleet()
        # a plan that took the launcher long takes the agents as long before their first move
        planned = (f", planned here in {s.plan_cpu_s:.0f} s (the agents plan it again)"
                   if s.plan_cpu_s >= LONG_PLAN_S else "")
        self.view.event(f"fleet up: mission {self.mission}, {s.k} agents, world {s.world}, "
                        f"algo {s.algo}, run dir {self.run_dir.path}{planned}")

    def _booting(self) -> int:
        """Agents started that have neither been heard nor exited."""
        return sum(1 for c in self.agents
                   if c.robot not in self.tracker.heard and c.returncode is None)

    async def _pace(self) -> None:
        """Before the next agent starts, while ``settings.booting`` agents are starting (not
        heard yet): wait until one is heard or exits (a paced start-up; 0: no pacing). Never
        longer than PACE_PATIENCE_S per agent: a robot that never announces itself is the
        gather's business (it goes on without it), not a reason to hold the others back."""
        window = self.settings.booting
        if window <= 0:
            return
        deadline = time.monotonic() + PACE_PATIENCE_S
        while (self._booting() >= window and time.monotonic() < deadline
               and not self.stop.is_set()):
            await asyncio.sleep(PACE_TICK_S)  # statuses are heard on this loop meanwhile

    def _recovery(self) -> list[str]:
        """--recovery for the agents, only when not the default (ORMSTC agents have none)."""
        recovery = self.settings.recovery
        return [] if recovery == DEFAULT_RECOVERY else ["--recovery", recovery]

    def children(self) -> list[Child]:
        return self.supervisor.children

    def write_fleet(self) -> None:
        s = self.setup
        self.supervisor.write_fleet(FleetInfo(
            mission=self.mission, endpoint=self.endpoint, own_router=self.own_router,
            world=s.world, algo=s.algo, robots=s.k, starts=s.starts,
            time_scale=s.time_scale, created=time.time(), kind="grid",
            credentials=None if self.security.credentials is None
            else str(self.security.credentials)))

    def shutdown(self) -> None:
        self.supervisor.shutdown()

    # --- bus -------------------------------------------------------------------------------

    def subscribe(self, bus: Bus) -> None:
        """Every message of the mission, in order: all of them feed the model the summary's
        figures are read from (as a monitor's would), some also the supervision; recovered
        from the publishers' caches after a router restart or freeze (bus.recovery), so the
        summary's ground truth has no hole."""
        bus.subscribe(keys.everything(self.mission), tuple(MESSAGE_TYPES.values()),
                      self._on_message, BoundedFifo(SUB_BUFFER), recover=True)

    def _on_message(self, key: str, msg: object) -> None:
        t = self.tracker
        t.observe(time.monotonic() - self.t0, key, msg)
        if isinstance(msg, CoverEvent):
            self._on_cover(msg)
        elif isinstance(msg, RobotStatus):
            t.on_status(msg)
        elif isinstance(msg, RobotEvent):
            t.on_event(msg)
        elif isinstance(msg, DeathNotice):
            self._on_death(key, msg)
        elif isinstance(msg, MissionStatus):
            self._on_verdict(key, msg)

    def _on_cover(self, event: CoverEvent) -> None:
        # Per cover, not per tick: armed orders at a coverage (deploy/kill_orders.py) fire here,
        # and simhw holds the world for a SIGKILL until the watcher says "resume".
        if self.tracker.on_cover(event, time.monotonic()) and (
                self.kills.fire_armed() or self.kills.waits_on_coverage()):
            self.wake.set()

    def _on_death(self, _key: str, notice: DeathNotice) -> None:
        # every death is told, not only those of our own kill orders (`mstc kill` from
        # another terminal, a crash); with the delay when we failed it ourselves
        if self.tracker.on_death(notice, self.kills.noticed(notice.robot)):
            self.kills.forget(notice.robot)

    def _on_verdict(self, _key: str, status: MissionStatus) -> None:
        if status.state == "failed" and not self.failed_verdict:
            self.failed_verdict = status.message or "no reason given"

    async def poll_world(self, bus: Bus) -> None:
        while True:
            await self.query_world(bus)
            await asyncio.sleep(POLL_S)

    async def query_world(self, bus: Bus) -> None:
        for reply in await bus.query(keys.world(self.mission), None, WorldState, timeout=2.0):
            self.tracker.observe(time.monotonic() - self.t0, reply.key, reply.msg, "query")
            try:
                self.tracker.on_world(reply.msg, time.monotonic())
            except ValueError as error:
                raise FleetError(f"simhw's world does not match: {error}") from error
            if self.kills.fire_armed():
                self.wake.set()

    # --- supervision -----------------------------------------------------------------------

    async def supervise(self, bus: Bus) -> Outcome:
        async with asyncio.TaskGroup() as group:
            poller = group.create_task(self.poll_world(bus))
            try:
                return await self.watch(bus)
            finally:
                poller.cancel()

    async def watch(self, bus: Bus) -> Outcome:
        t, s = self.tracker, self.settings
        start_timeout = s.start_timeout
        started: float | None = None
        complete_at: float | None = None
        initial = t.covered
        while True:
            now = time.monotonic()
            outcome = await self._check_children(bus)
            if self.stop.is_set():
                sig = self.supervisor.stop_signal or signal.SIGINT
                return Outcome(128 + sig, f"stopped by {signal.Signals(sig).name}")
            if outcome is None and self.failed_verdict:
                outcome = Outcome(1, f"an agent declared the mission failed: "
                                     f"{self.failed_verdict}")
            if outcome is not None:
                return outcome
            if started is None and (t.announced == t.robots or t.covered > initial):
                started = now
                t.last_progress = now
                self.view.event(f"[{now - self.t0:6.1f}s] mission started: all robots up")
                await self.kills.arm(bus)
            elif started is None and now - self.t0 > start_timeout:
                missing = sorted(set(range(t.robots)) - t.heard)
                return Outcome(1, f"agents not up after {start_timeout:.0f} s; robots not "
                                  f"announced: {missing} (see their logs in "
                                  f"{self.run_dir.logs})")
            await self.kills.resume_if_due(bus)
            if started is not None and not t.complete:
                # Once every sub-cell is covered a death tests nothing: orders due only
                # now stay pending, listed as not carried out (a campaign counts them late).
                await self.kills.run_due(bus, now - started)
            if not t.complete and self._all_stopped():
                # What we heard can lag what simhw saw (a loaded host, a burst of covers at
                # time scale 0, covers still being recovered): the world decides, not us.
                await self.query_world(bus)
            if t.complete:
                if complete_at is None:
                    complete_at = now
                    self.view.event(f"[{now - self.t0:6.1f}s] {MISSION_COVERED}")
                if self._all_settled() or now - complete_at > s.linger:
                    return Outcome(0, "every reachable free sub-cell was covered")
            elif self._all_stopped():
                return Outcome(1, "every agent has stopped; " + self._uncovered())
            elif started is not None and now - t.last_progress > s.stall_timeout + (
                    s.plan_allowance if t.covered <= initial else 0.0):
                return Outcome(1, self._stall_diagnosis(now - t.last_progress))
            self._flush_log()
            self.view.update(t, now - self.t0)
            with contextlib.suppress(TimeoutError):
                async with asyncio.timeout(TICK_S):
                    await self.wake.wait()
            self.wake.clear()

    def _all_stopped(self) -> bool:
        return all(c.returncode is not None for c in self.agents)

    def _all_settled(self) -> bool:
        return all(v.completed or v.lost or self.agents[v.robot].returncode is not None
                   for v in self.tracker.views)

    def _uncovered(self) -> str:
        t = self.tracker
        return (f"{t.total - t.covered} reachable sub-cells uncovered "
                f"(e.g. {t.uncovered()})")

    def _stall_diagnosis(self, quiet: float) -> str:
        t = self.tracker
        states = ", ".join(f"{v.robot}:{'lost' if v.lost else v.state}" for v in t.views)
        return (f"mission stalled: no new sub-cell covered for {quiet:.0f} s; "
                f"{self._uncovered()}; robot states {states}; "
                f"agent logs in {self.run_dir.logs}")

    async def _check_children(self, bus: Bus) -> Outcome | None:
        for child in self.children():
            code = child.returncode
            if code is None or child.name in self._reported or child.expected_exit:
                continue
            self._reported.add(child.name)
            if child.role != "agent":
                return Outcome(1, f"{child.name} exited early with code {code}; last lines "
                                  f"of {child.log}:\n{child.tail()}")
            assert child.robot is not None
            if code == AGENT_DONE:
                self.tracker.views[child.robot].state = "exited"
                continue
            why = (f"agent process killed by signal {-code}" if code < 0 else
                   "fenced: declared dead by its peers" if code == AGENT_FENCED else
                   f"agent exited with code {code}")
            view = self.tracker.views[child.robot]
            if code > 0 and code != AGENT_FENCED and not view.lost:
                # an agent whose body an operator failed (`mstc kill --hw`) ends this way
                # too: ask simhw before calling it a crash
                await self.query_world(bus)
            if view.lost.startswith("body failed"):
                self.tracker.log.append(f"robot {child.robot}'s agent stopped (exit code "
                                        f"{code}) because its body was failed")
                continue
            known = bool(view.lost)  # e.g. we killed it
            self.tracker.lose(child.robot, why)
            if code > 0 and code != AGENT_FENCED and not known:
                self.view.event(f"last lines of {child.log}:\n{child.tail(8)}")
        return None

    def _say(self, text: str) -> None:
        self.view.event(f"[{time.monotonic() - self.t0:6.1f}s] {text}")

    def _flush_log(self) -> None:
        for line in self.tracker.log[self._logged:]:
            self.view.event(f"[{time.monotonic() - self.t0:6.1f}s] {line}")
        self._logged = len(self.tracker.log)


async def launch(setup: MissionSetup, settings: UpSettings, endpoint: str, t0: float) -> int:
    """Run the whole fleet; return the exit code (see deploy.cmd_up)."""
    mission = settings.mission
    rd = RunDir(settings.run_dir).create()
    view = make_progress(settings.plain)
    launcher = Launcher(setup, settings, endpoint, rd, view)
    launcher.t0 = t0
    connection = launcher.security.operator(ConnectionSettings(
        connect=(endpoint,), mission=mission, lease_ms=settings.lease_ms))
    with launcher.supervisor.signals_stop():
        try:
            await launcher.start_router()
            async with Bus.connect(connection) as bus:
                launcher.subscribe(bus)
                await launcher.start_fleet()
                outcome = await launcher.supervise(bus) if not launcher.stop.is_set() else \
                    Outcome(128 + (launcher.supervisor.stop_signal or 2),
                            "stopped during start-up")
                await launcher.query_world(bus)
            summary = summarize(launcher.tracker, mission=mission, world=setup.world,
                                algo=setup.algo, wall_seconds=time.monotonic() - t0,
                                planned_makespan=setup.planned_makespan,
                                outcome=outcome.message)
            view.close()
            print(format_summary(summary), flush=True)
            if launcher.kills.unfired:  # a clean run is no survived kill: say what never came
                print("  " + NOT_CARRIED_OUT + ", ".join(
                    order.describe() for order in launcher.kills.unfired), flush=True)
            rd.write_summary(summary.to_json())
            if outcome.code == 0 and not summary.complete:
                return 1
            return outcome.code
        finally:
            view.close()
            launcher.shutdown()
