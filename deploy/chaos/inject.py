"""Process and network faults on a running fleet, from outside, by PID: SIGKILL, hangs
(SIGSTOP/SIGCONT of any length), router kill/restart and freeze, partitions of one robot
from its router (iptables DROP of its TCP connections on loopback, healed after), and CPU
starvation: of one robot (stopped for all but ``share`` of every 100 ms, a process the
scheduler hardly runs) or of the host (one busy process per core beside the fleet).

The router is the injector's own child (``mstc chaos`` starts it and runs ``mstc up
--connect``), so a restart brings the same router back on the same port. A partition needs
iptables and the right to use it: :func:`partition_problem` says why not, and campaigns and
tests skip partitions with that reason.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

from bus.router import READY_MARK
from deploy.chaos.schedule import Fault
from deploy.fleet import ended_with_launcher, mstc_argv


class InjectionError(RuntimeError):
    """A fault could not be carried out (the trial would run without it unseen)."""


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


def partition_problem() -> str | None:
    """Why partitions cannot be made here, or None."""
    if shutil.which("iptables") is None:
        return "iptables is not installed (apt-get install -y iptables)"
    probe = subprocess.run(["iptables", "-S", "INPUT"], capture_output=True, text=True,
                           check=False)
    if probe.returncode != 0:
        return f"iptables cannot be used: {probe.stderr.strip() or probe.returncode}"
    return None


def tcp_ports(pid: int, remote_port: int) -> list[int]:
    """Local ports of process ``pid``'s TCP connections to ``remote_port`` (loopback)."""
    inodes: set[str] = set()
    with contextlib.suppress(OSError):
        for fd in Path(f"/proc/{pid}/fd").iterdir():
            with contextlib.suppress(OSError):
                target = os.readlink(fd)
                if target.startswith("socket:["):
                    inodes.add(target[8:-1])
    ports = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with contextlib.suppress(OSError):
            for line in Path(table).read_text().splitlines()[1:]:
                fields = line.split()
                local, remote, inode = fields[1], fields[2], fields[9]
                if inode in inodes and int(remote.rsplit(":", 1)[1], 16) == remote_port:
                    ports.append(int(local.rsplit(":", 1)[1], 16))
    return sorted(set(ports))


def _rule(action: str, direction: str, port: int) -> subprocess.CompletedProcess[str]:
    # -w: trials running side by side take the xtables lock in turn instead of failing.
    return subprocess.run(["iptables", "-w", "5", action, "INPUT", "-i", "lo", "-p", "tcp",
                           direction, str(port), "-j", "DROP"],
                          capture_output=True, text=True, check=False)


def _iptables(action: str, port: int) -> None:
    """Insert (-I) or delete (-D) the two DROP rules of one local port on lo."""
    done: list[str] = []
    for direction in ("--sport", "--dport"):
        result = _rule(action, direction, port)
        if result.returncode != 0:
            if action == "-I":  # no half partition left behind
                for undo in done:
                    _rule("-D", undo, port)
            raise InjectionError(f"iptables {action} port {port}: "
                                 f"{result.stderr.strip() or result.returncode}")
        done.append(direction)


def _heal(ports: list[int]) -> str:
    """Delete the rules of ``ports``; what could not be deleted, as a note for the record."""
    failed = []
    for port in ports:
        try:
            _iptables("-D", port)
        except InjectionError as error:
            failed.append(str(error))
    return f"; heal failed: {'; '.join(failed)}" if failed else ""


class Injector:
    """Carries out a trial's faults against its router and its fleet's PIDs."""

    def __init__(self, router: RouterProcess, run_dir: Path) -> None:
        self.router = router
        self.run_dir = run_dir
        self.done: list[str] = []  # what was carried out, for the trial's record

    def agent_pid(self, robot: int) -> int | None:
        path = self.run_dir / "pids" / f"agent-{robot}.pid"
        with contextlib.suppress(OSError, ValueError, IndexError):
            return int(path.read_text().split()[0])
        return None

    async def apply(self, fault: Fault) -> None:
        if fault.robot is None:
            await (self._starve_host(fault) if fault.kind == "starve" else self._router(fault))
            return
        pid = self.agent_pid(fault.robot)
        if pid is None:
            # Not spawned yet: a fault this early hits the robot as it boots.
            for _ in range(1500):  # mstc up spawns the agents once simhw is ready
                await asyncio.sleep(0.02)
                if (pid := self.agent_pid(fault.robot)) is not None:
                    break
        if pid is None:
            self.done.append(f"{fault.describe()}: no such process")
            return
        if fault.mark and not await self._marked(fault.robot, fault.mark):
            self.done.append(f"{fault.describe()}: the mark never came")
            return
        await asyncio.sleep(fault.at if fault.mark else 0.0)
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
            ports = tcp_ports(pid, self.router.port)
            cut: list[int] = []
            try:
                for port in ports:
                    _iptables("-I", port)
                    cut.append(port)
                await asyncio.sleep(fault.seconds)
            except InjectionError as error:
                self.done.append(f"{fault.describe()}: not carried out: {error}")
                return
            finally:
                healed = _heal(cut)
            self.done.append(f"{fault.describe()}: ports {ports}{healed}")
            return
        self.done.append(fault.describe())

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
