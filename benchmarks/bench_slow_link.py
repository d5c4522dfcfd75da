"""A fleet over two hosts whose link is slow: how narrow a link between hosts still carries a
mission, and what a narrower one does (docs/operations.md, "Several hosts").

    .venv/bin/python benchmarks/bench_slow_link.py [--rates 1mbit,100kbit,64kbit]
        [--router-lease-ms 1000] [--router-sndbuf BYTES] [--algo opt] [--time-scale 50]
        [--limit 300] [--logs DIR]

Two network namespaces on one switch (deploy.chaos.hosts; needs root), the link of the far
host shaped by ``tc tbf`` in both directions (rate, 8 kB burst, 300 ms of queue). The near
host runs its router, simhw, a recording monitor and robots 0-1; the far host its router,
joined to the near one, and robots 2-3 (example world, 4 robots; every far robot's moves
go to simhw across the link). Printed per rate: the monitor's verdict and wall time, each
robot's exit code (4: fenced), the deaths declared and why, and what the link carried.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import tempfile
import time
from pathlib import Path

from bus.router import READY_MARK
from deploy.chaos.hosts import Host, hosts, hosts_problem
from deploy.fleet import mstc_argv

STARTS = "0,0;5,20;15,3;20,25"
WORLD = ("--world", "example")
MISSION = "slow"


def _wait_for(log: Path, text: str, proc: subprocess.Popen[bytes], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if log.exists() and text in log.read_text(errors="replace"):
            return
        if proc.poll() is not None:
            raise SystemExit(f"{log.name}: exited {proc.returncode}")
        time.sleep(0.05)
    raise SystemExit(f"{log.name} never said {text!r}")


def _shape(namespace: str, device: str, rate: str) -> None:
    subprocess.run(["ip", "netns", "exec", namespace, "tc", "qdisc", "add", "dev", device,
                    "root", "tbf", "rate", rate, "burst", "8kb", "latency", "300ms"],
                   check=True)


def _carried(namespace: str, device: str) -> str:
    shown = subprocess.run(["ip", "netns", "exec", namespace, "tc", "-s", "qdisc", "show",
                            "dev", device], capture_output=True, text=True, check=True).stdout
    found = re.search(r"Sent (\d+) bytes (\d+) pkt \(dropped (\d+)", shown)
    return "?" if found is None else \
        f"{int(found[1]) / 1000:.0f} kB in {found[2]} packets, {found[3]} dropped"


def _buffers(size: int | None, logs: Path) -> tuple[str, ...]:
    """The routers' --zenoh-config setting their TCP socket buffers to ``size`` bytes."""
    if size is None:
        return ()
    config = logs / "router-buffers.json5"
    buffers = {"so_sndbuf": size, "so_rcvbuf": size}
    config.write_text(json.dumps({"transport": {"link": {"tcp": buffers}}}) + "\n")
    return ("--zenoh-config", str(config))


def trial(rate: str, args: argparse.Namespace, logs: Path) -> None:
    started: dict[str, subprocess.Popen[bytes]] = {}

    def start(name: str, host: Host, command: str, *argv: str) -> Path:
        log = logs / f"{name}.log"
        with log.open("wb") as out:
            started[name] = subprocess.Popen(host.run(mstc_argv(command, *argv)),
                                             stdin=subprocess.DEVNULL, stdout=out,
                                             stderr=subprocess.STDOUT)
        return log

    with hosts(2, prefix="sl") as (near, far):
        tag = near.name.split("-")[0]
        hub, port = f"{tag}-hub", f"{tag}p1"[-15:]  # the switch's end of the far link
        _shape(far.name, far.link, rate)
        _shape(hub, port, rate)
        lease = ("--lease-ms", str(args.router_lease_ms), *_buffers(args.router_sndbuf, logs))
        link = ("--mode", "client", "--mission", MISSION)
        try:
            log = start("router-0", near, "router", "--listen", near.endpoint,
                        "--exit-with-parent", *lease)
            _wait_for(log, READY_MARK, started["router-0"], 20)
            log = start("router-1", far, "router", "--listen", far.endpoint, "--connect",
                        near.endpoint, "--exit-with-parent", *lease)
            _wait_for(log, READY_MARK, started["router-1"], 20)
            log = start("simhw", near, "simhw", *WORLD, "--starts", STARTS, "--seed", "0",
                        "--time-scale", str(args.time_scale), "--connect", near.endpoint,
                        *link)
            _wait_for(log, "simhw ready", started["simhw"], 30)
            log = start("monitor", near, "monitor", "--connect", near.endpoint, "--mission",
                        MISSION, "--plain", "--exit-when-done", "--duration", str(args.limit))
            _wait_for(log, "world example", started["monitor"], 30)
            began = time.monotonic()
            for robot, host in ((0, near), (1, near), (2, far), (3, far)):
                start(f"agent-{robot}", host, "agent", "--id", str(robot), "--algo", args.algo,
                      *WORLD, "--tree", "dfs", "--seed", "0", "--robots", "4", "--connect",
                      host.endpoint, *link)
            started["monitor"].wait(args.limit + 30)
            wall = time.monotonic() - began
            codes = []
            for robot in range(4):
                try:
                    codes.append(str(started[f"agent-{robot}"].wait(30)))
                except subprocess.TimeoutExpired:
                    codes.append("running")
            out, back = _carried(far.name, far.link), _carried(hub, port)
        finally:
            for proc in started.values():
                if proc.poll() is None:
                    proc.kill()
                proc.wait(10)
    watched = (logs / "monitor.log").read_text(errors="replace")
    summary = re.findall(r"summary +(coverage [^,]+)", watched)
    deaths = re.findall(r"robot (\d+) declared dead by robot (\d+) \((\w+)", watched)
    print(f"{rate:>8} | {'complete' if 'mission complete' in watched else 'NOT complete'}, "
          f"{summary[-1] if summary else '?'} | {wall:5.1f} s | exit codes {' '.join(codes)} "
          f"| deaths {', '.join(f'{d} by {by} ({why})' for d, by, why in deaths) or 'none'} "
          f"| far -> near {out}; near -> far {back}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rates", default="1mbit,100kbit,64kbit",
                        help="comma-separated tc rates of the far host's link")
    parser.add_argument("--router-lease-ms", type=int, default=1000,
                        help="the two routers' transport lease (the agents keep 1000)")
    parser.add_argument("--router-sndbuf", type=int, default=None,
                        help="the two routers' TCP send and receive buffers in bytes "
                             "(default: the kernel's)")
    parser.add_argument("--algo", default="opt")
    parser.add_argument("--time-scale", type=float, default=50.0)
    parser.add_argument("--limit", type=float, default=300.0,
                        help="seconds the monitor waits for the mission")
    parser.add_argument("--logs", type=Path, default=None,
                        help="keep every process's log under DIR/<rate> (default: dropped)")
    args = parser.parse_args()
    problem = hosts_problem()
    if problem is not None:
        raise SystemExit(f"bench_slow_link: {problem}")
    print(f"router lease {args.router_lease_ms} ms, {args.algo}, time scale {args.time_scale}")
    for rate in args.rates.split(","):
        if args.logs is not None:
            (args.logs / rate).mkdir(parents=True, exist_ok=True)
            trial(rate, args, args.logs / rate)
            continue
        with tempfile.TemporaryDirectory(prefix="mstc-slow-") as logs:
            trial(rate, args, Path(logs))


if __name__ == "__main__":
    main()
