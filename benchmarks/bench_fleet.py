"""Fleet benchmarks (figures for docs/operations.md; not a test, nothing is asserted).

    .venv/bin/python benchmarks/bench_fleet.py latency [--fleets 4 --robots 6]
    .venv/bin/python benchmarks/bench_fleet.py startup [--robots 10]     # also RSS per process
    .venv/bin/python benchmarks/bench_fleet.py big [--robots 30 --time-scale 0]
    .venv/bin/python benchmarks/bench_fleet.py replan [--robots 20,40]
    .venv/bin/python benchmarks/bench_fleet.py all

latency: SIGKILL agents one at a time in running fleets (``mstc up`` at time scale 1 so the
mission outlasts the kills) and time, from the kill, the deletion of the robot's liveliness
token and the first DeathNotice a peer publishes; it also counts death notices about robots
that were never killed (false suspicions). startup: wall time from starting ``mstc up`` to
every agent having announced itself, then the resident memory of each process. big: a full
mission (default 30 robots on grid30x20, 2400 sub-cells, ``--algo`` opt) through ``mstc up``:
wall time, the time from every agent announced to the first move (the plan, computed once in a
crowd, and the digests), and the executed makespan over the planner's makespan. replan: for
each fleet size, robot k/2 killed at 30 % coverage (time scale 0, opt on grid30x20), once
with the crowd's re-plan shared by its lowest survivor (the default) and once with every
survivor computing it (``--replan-share-from 1000``), one after the other: seconds from the
death being known to the first and the last survivor's re-plan, how the survivors had it,
and the mission's wall time.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from bus import keys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.messages import DeathNotice, RobotStatus
from deploy.errors import FleetError
from deploy.fleet import FleetInfo, RunDir

MAIN = "import sys; from deploy.cli import main; sys.exit(main())"


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


class UpProcess:
    """A background ``mstc up`` whose stdout lines are collected by a thread."""

    def __init__(self, run_dir: Path, *args: str) -> None:
        self.run_dir = run_dir
        self.port = free_port()
        self.t0 = time.monotonic()
        self.proc = subprocess.Popen(
            [sys.executable, "-c", MAIN, "up", "--plain", "--listen",
             f"tcp/127.0.0.1:{self.port}", "--run-dir", str(run_dir), *args],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[tuple[float, str]] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append((time.monotonic(), line.rstrip()))

    def wait_line(self, text: str, timeout: float) -> float:
        """Monotonic time the first line containing ``text`` was read."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for at, line in list(self.lines):
                if text in line:
                    return at
            if self.proc.poll() is not None and not self._reader.is_alive():
                break
            time.sleep(0.02)
        tail = "\n".join(line for _, line in self.lines[-15:])
        raise RuntimeError(f"no line with {text!r} from mstc up:\n{tail}")

    def fleet(self) -> FleetInfo:
        """fleet.json once it lists every agent (mstc up rewrites it as each one starts)."""
        deadline = time.monotonic() + 600
        while True:
            if (self.run_dir / "fleet.json").exists():
                info = RunDir(self.run_dir).read_fleet()
                if sum(p.role == "agent" for p in info.processes) == info.robots:
                    return info
            if time.monotonic() > deadline or self.proc.poll() is not None:
                raise RuntimeError("mstc up did not write a complete fleet.json")
            time.sleep(0.05)

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        code = self.proc.wait(120)
        self._reader.join(5)
        return code


def _lease(args: argparse.Namespace) -> list[str]:
    return [] if args.lease_ms is None else ["--lease-ms", str(args.lease_ms)]


def rss_mb(pid: int) -> float | None:
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    except OSError:
        return None
    return None


def pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, round(q * (len(ordered) - 1)))]


# --- latency --------------------------------------------------------------------------------

async def _kill_series(info: FleetInfo, victims: list[int], gap: float, sig: int
                       ) -> tuple[list[float], list[float], int]:
    settings = ConnectionSettings(connect=(info.endpoint,), mission=info.mission)
    deaths: dict[int, float] = {}
    tokens_gone: dict[int, float] = {}
    statuses: set[int] = set()
    killed: set[int] = set()
    false_suspicions = 0

    def on_death(_key: str, notice: DeathNotice) -> None:
        nonlocal false_suspicions
        if notice.robot not in killed and notice.robot not in deaths:
            false_suspicions += 1
        deaths.setdefault(notice.robot, time.monotonic())

    def on_token_gone(key: str) -> None:
        parsed = keys.parse(key)
        if parsed is not None and parsed.robot is not None:
            tokens_gone.setdefault(parsed.robot, time.monotonic())

    async with Bus.connect(settings) as bus:
        bus.subscribe(keys.all_deaths(info.mission), DeathNotice, on_death)
        bus.subscribe(keys.all_statuses(info.mission), RobotStatus,
                      lambda _k, st: statuses.add(st.robot))
        bus.watch_liveliness(keys.all_alive(info.mission), lambda _k: None, on_token_gone)
        async with asyncio.timeout(120):
            while len(statuses) < info.robots:
                await asyncio.sleep(0.05)
        await asyncio.sleep(1.0)  # let the agents reach their steady heartbeat
        death_lat, token_lat = [], []
        for robot in victims:
            t_kill = time.monotonic()
            killed.add(robot)
            os.kill(info.agent(robot).pid, sig)
            async with asyncio.timeout(15):
                while robot not in deaths:
                    await asyncio.sleep(0.005)
            if sig != signal.SIGKILL:  # a hung (stopped) process: end it for good now
                os.kill(info.agent(robot).pid, signal.SIGKILL)
            death_lat.append(deaths[robot] - t_kill)
            if robot in tokens_gone:
                token_lat.append(tokens_gone[robot] - t_kill)
            await asyncio.sleep(gap)
    return death_lat, token_lat, false_suspicions


def bench_latency(args: argparse.Namespace, root: Path) -> None:
    deaths: list[float] = []
    tokens: list[float] = []
    false_total = 0
    for fleet in range(args.fleets):
        # --insecure: this bench's own session listens to the fleet without credentials
        # (a secured router would never admit it, and the bench would wait forever)
        up = UpProcess(root / f"latency-{fleet}", "--insecure", "-n", str(args.robots),
                       "--world", "office",
                       "--time-scale", "1", *_lease(args),
                       "--stall-timeout", "600", "--seed", str(fleet),
                       *[f"--agent-arg={a}" for a in args.agent_arg])
        try:
            info = up.fleet()
            sig = signal.SIGSTOP if args.hang else signal.SIGKILL
            d, t, f = asyncio.run(_kill_series(info, list(range(1, args.robots)), args.gap,
                                               sig))
            deaths += d
            tokens += t
            false_total += f
        finally:
            up.stop()
    what = "SIGSTOP" if args.hang else "SIGKILL"
    print(f"{what} -> first DeathNotice from a peer, {len(deaths)} kills: "
          f"median {1000 * statistics.median(deaths):.0f} ms, p95 {1000 * pct(deaths, .95):.0f} "
          f"ms, max {1000 * max(deaths):.0f} ms")
    if tokens:
        print(f"{what} -> liveliness token deleted, {len(tokens)} kills: median "
              f"{1000 * statistics.median(tokens):.1f} ms, p95 {1000 * pct(tokens, .95):.1f} ms")
    print(f"death notices about robots never killed (false suspicions): {false_total}")


# --- start-up and memory --------------------------------------------------------------------

def bench_startup(args: argparse.Namespace, root: Path) -> None:
    up = UpProcess(root / "startup", "-n", str(args.robots), "--world", "office",
                   "--time-scale", "1", "--stall-timeout", "600")
    try:
        ready = up.wait_line("mission started", 180)
        print(f"{args.robots} robots: mstc up start -> every agent announced: "
              f"{ready - up.t0:.1f} s wall")
        time.sleep(2.0)
        info = up.fleet()
        by_role: dict[str, list[float]] = {}
        for proc in info.processes:
            mb = rss_mb(proc.pid)
            if mb is not None:
                by_role.setdefault(proc.role, []).append(mb)
        for role, values in sorted(by_role.items()):
            print(f"RSS {role:6s}: median {statistics.median(values):.0f} MB, "
                  f"max {max(values):.0f} MB ({len(values)} processes)")
    finally:
        up.stop()


# --- the big mission ------------------------------------------------------------------------

class ProcessSampler:
    """Samples every fleet process's CPU time and peak resident memory from /proc once a
    second (in a thread), so a process's last sample is its figure even after it exits."""

    def __init__(self, run_dir: Path) -> None:
        self.run_dir = run_dir
        self.cpu: dict[str, tuple[str, float]] = {}  # name -> (role, CPU seconds)
        self.peak: dict[str, tuple[str, float]] = {}  # name -> (role, peak RSS MB)
        self.done = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        tick = os.sysconf("SC_CLK_TCK")
        while not self.done.wait(1.0):
            try:
                info = RunDir(self.run_dir).read_fleet()
            except FleetError:
                continue
            for proc in info.processes:
                try:
                    stat = Path(f"/proc/{proc.pid}/stat").read_text().rsplit(")", 1)[1].split()
                    status = Path(f"/proc/{proc.pid}/status").read_text()
                except OSError:
                    continue
                if stat[0] == "Z":
                    continue
                self.cpu[proc.name] = (proc.role, (int(stat[11]) + int(stat[12])) / tick)
                for line in status.splitlines():
                    if line.startswith("VmHWM:"):
                        self.peak[proc.name] = (proc.role, int(line.split()[1]) / 1024)

    def stop(self) -> None:
        self.done.set()
        self._thread.join(5)

    def report(self) -> list[str]:
        lines = []
        for what, table, unit in (("CPU", self.cpu, "s"), ("peak RSS", self.peak, "MB")):
            by_role: dict[str, list[float]] = {}
            for role, value in table.values():
                by_role.setdefault(role, []).append(value)
            for role, values in sorted(by_role.items()):
                lines.append(f"{what} {role:8s}: median {statistics.median(values):.1f} {unit}, "
                             f"max {max(values):.1f} {unit}, total {sum(values):.1f} {unit} "
                             f"({len(values)} processes)")
        return lines


def bench_big(args: argparse.Namespace, root: Path) -> None:
    run_dir = root / "big"
    up = UpProcess(run_dir, "-n", str(args.robots), "--world", args.world, "--algo", args.algo,
                   "--time-scale", str(args.time_scale), "--stall-timeout", "120",
                   "--start-timeout", "600", *_lease(args),
                   *[f"--agent-arg={a}" for a in args.agent_arg])
    sampler = ProcessSampler(run_dir)
    code = up.proc.wait(1800)
    up.stop()
    sampler.stop()
    (root / "up.txt").write_text("".join(f"{at - up.t0:7.2f} {line}\n" for at, line in up.lines))
    summary = json.loads((run_dir / "summary.json").read_text())
    print("\n".join(line for _, line in up.lines[-8:]))
    started = next((at for at, line in up.lines if "mission started" in line), None)
    moving = next((at for at, line in up.lines if _FIRST_MOVES.search(line)), None)
    planning = ("never" if started is None or moving is None else
                f"{moving - started:.1f} s (to the first progress line with moves)")
    print(f"{args.robots} robots, {args.algo}, on {args.world} at time scale "
          f"{args.time_scale:g}: exit {code}, "
          f"wall {time.monotonic() - up.t0:.1f} s, start-up (mstc up start -> all announced) "
          f"{'never' if started is None else f'{started - up.t0:.1f} s'}, planning (all "
          f"announced -> moving) {planning}, coverage "
          f"{summary['coverage']:.1f} %, robots lost {len(summary['robots_lost'])}, "
          f"executed makespan {summary['makespan_moves']} / planned "
          f"{summary['planned_makespan']} = "
          f"{summary['makespan_moves'] / summary['planned_makespan']:.3f}")
    print("\n".join(sampler.report()))
    print(f"load average after the run: {' '.join(f'{x:.1f}' for x in os.getloadavg())}")


_SECONDS = re.compile(r"^\[ *([\d.]+)s\] ")
_FIRST_MOVES = re.compile(r"moves [1-9]")


def _at(line: str) -> float | None:
    """The mission time ``mstc up`` stamps its line with."""
    found = _SECONDS.match(line)
    return None if found is None else float(found.group(1))


def bench_replan(args: argparse.Namespace, root: Path) -> None:
    sizes = [int(n) for n in str(args.robots).split(",")]
    for robots in sizes:
        for label, extra in (("shared", ()), ("every survivor",
                                               ("--agent-arg=--replan-share-from=1000",))):
            run_dir = root / f"replan-{robots}-{label.replace(' ', '-')}"
            up = UpProcess(run_dir, "-n", str(robots), "--world", args.world, "--algo", "opt",
                           "--time-scale", "0", "--kill", f"{robots // 2}@progress=30",
                           *extra, *[f"--agent-arg={a}" for a in args.agent_arg])
            code = up.proc.wait(1800)
            wall = time.monotonic() - up.t0
            up.stop()
            lines = [line for _, line in up.lines]
            known = next((_at(ln) for ln in lines if "declared dead" in ln), None)
            replans = [ln for ln in lines if " re-planned: " in ln]
            times = sorted(t for t in map(_at, replans) if t is not None)
            hows: dict[str, int] = {}
            for ln in replans:
                how = re.sub(r"robot \d+", "robot R", ln.split("moves to walk", 1)[-1]
                             .split(" (reports", 1)[0].lstrip(", ")) or "computed alone"
                hows[how] = hows.get(how, 0) + 1
            verdict = next((ln.split(":", 1)[1].split("—")[0].strip() for ln in lines
                            if ln.startswith("mission ")), "no verdict")
            after = ("no re-plan" if known is None or not times else
                     f"{times[0] - known:.1f}-{times[-1] - known:.1f} s after the death")
            print(f"{robots} robots, {label:14s}: exit {code}, {verdict}, re-planned {after}, "
                  f"{len(replans)} re-plans ({', '.join(f'{n} {h}' for h, n in hows.items())}),"
                  f" wall {wall:.1f} s", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("what", choices=("latency", "startup", "big", "replan", "all"))
    parser.add_argument("--robots", default=None,
                        help="fleet size (replan: sizes separated by commas, default 20,40)")
    parser.add_argument("--fleets", type=int, default=4)
    parser.add_argument("--hang", action="store_true",
                        help="latency: SIGSTOP (a hung robot) instead of SIGKILL")
    parser.add_argument("--gap", type=float, default=1.0, help="seconds between kills")
    parser.add_argument("--world", default="grid30x20")
    parser.add_argument("--algo", default="opt",
                        help="big: the offline algorithm the fleet flies (default opt)")
    parser.add_argument("--lease-ms", type=int, default=None,
                        help="transport lease of every process (default: mstc up's)")
    parser.add_argument("--time-scale", type=float, default=0.0)
    parser.add_argument("--keep", type=Path, default=None, metavar="DIR",
                        help="keep the run directories (and mstc up's output) under DIR")
    parser.add_argument("--agent-arg", action="append", default=[],
                        help="extra agent option, e.g. --agent-arg=--dead-after=0.5")
    args = parser.parse_args()
    defaults: dict[str, int | str] = {"latency": 6, "startup": 10, "big": 30, "replan": "20,40"}
    with tempfile.TemporaryDirectory(prefix="bench_fleet_") as tmp:
        root = Path(tmp) if args.keep is None else args.keep
        for what in (("latency", "startup", "big") if args.what == "all" else (args.what,)):
            sub = argparse.Namespace(**vars(args))
            sub.robots = args.robots or defaults[what]
            if what != "replan":
                sub.robots = int(sub.robots)
            {"latency": bench_latency, "startup": bench_startup, "big": bench_big,
             "replan": bench_replan}[what](sub, root)


if __name__ == "__main__":
    main()
