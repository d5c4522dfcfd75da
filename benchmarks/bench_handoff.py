"""What bus.handoff costs: a burst of samples into one subscription, handed over by a thread
of the declaration's own (Zenoh's ``indirect`` callback: the code) against Zenoh's receive
thread calling the hand-over itself (before), alternated in one run. (What it buys, a link
read whatever the loop does on a starved host, is in docs/operations.md, "Flat out": a
synthetic busy loop beside busy processes did not reproduce it, 1-7 ms either way.)
Starts its own ``mstc router`` on a free port.

    .venv/bin/python benchmarks/bench_handoff.py [--rounds 3] [--burst 20000]
"""

from __future__ import annotations

import argparse
import asyncio
import socket
import statistics
import time
from collections.abc import Callable
from typing import Any

import zenoh

import bus.bridge
from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import ConnectionSettings
from bus.handoff import handed_off
from bus.messages import Progress
from bus.router import start_router_process, stop_process

MISSION = "bench"


def direct(declare: Callable[[Any], Any], on_item: Callable[[Any], None], name: str) -> Any:
    """Before bus.handoff: Zenoh's receive thread runs the hand-over."""
    return declare(zenoh.handlers.Callback(on_item, indirect=False))


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


async def burst(endpoint: str, n: int) -> tuple[float, float]:
    """(messages per second, CPU microseconds per message of this process)."""
    settings = ConnectionSettings(connect=(endpoint,), mission=MISSION)
    async with Bus.connect(settings) as rx, Bus.connect(settings) as tx:
        sub = rx.subscribe(keys.all_progress(MISSION), Progress, policy=BoundedFifo(n + 1))
        await asyncio.sleep(0.3)
        msg = Progress(2, 1, 0, (0, 0), 0.0)
        cpu, start = time.process_time(), time.perf_counter()
        for _ in range(n):
            tx.publish(keys.progress(MISSION, 2), msg)
        async with asyncio.timeout(60):
            for _ in range(n):
                await sub.recv()
        wall = time.perf_counter() - start
        return n / wall, (time.process_time() - cpu) / n * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--burst", type=int, default=20000)
    args = parser.parse_args()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = start_router_process(endpoint)
    modes = {"handoff (code)": handed_off, "direct (before)": direct}
    rates: dict[str, list[float]] = {m: [] for m in modes}
    cpus: dict[str, list[float]] = {m: [] for m in modes}
    try:
        for _ in range(args.rounds):
            for mode, declare in modes.items():
                bus.bridge.handed_off = declare
                rate, cpu = asyncio.run(burst(endpoint, args.burst))
                rates[mode].append(rate)
                cpus[mode].append(cpu)
    finally:
        bus.bridge.handed_off = handed_off
        stop_process(router)
    for mode in modes:
        print(f"{mode:16s} burst of {args.burst}: {statistics.median(rates[mode]):9,.0f} msg/s, "
              f"{statistics.median(cpus[mode]):5.1f} us CPU per message (median of "
              f"{args.rounds})")

if __name__ == "__main__":
    main()
