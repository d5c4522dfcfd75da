"""What the secured bus costs (figures for docs/security.md; not a test, nothing is asserted).

    .venv/bin/python benchmarks/bench_security.py [latency|fleet|all] [--messages 3000]
                                                  [--robots 5 --algo opt --trials 3]

latency: one ``mstc router`` per configuration (plain TCP; log-in + ACL; log-in + ACL over
mTLS), a publisher logged in as robot_3 and a subscriber as observer: put -> callback
latency of small messages (p50/p99), paced at one per millisecond, and the time to open a
session (the log-in handshake). fleet: wall time of ``mstc up`` missions at time scale 0,
``--insecure`` against the default (log-in + ACL), interleaved so machine load hits both.
"""

from __future__ import annotations

import argparse
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import zenoh

from bus import keys
from bus.codec import encode
from bus.config import ConnectionSettings, TlsFiles, insert_values, make_zenoh_config
from bus.messages import Heartbeat
from bus.router import start_router_process, stop_process
from bus.security import credentials

ROOT = Path(__file__).resolve().parent.parent
MAKE_CERTS = ROOT / "scripts" / "make-certs.sh"
MISSION = "bench"
MAIN = "import sys; from deploy.cli import main; sys.exit(main())"


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@dataclass(frozen=True)
class Setup:
    name: str
    secure: bool
    tls: bool


SETUPS = (Setup("plain tcp", False, False), Setup("log-in + ACL", True, False),
          Setup("log-in + ACL + mTLS", True, True))


def _pct(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


class _Router:
    def __init__(self, setup: Setup, work: Path) -> None:
        self.creds = work / credentials.CREDENTIALS_FILE
        credentials.generate(MISSION, 6).save(self.creds)
        self.pki = work / "pki"
        args: list[str] = []
        if setup.secure:
            args += ["--credentials", str(self.creds)]
        if setup.tls:
            subprocess.run([str(MAKE_CERTS), str(self.pki), "--client", "robot_3",
                            "--client", "observer"], check=True, capture_output=True)
            args += ["--tls-ca", str(self.pki / "ca.pem"), "--tls-cert",
                     str(self.pki / "router.pem"), "--tls-key", str(self.pki / "router.key"),
                     "--mtls"]
        proto = "tls/localhost" if setup.tls else "tcp/127.0.0.1"
        self.endpoint = f"{proto}:{free_port()}"
        self.setup = setup
        self.proc = start_router_process(self.endpoint, extra_args=tuple(args))

    def session(self, role: str) -> zenoh.Session:
        tls = TlsFiles(self.pki / "ca.pem", self.pki / f"{role}.pem",
                       self.pki / f"{role}.key") if self.setup.tls else None
        settings = ConnectionSettings(
            connect=(self.endpoint,), mission=MISSION, tls=tls,
            credentials=self.creds if self.setup.secure else None,
            role=role if self.setup.secure else None)
        config = make_zenoh_config(settings)
        insert_values(config, {"connect/timeout_ms": 5000, "connect/exit_on_failure": True})
        return zenoh.open(config)

    def close(self) -> None:
        stop_process(self.proc)


class _Clock:
    """Arrival times of numbered puts (the n-th sample is the n-th put: one publisher)."""

    def __init__(self) -> None:
        self.sent: dict[int, float] = {}
        self.latencies: list[float] = []
        self.arrived = 0
        self._lock = threading.Lock()

    def on_sample(self, _sample: zenoh.Sample) -> None:
        now = time.perf_counter()
        with self._lock:
            seq = self.arrived
            self.arrived += 1
        if seq in self.sent:
            self.latencies.append((now - self.sent[seq]) * 1e6)


def _measure(router: _Router, messages: int, payload: bytes) -> tuple[list[float], int]:
    pub, sub = router.session("robot_3"), router.session("observer")
    clock = _Clock()
    try:
        subscriber = sub.declare_subscriber(
            keys.heartbeat(MISSION, 3), zenoh.handlers.Callback(clock.on_sample,
                                                                indirect=False))
        publisher = pub.declare_publisher(keys.heartbeat(MISSION, 3))
        time.sleep(0.5)
        for seq in range(messages):
            clock.sent[seq] = time.perf_counter()
            publisher.put(payload)
            time.sleep(0.001)
        time.sleep(0.5)
        subscriber.undeclare()
        publisher.undeclare()
    finally:
        pub.close()
        sub.close()
    return clock.latencies, messages - clock.arrived


def bench_latency(messages: int) -> None:
    print(f"put -> callback latency, {messages} heartbeats at 1/ms, publisher robot_3, "
          f"subscriber observer, via a router process")
    print(f"{'setup':<22} {'open ms':>8} {'p50 us':>8} {'p99 us':>8} {'lost':>5}")
    payload = encode(Heartbeat(3, 1, 1, (1, 2, 0), "covering", 1.0))
    for setup in SETUPS:
        with tempfile.TemporaryDirectory() as tmp:
            router = _Router(setup, Path(tmp))
            try:
                opens = []
                for _ in range(5):
                    t0 = time.perf_counter()
                    router.session("observer").close()
                    opens.append((time.perf_counter() - t0) * 1e3)
                got, lost = _measure(router, messages, payload)
                print(f"{setup.name:<22} {statistics.median(opens):>8.1f} "
                      f"{_pct(got, 0.5):>8.0f} {_pct(got, 0.99):>8.0f} {lost:>5}")
            finally:
                router.close()


def _mission(run_dir: Path, robots: int, algo: str, insecure: bool) -> float:
    args = [sys.executable, "-c", MAIN, "up", "--plain", "--listen",
            f"tcp/127.0.0.1:{free_port()}", "--run-dir", str(run_dir), "-n", str(robots),
            "--algo", algo, "--time-scale", "0"]
    if insecure:
        args.append("--insecure")
    t0 = time.monotonic()
    done = subprocess.run(args, capture_output=True, text=True, timeout=300)
    elapsed = time.monotonic() - t0
    if done.returncode != 0:
        raise SystemExit(f"mstc up failed ({done.returncode}): {done.stdout[-2000:]}")
    return elapsed


def bench_fleet(robots: int, algo: str, trials: int) -> None:
    print(f"mstc up -n {robots} --algo {algo} --time-scale 0: wall time (s), "
          f"{trials} interleaved trials")
    walls: dict[bool, list[float]] = {True: [], False: []}
    with tempfile.TemporaryDirectory() as tmp:
        for trial in range(trials):
            for insecure in (True, False):
                run_dir = Path(tmp) / f"{trial}-{'insecure' if insecure else 'secure'}"
                walls[insecure].append(_mission(run_dir, robots, algo, insecure))
    for insecure, name in ((True, "--insecure"), (False, "log-in + ACL (default)")):
        values = walls[insecure]
        print(f"{name:<24} median {statistics.median(values):6.2f}  "
              f"min {min(values):6.2f}  max {max(values):6.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("part", nargs="?", choices=("latency", "fleet", "all"), default="all")
    parser.add_argument("--messages", type=int, default=3000)
    parser.add_argument("--robots", type=int, default=5)
    parser.add_argument("--algo", default="opt")
    parser.add_argument("--trials", type=int, default=3)
    args = parser.parse_args()
    if args.part in ("latency", "all"):
        bench_latency(args.messages)
    if args.part in ("fleet", "all"):
        bench_fleet(args.robots, args.algo, args.trials)


if __name__ == "__main__":
    main()
