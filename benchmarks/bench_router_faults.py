"""What a subscriber still has after a router fault, plain pub/sub against the recoverable
families' advanced pub/sub (bus.recovery), for docs/protocol.md "Recoverable families".

    .venv/bin/python benchmarks/bench_router_faults.py [--trials 3]

A publisher process puts 300 samples on each of two keys at 50 per second; a third of the
way in, the router (its own ``mstc router`` on a free port) is restarted after 1 s down, or
frozen 0.8 s (SIGSTOP/SIGCONT). Printed per mode and fault: samples the subscriber ends with
out of 600 (min and max over the trials) and the misses reported.
"""

from __future__ import annotations

import argparse
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import zenoh

from bus.config import ConnectionSettings, make_zenoh_config
from bus.recovery import declare_recovering_subscriber
from bus.router import start_router_process, stop_process

SAMPLES, KEYS = 300, 2
PUBLISHER = """
import sys, time
import zenoh
from bus.config import ConnectionSettings, make_zenoh_config
from bus.qos import STREAM
from bus.recovery import Publishers

session = zenoh.open(make_zenoh_config(ConnectionSettings(connect=(sys.argv[1],),
                                                          mission="bench")))
publishers = Publishers(session)
print("ready", flush=True)
samples, keys = int(sys.argv[3]), int(sys.argv[4])
for n in range(samples):
    for i in range(keys):
        key = f"mstc/bench/sim/cover/{i}"
        if sys.argv[2] == "plain":
            session.put(key, str(n).encode())
        else:
            publishers.put(key, str(n).encode(), STREAM, 4096)
    if n == samples // 3:
        print("third", flush=True)
    time.sleep(0.02)
print("done", flush=True)
sys.stdin.read()
"""


def free_endpoint() -> str:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


def trial(mode: str, fault: str) -> tuple[int, int]:
    """Samples received and misses reported in one run."""
    endpoint = free_endpoint()
    router = start_router_process(endpoint)
    session = zenoh.open(make_zenoh_config(ConnectionSettings(connect=(endpoint,),
                                                              mission="bench")))
    got: set[tuple[str, bytes]] = set()
    missed: list[int] = []
    lock = threading.Lock()

    def on_sample(sample: zenoh.Sample) -> None:
        with lock:
            got.add((str(sample.key_expr), sample.payload.to_bytes()))

    declared = [session.declare_subscriber("mstc/bench/**", on_sample)] if mode == "plain" \
        else list(declare_recovering_subscriber(session, "mstc/bench/**", on_sample,
                                                lambda _source, n: missed.append(n)))
    publisher = subprocess.Popen([sys.executable, "-c", PUBLISHER, endpoint, mode, str(SAMPLES),
                                  str(KEYS)],
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert publisher.stdout is not None and publisher.stdin is not None
    try:
        publisher.stdout.readline()
        publisher.stdout.readline()  # a third of the way in
        if fault == "restart":
            stop_process(router)
            time.sleep(1.0)
            router = start_router_process(endpoint)
        else:
            os.kill(router.pid, signal.SIGSTOP)
            time.sleep(0.8)
            os.kill(router.pid, signal.SIGCONT)
        publisher.stdout.readline()
        time.sleep(3.0)  # recovery: heartbeats every 0.5 s, then the cache's answer
        with lock:
            return len(got), sum(missed)
    finally:
        publisher.stdin.close()
        publisher.wait(10.0)
        for item in declared:
            item.undeclare()
        session.close()
        stop_process(router)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=3)
    args = parser.parse_args()
    print(f"{'mode':9} {'fault':8} samples of {SAMPLES * KEYS} (min..max), misses reported")
    for mode in ("plain", "advanced"):
        for fault in ("restart", "freeze"):
            runs = [trial(mode, fault) for _ in range(args.trials)]
            counts = [n for n, _ in runs]
            print(f"{mode:9} {fault:8} {min(counts)}..{max(counts)}, "
                  f"{sum(m for _, m in runs)}", flush=True)


if __name__ == "__main__":
    main()
