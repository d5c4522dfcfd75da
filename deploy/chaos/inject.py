"""Process and network faults on a running fleet, from outside, by PID: SIGKILL, hangs
(SIGSTOP/SIGCONT of any length), router kill/restart and freeze, partitions of one robot
from its router (deploy.chaos.partition: its connections dropped and its reconnections
refused on loopback, healed after), and CPU starvation: of one robot (stopped for all but
``share`` of every 100 ms, a process the scheduler hardly runs) or of the host (one busy
process per core beside the fleet).

The router is the injector's own child (``mstc chaos`` starts it and runs ``mstc up
--connect``), so a restart brings the same router back on the same port. A partition needs
iptables and the right to use it: ``deploy.chaos.partition.partition_problem`` says why
not, and campaigns and tests skip partitions with that reason.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import subprocess
import sys
from pathlib import Path

from bus.router import READY_MARK
from deploy.chaos.partition import Cut, InjectionError, tcp_ports
from deploy.chaos.schedule import TOO_LATE, Fault
from deploy.fleet import ProcessRecord, ended_with_launcher, is_running, mstc_argv
from deploy.settings import MISSION_COVERED


class RouterProcess:
    """A ``mstc router`` on ``endpoint`` that can be killed, restarted and frozen."""

    def __init__(self, endpoint: str, log: Path) -> None:
        self.endpoint = endpoint
        self.log = log
        self.proc: subprocess.Popen[bytes] | None = None

    @property
    def port(self) -> int:
        return int(self.endpoint.rsplit(":", 1)[1])

    def _ready_marks(self) -> int:
        with contextlib.suppress(OSError):
            return self.log.read_text(errors="replace").count(READY_MARK)
        return 0

    async def start(self, timeout: float = 20.0) -> None:
        """Start (or restart) the router; return once it says it is ready."""
        seen = self._ready_marks()
        with self.log.open("ab") as out:
            self.proc = subprocess.Popen(
                mstc_argv("router", "--listen", self.endpoint, "--exit-with-parent"),
                stdin=subprocess.DEVNULL,
                stdout=out, stderr=subprocess.STDOUT, start_new_session=True,
                env=dict(os.environ, PYTHONUNBUFFERED="1"))
        async with asyncio.timeout(timeout):
            while self._ready_marks() <= seen:
                if self.proc.poll() is not None:
                    raise RuntimeError(f"mstc router exited {self.proc.returncode}")
                await asyncio.sleep(0.05)

    def signal(self, sig: int) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.send_signal(sig)

    def kill(self) -> None:
        if self.proc is not None:
            self.signal(signal.SIGCONT)
            self.signal(signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(5.0)


# How long a partition waits for a booting robot's first connection to the router.
CONNECTION_WAIT_S = 30.0


class Injector:
    """Carries out a trial's faults against its router and its fleet's PIDs."""

    def __init__(self, router: RouterProcess, run_dir: Path, up_log: Path | None = None) -> None:
        self.router = router
        self.run_dir = run_dir
        self.up_log = up_log  # mstc up's output: once it says the mission is covered, no fault
        self.done: list[str] = []  # what was carried out, for the trial's record

    def _too_late(self, fault: Fault) -> bool:
        """True (and recorded) once ``mstc up`` says every sub-cell is covered: a fault then
        tests nothing, yet a lingering robot's process is still there to kill (seed 6023,
        trial 16: a kill 0.6 s after the mission ended, recorded as survived)."""
        if self.up_log is None:
            return False
        with contextlib.suppress(OSError):
            if MISSION_COVERED in self.up_log.read_text(errors="replace"):
                self.done.append(f"{fault.describe()}: {TOO_LATE}")
                return True
        return False

    def agent(self, robot: int) -> ProcessRecord | None:
        """Robot ``robot``'s agent as its pid file names it (None before it is spawned).
        The file outlives the process until the fleet stops: :meth:`apply` checks
        ``is_running`` before it acts."""
        path = self.run_dir / "pids" / f"agent-{robot}.pid"
        with contextlib.suppress(OSError, ValueError, IndexError):
            pid, started = (int(word) for word in path.read_text().split()[:2])
            return ProcessRecord(f"agent-{robot}", "agent", pid, started or None)
        return None

    async def apply(self, fault: Fault) -> None:
        if fault.robot is None:
            if not self._too_late(fault):
                await (self._starve_host(fault) if fault.kind == "starve" else
                       self._router(fault))
            return
        agent = self.agent(fault.robot)
        if agent is None:
            # Not spawned yet: a fault this early hits the robot as it boots.
            for _ in range(1500):  # mstc up spawns the agents once simhw is ready
                await asyncio.sleep(0.02)
                if (agent := self.agent(fault.robot)) is not None:
                    break
        if agent is None:
            self.done.append(f"{fault.describe()}: no such process")
            return
        if fault.mark and not await self._marked(fault.robot, fault.mark):
            self.done.append(f"{fault.describe()}: the mark never came")
            return
        await asyncio.sleep(fault.at if fault.mark else 0.0)
        if self._too_late(fault):
            return
        if not is_running(agent):
            # ended (killed, fenced, left), or its pid since given to another process: a
            # signal would be lost, or hit a stranger, and be recorded as done
            self.done.append(f"{fault.describe()}: no such process")
            return
        pid = agent.pid
        if fault.kind == "kill":
            _signal(pid, signal.SIGKILL)
        elif fault.kind == "hang":
            _signal(pid, signal.SIGSTOP)
            try:
                await asyncio.sleep(fault.seconds)
            finally:
                _signal(pid, signal.SIGCONT)
        elif fault.kind == "starve":
            await _throttle(pid, fault.seconds, fault.share)
        elif fault.kind == "partition":
            await self._partition(fault, agent)
            return
        self.done.append(fault.describe())

    async def _partition(self, fault: Fault, agent: ProcessRecord) -> None:
        """Cut robot ``fault.robot`` off for ``fault.seconds`` (deploy.chaos.partition). A
        robot still booting has no connection to cut yet: it is waited for, as a kill waits
        for its process, and the record says how long."""
        loop = asyncio.get_running_loop()
        asked = loop.time()
        pid = agent.pid
        ports = tcp_ports(pid, self.router.port)
        while not ports and is_running(agent) and loop.time() - asked < CONNECTION_WAIT_S:
            await asyncio.sleep(0.02)
            ports = tcp_ports(pid, self.router.port)
        if not ports:
            self.done.append(f"{fault.describe()}: not carried out: robot {fault.robot} had "
                             "no connection to the router")
            return
        waited = loop.time() - asked
        cut = Cut(pid, self.router.port)
        failure: InjectionError | None = None
        try:
            cut.make(ports)
            await asyncio.sleep(fault.seconds)
        except InjectionError as error:
            failure = error
        finally:
            healed = cut.heal()
        if failure is not None:
            self.done.append(f"{fault.describe()}: not carried out: {failure}{healed}")
            return
        notes = [f"ports {ports}"]
        if waited >= 0.05:
            notes.append(f"after {waited:.1f} s waiting for its connection")
        if cut.reconnects_blocked:
            notes.append(f"reconnections not blocked: {cut.reconnects_blocked}")
        self.done.append(f"{fault.describe()}: {', '.join(notes)}{healed}")

    async def _marked(self, robot: int, mark: str, timeout: float = 60.0) -> bool:
        """Wait until robot ``robot``'s log shows ``mark``; False if it never does."""
        log = self.run_dir / "logs" / f"agent-{robot}.log"
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(timeout):
                while True:
                    with contextlib.suppress(OSError):
                        if mark in log.read_text(errors="replace"):
                            return True
                    await asyncio.sleep(0.02)
        return False

    async def _starve_host(self, fault: Fault) -> None:
        hogs = busy_processes(os.cpu_count() or 1)
        try:
            await asyncio.sleep(fault.seconds)
        finally:
            for hog in hogs:
                hog.kill()
                hog.wait()
        self.done.append(f"{fault.describe()}: {len(hogs)} busy processes")

    async def _router(self, fault: Fault) -> None:
        if fault.kind == "router-freeze":
            self.router.signal(signal.SIGSTOP)
            try:
                await asyncio.sleep(fault.seconds)
            finally:
                self.router.signal(signal.SIGCONT)
        elif fault.kind == "router-kill":
            self.router.kill()
            await asyncio.sleep(fault.seconds)
            await self.router.start()
        self.done.append(fault.describe())


THROTTLE_PERIOD_S = 0.1


async def _throttle(pid: int, seconds: float, share: float) -> None:
    """Let ``pid`` run for ``share`` of every period, stopped for the rest, for ``seconds``."""
    running = THROTTLE_PERIOD_S * min(max(share, 0.0), 1.0)
    loop = asyncio.get_running_loop()
    end = loop.time() + seconds
    try:
        while loop.time() < end:
            _signal(pid, signal.SIGSTOP)
            await asyncio.sleep(THROTTLE_PERIOD_S - running)
            _signal(pid, signal.SIGCONT)
            await asyncio.sleep(running)
    finally:
        _signal(pid, signal.SIGCONT)


def busy_processes(count: int) -> list[subprocess.Popen[bytes]]:
    """``count`` processes that spin on a CPU each until killed, or until this process
    dies: a campaign killed during a starve-host fault left them spinning for good."""
    return [subprocess.Popen(ended_with_launcher([sys.executable, "-c", "while True: pass"]),
                             stdin=subprocess.DEVNULL, start_new_session=True)
            for _ in range(count)]


def _signal(pid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.kill(pid, sig)
