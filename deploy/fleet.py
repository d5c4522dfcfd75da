"""Process management for a local fleet: run directory, child processes, PID files, shutdown.

Children are started with ``subprocess`` (never a fork of a process that imported zenoh) as
``python -m deploy.cli <command>``, each in its own session so that a Ctrl-C in the terminal
reaches only the launcher, which then stops them in order. A PID file holds the pid *and*
the process start time from /proc, so that ``mstc down``/``mstc kill`` never signal an
unrelated process that reused the pid after the fleet ended.

Run directory layout::

    <run>/fleet.json        FleetInfo: mission, endpoint, world, processes (read by down/kill)
    <run>/summary.json      the end-of-mission summary (mstc up; mstc tree-fleet's verdict)
    <run>/logs/<name>.log   stdout+stderr of each process (router, simhw, agent-<i>)
    <run>/pids/<name>.pid   "<pid> <start-ticks>" of each process, up.pid for the launcher
"""

from __future__ import annotations

import asyncio
import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from deploy.errors import FleetError

RUNS_ROOT = Path("runs")
FLEET_FILE = "fleet.json"
SUMMARY_FILE = "summary.json"
LAUNCHER = "up"  # the launcher's role and name in fleet.json, whichever command it is
# Stopping order by role: agents first (they would report a vanished world as a failure),
# then the world processes, the router last (everyone's link).
SHUTDOWN_ORDER = {"agent": 0, "simhw": 1, "radio": 1, "router": 2}
# `mstc up --connect` waits this long for a router that does not answer yet (one being
# restarted, or started by a script beside it) before it gives up.
ROUTER_WAIT_S = 10.0
ROUTER_PROBE_PERIOD_S = 0.2


@dataclass(frozen=True)
class ProcessRecord:
    """One process of a fleet as written to fleet.json."""

    name: str
    role: str  # "up" (the launcher), "router", "simhw", "radio" or "agent"
    pid: int
    started: int | None  # start time in clock ticks since boot (/proc/<pid>/stat field 22)
    log: str = ""
    robot: int | None = None


@dataclass(frozen=True)
class FleetInfo:
    """What ``mstc kill``, ``mstc down`` and ``mstc monitor`` need to know about a running
    fleet. ``kind`` "grid" (mstc up: ``world`` is a map) or "tree" (mstc tree-fleet: ``world``
    is the tree spec, no simulated bodies)."""

    mission: str
    endpoint: str
    own_router: bool
    world: str
    algo: str
    robots: int
    starts: tuple[tuple[int, int], ...]
    time_scale: float
    created: float
    processes: tuple[ProcessRecord, ...] = field(default_factory=tuple)
    kind: str = "grid"
    credentials: str | None = None  # the mission's credentials file; None: an insecure run

    def to_json(self) -> dict[str, Any]:
        return asdict(self)

    def to_fields(self) -> dict[str, Any]:
        """The constructor's arguments (``processes`` left as records)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> FleetInfo:
        procs = tuple(ProcessRecord(**p) for p in data.get("processes", ()))
        values = {k: v for k, v in data.items() if k != "processes"}
        values["starts"] = tuple((int(r), int(c)) for r, c in values.get("starts", ()))
        return cls(**values, processes=procs)

    def agent(self, robot: int) -> ProcessRecord:
        for proc in self.processes:
            if proc.role == "agent" and proc.robot == robot:
                return proc
        raise FleetError(f"no agent for robot {robot} in this fleet (robots 0..{self.robots - 1})")


class RunDir:
    """The files of one fleet run."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)

    @property
    def logs(self) -> Path:
        return self.path / "logs"

    @property
    def pids(self) -> Path:
        return self.path / "pids"

    def create(self) -> RunDir:
        try:
            self.logs.mkdir(parents=True, exist_ok=True)
            self.pids.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise FleetError(f"cannot create run directory {self.path}: {error}") from error
        return self

    def log_path(self, name: str) -> Path:
        return self.logs / f"{name}.log"

    def write_pid(self, record: ProcessRecord) -> None:
        (self.pids / f"{record.name}.pid").write_text(f"{record.pid} {record.started or 0}\n")

    def remove_pid(self, name: str) -> None:
        (self.pids / f"{name}.pid").unlink(missing_ok=True)

    def write_fleet(self, info: FleetInfo) -> None:
        _write_json_atomic(self.path / FLEET_FILE, info.to_json())

    def read_fleet(self) -> FleetInfo:
        path = self.path / FLEET_FILE
        try:
            return FleetInfo.from_json(json.loads(path.read_text()))
        except FileNotFoundError:
            raise FleetError(f"{path} does not exist: not a fleet run directory") from None
        except (OSError, ValueError, TypeError, KeyError) as error:
            raise FleetError(f"cannot read {path}: {error}") from error

    def write_summary(self, data: dict[str, Any]) -> None:
        _write_json_atomic(self.path / SUMMARY_FILE, data)


def _write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    # Readers (mstc down in another terminal) must never see half a file.
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(data, indent=2) + "\n")
    tmp.replace(path)


def unique_mission() -> str:
    """A mission name no other fleet uses, so fleets sharing a router never mix."""
    return f"fleet-{secrets.token_hex(3)}"


def default_run_dir(mission: str, root: Path = RUNS_ROOT) -> Path:
    return root / f"{time.strftime('%Y%m%d-%H%M%S')}-{mission}"


def latest_run_dir(root: Path = RUNS_ROOT) -> Path:
    """The run directory whose fleet.json is the newest under ``root``."""
    candidates = list(root.glob(f"*/{FLEET_FILE}")) if root.is_dir() else []
    if not candidates:
        raise FleetError(f"no fleet run directory under {root}/ (give --run-dir)")
    return max(candidates, key=lambda p: p.stat().st_mtime).parent


# --- process identity -----------------------------------------------------------------------

def _proc_stat(pid: int) -> list[str] | None:
    """Fields 3.. of /proc/<pid>/stat (None where /proc is unavailable or pid is gone)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    # The command name (field 2) may hold spaces; fields after its closing paren are fixed.
    return stat.rsplit(")", 1)[1].split()


def start_ticks(pid: int) -> int | None:
    """The process start time in clock ticks since boot (None if unknown)."""
    fields = _proc_stat(pid)
    return None if fields is None else int(fields[19])


def is_running(record: ProcessRecord) -> bool:
    """True if the recorded process is still the one running under its pid."""
    fields = _proc_stat(record.pid)
    if fields is not None:
        if fields[0] == "Z":  # a zombie has ended; only its parent has not reaped it yet
            return False
        return record.started is None or int(fields[19]) == record.started
    if Path("/proc").is_dir():
        return False
    try:
        os.kill(record.pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def send_signal(record: ProcessRecord, sig: int) -> bool:
    """Signal the recorded process if it is still that process; False if it is gone."""
    if not is_running(record):
        return False
    try:
        os.kill(record.pid, sig)
    except ProcessLookupError:
        return False
    return True


def wait_gone(records: list[ProcessRecord], timeout: float) -> list[ProcessRecord]:
    """Wait until the processes end (or ``timeout``); return those still running."""
    deadline = time.monotonic() + timeout
    alive = [r for r in records if is_running(r)]
    while alive and time.monotonic() < deadline:
        time.sleep(0.05)
        alive = [r for r in alive if is_running(r)]
    return alive


# --- children -----------------------------------------------------------------------------

class Child:
    """A process started by the launcher, with its log file."""

    def __init__(self, name: str, role: str, argv: list[str], log: Path,
                 robot: int | None = None) -> None:
        self.name = name
        self.role = role
        self.robot = robot
        self.log = log
        self.argv = argv
        self.expected_exit = False  # set before we stop or kill it on purpose
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        with log.open("ab") as out:
            self.proc = subprocess.Popen(
                ended_with_launcher(argv), stdin=subprocess.DEVNULL, stdout=out,
                stderr=subprocess.STDOUT, env=env, start_new_session=True)
        self.record = ProcessRecord(name=name, role=role, pid=self.proc.pid,
                                    started=start_ticks(self.proc.pid), log=str(log),
                                    robot=robot)

    @property
    def returncode(self) -> int | None:
        return self.proc.poll()

    def signal(self, sig: int) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)

    def tail(self, lines: int = 15) -> str:
        return log_tail(self.log, lines)


def ended_with_launcher(argv: list[str]) -> list[str]:
    """``argv`` run so that the kernel sends it SIGTERM when the launcher dies, even by
    SIGKILL (``setpriv --pdeathsig``, which execs the command: the pid stays the command's).
    Children run in sessions of their own, so without it a killed ``mstc up`` left its
    router, simhw and agents running. Unchanged where there is no setpriv (util-linux).
    The signal follows the launcher's thread that spawned the child: spawn on the loop."""
    setpriv = shutil.which("setpriv")
    return argv if setpriv is None else [setpriv, "--pdeathsig", "TERM", *argv]


def niced(argv: list[str], niceness: int) -> list[str]:
    """``argv`` run at a lower CPU priority (``nice -n``; the pid stays the command's, as
    nice execs it), or unchanged for niceness 0 or where there is no nice command."""
    nice = shutil.which("nice") if niceness > 0 else None
    return argv if nice is None else [nice, "-n", str(niceness), *argv]


def mstc_argv(command: str, *args: str) -> list[str]:
    """The argv of an ``mstc <command>`` child run by this Python interpreter."""
    return [sys.executable, "-m", "deploy.cli", command, *args]


def log_tail(path: Path, lines: int = 15) -> str:
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return ""
    return "\n".join(text.rstrip().splitlines()[-lines:])


async def wait_ready(child: Child, mark: str, timeout: float,
                     stop: asyncio.Event | None = None) -> None:
    """Until ``mark`` shows in the child's log; FleetError if it exits first or ``timeout``
    passes (not when ``stop`` is set: the launcher is stopping anyway)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not (stop is not None and stop.is_set()):
        if mark in log_tail(child.log, 50):
            return
        if child.returncode is not None:
            last = log_tail(child.log, 3) or f"exit code {child.returncode}"
            raise FleetError(f"{child.name} failed to start: {last} (log: {child.log})")
        await asyncio.sleep(0.05)
    if stop is None or not stop.is_set():
        raise FleetError(f"{child.name} not ready after {timeout:.0f} s (log: {child.log})")


def stop_children(children: list[Child], timeout: float = 5.0) -> None:
    """SIGTERM every child still running, wait up to ``timeout``, then SIGKILL the rest."""
    for child in children:
        child.expected_exit = True
        child.signal(signal.SIGTERM)
    deadline = time.monotonic() + timeout
    for child in children:
        try:
            child.proc.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            child.proc.kill()
            child.proc.wait()


# --- endpoints ----------------------------------------------------------------------------

def tcp_address(endpoint: str) -> tuple[str, int] | None:
    """(host, port) of a ``tcp/host:port`` endpoint, None for other protocols."""
    proto, _, address = endpoint.partition("/")
    if proto != "tcp":
        return None
    host, sep, port = address.rpartition(":")
    if not sep or not port.isdigit():
        raise FleetError(f"endpoint {endpoint!r} must look like tcp/127.0.0.1:7447")
    return host.strip("[]"), int(port)


def check_port_free(endpoint: str) -> None:
    """FleetError at once if something already listens on ``endpoint`` (another fleet)."""
    address = tcp_address(endpoint)
    if address is None:
        return
    family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as sock:
        # SO_REUSEADDR ignores TIME_WAIT leftovers but still fails on a live listener.
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind(address)
        except OSError as error:
            raise FleetError(
                f"{endpoint} is already in use ({error.strerror}): another fleet or router "
                f"is running there; stop it with 'mstc down' or choose --listen") from None


def port_reachable(endpoint: str, timeout: float = 1.0) -> bool:
    """True if a TCP connection to ``endpoint`` succeeds (a router is listening)."""
    address = tcp_address(endpoint)
    if address is None:
        return True
    try:
        with socket.create_connection(address, timeout=timeout):
            return True
    except OSError:
        return False


def router_answers_within(endpoint: str, timeout: float, on_wait: Callable[[], None]) -> bool:
    """True once a router listens at ``endpoint``, probing until ``timeout`` seconds have
    passed; ``on_wait`` is called once, at the first failed probe. A router that is being
    (re)started, or one a script starts beside ``mstc up``, is waited out, not reported as
    missing."""
    deadline = time.monotonic() + timeout
    waited = False
    while not port_reachable(endpoint, timeout=min(1.0, timeout)):
        if time.monotonic() >= deadline:
            return False
        if not waited:
            waited = True
            on_wait()
        time.sleep(ROUTER_PROBE_PERIOD_S)
    return True
