"""Figures for docs/protocol.md: codec cost, latency and throughput through the bridge,
failure-detection latency after SIGKILL, and how often a census (a liveliness get, the
detector's check of a token deletion) comes back short, from a session that watches the
tokens and from one that does not, on a quiet host and beside one busy process per core
(the short answers come with load). Starts its own ``mstc router`` on a free port.

    .venv/bin/python benchmarks/bench_bus.py [--trials 10] [--gets 1000]
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import os
import signal
import socket
import statistics
import subprocess
import sys
import time
import timeit

from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.codec import decode, encode
from bus.config import ConnectionSettings
from bus.liveness import LivelinessService
from bus.messages import DeathNotice, Heartbeat, Progress
from bus.router import start_router_process, stop_process
from deploy.chaos.inject import busy_processes

ROBOT = """
import asyncio, sys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.liveness import LivelinessService

async def main():
    settings = ConnectionSettings(connect=(sys.argv[1],), mission=sys.argv[2])
    async with Bus.connect(settings) as bus:
        service = LivelinessService(bus, robot=int(sys.argv[3]), incarnation=1)
        print("ready", flush=True)
        await service.run()

asyncio.run(main())
"""


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def bench_codec() -> None:
    hb = Heartbeat(robot=3, incarnation=1, seq=42, pose=(10, 20, 1), state="covering",
                   sim_time=12.5)
    payload = encode(hb)
    n = 20000
    enc = timeit.timeit(lambda: encode(hb), number=n) / n * 1e6
    dec = timeit.timeit(lambda: decode(payload, Heartbeat), number=n) / n * 1e6
    print(f"codec Heartbeat: {len(payload)} bytes, encode {enc:.1f} us, "
          f"strict decode {dec:.1f} us")


async def bench_latency_throughput(endpoint: str) -> None:
    settings = ConnectionSettings(connect=(endpoint,), mission="bench")
    async with Bus.connect(settings) as rx, Bus.connect(settings) as tx:
        arrivals: list[float] = []
        sent: dict[int, float] = {}
        timing = rx.subscribe(keys.all_progress("bench"), Progress,
                              lambda _k, m: arrivals.append(time.perf_counter() - sent[m.seq]))
        await asyncio.sleep(0.5)
        for seq in range(500):
            sent[seq] = time.perf_counter()
            tx.publish(keys.progress("bench", 1), Progress(1, 1, seq, (0, 0), 0.0))
            await asyncio.sleep(0.002)
        await asyncio.sleep(0.5)
        timing.close()
        lat = sorted(arrivals)
        p50, p99 = lat[len(lat) // 2] * 1e6, lat[int(len(lat) * 0.99)] * 1e6
        print(f"put -> handler on loop, {len(lat)}/500 received: p50 {p50:.0f} us, "
              f"p99 {p99:.0f} us")

        sub = rx.subscribe(keys.all_progress("bench"), Progress, policy=BoundedFifo(100000))
        await asyncio.sleep(0.3)
        n = 20000
        start = time.perf_counter()
        msg = Progress(2, 1, 0, (0, 0), 0.0)  # its key's robot: decoding checks the two agree
        for _ in range(n):
            tx.publish(keys.progress("bench", 2), msg)
        got = 0
        async with asyncio.timeout(30):
            while got < n:
                await sub.recv()
                got += 1
        rate = n / (time.perf_counter() - start)
        print(f"burst of {n} Progress into one BoundedFifo subscription: {rate:,.0f} msg/s "
              f"(drops {rx.drops.total()})")


async def bench_detection(endpoint: str, trials: int) -> None:
    latencies: list[float] = []
    for trial in range(trials):
        mission = f"detect{trial}"
        deaths: list[DeathNotice] = []
        settings = ConnectionSettings(connect=(endpoint,), mission=mission)
        async with Bus.connect(settings) as bus:
            service = LivelinessService(bus, robot=0, incarnation=1, on_death=deaths.append)
            async with asyncio.TaskGroup() as group:
                task = group.create_task(service.run())
                proc = subprocess.Popen([sys.executable, "-c", ROBOT, endpoint, mission, "1"],
                                        stdout=subprocess.PIPE, text=True)
                assert proc.stdout is not None
                proc.stdout.readline()
                await asyncio.sleep(0.5)
                proc.send_signal(signal.SIGKILL)
                killed = time.monotonic()
                async with asyncio.timeout(10):
                    while not deaths:
                        await asyncio.sleep(0.002)
                latencies.append(time.monotonic() - killed)
                proc.wait()
                proc.stdout.close()
                task.cancel()
    print(f"SIGKILL -> DeathNotice (default LivelinessService), {trials} trials: median "
          f"{statistics.median(latencies) * 1000:.0f} ms, max {max(latencies) * 1000:.0f} ms")


async def bench_census(endpoint: str, gets: int, load: str) -> None:
    """Two robots hold their tokens; a session asks for every token ``gets`` times, 20 ms
    apart, and counts the answers that lack any of the three (its own included)."""
    mission = "census"
    holders = [subprocess.Popen([sys.executable, "-c", ROBOT, endpoint, mission, str(robot)],
                                stdout=subprocess.PIPE, text=True) for robot in (1, 2)]
    try:
        for proc in holders:
            assert proc.stdout is not None
            proc.stdout.readline()
        for watching in (True, False):
            settings = ConnectionSettings(connect=(endpoint,), mission=mission)
            async with Bus.connect(settings) as bus:
                bus.declare_token(keys.alive(mission, 0, 1))
                watch = bus.watch_liveliness(keys.all_alive(mission), lambda key: None,
                                             lambda key: None) if watching else None
                await asyncio.sleep(1.0)
                sizes: collections.Counter[int | None] = collections.Counter()
                loop = asyncio.get_running_loop()
                for _ in range(gets):
                    answer: asyncio.Future[frozenset[str] | None] = loop.create_future()
                    bus.ask_tokens(keys.all_alive(mission), 1.0, answer.set_result)
                    tokens = await answer
                    sizes[None if tokens is None else len(tokens)] += 1
                    await asyncio.sleep(0.02)
                if watch is not None:
                    watch.close()
            short = gets - sizes[3]
            how = ", ".join(f"{n} with {'no answer' if size is None else f'{size} tokens'}"
                            for size, n in sizes.items() if size != 3)
            print(f"census of 3 tokens, {gets} gets, {load}, session "
                  f"{'watching' if watching else 'not watching'} the tokens: {short} short"
                  + (f" ({how})" if how else ""))
    finally:
        for proc in holders:
            proc.kill()
            proc.wait()
            assert proc.stdout is not None
            proc.stdout.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--gets", type=int, default=1000, help="liveliness gets per census run")
    args = parser.parse_args()
    bench_codec()
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = start_router_process(endpoint)
    try:
        asyncio.run(bench_latency_throughput(endpoint))
        asyncio.run(bench_detection(endpoint, args.trials))
        asyncio.run(bench_census(endpoint, args.gets, "quiet host"))
        busy = busy_processes(len(os.sched_getaffinity(0)))
        try:
            asyncio.run(bench_census(endpoint, args.gets, "one busy process per core"))
        finally:
            for proc in busy:
                proc.kill()
                proc.wait()
    finally:
        stop_process(router)


if __name__ == "__main__":
    main()
