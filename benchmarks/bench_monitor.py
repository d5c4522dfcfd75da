"""Can the monitor keep up with a 30-robot mission? Messages/s sustained, lag, queue, CPU.

Run: .venv/bin/python benchmarks/bench_monitor.py [--robots 30] [--moves-per-s 20]
     [--seconds 8] [--scales 1,2,4]

A publisher subprocess plays a fleet of ``robots`` bodies each moving ``moves-per-s``
sub-cells per second (times each scale): per move a CoverEvent, a GroundTruthPose and a
Progress (what simhw and an agent publish), plus 5 heartbeats per robot per second, and it
answers the world query. The monitor runs in this process with its rich view rendered to a
null console (at most 4 Hz), recording to a temporary file, as ``mstc monitor --record``.
Printed per scale: offered messages/s, messages sent and received, the monitor's drops
(decode or overflow), its largest queue, the lag from publication to model update
(median/p99/max) and the monitor's CPU share (process CPU time / wall time, Zenoh threads
included). Keeping up = no drops, a bounded queue, lag well under a second.
"""

from __future__ import annotations

import argparse
import asyncio
import io
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from rich.console import Console

from bus import keys
from bus.bridge import Bus
from bus.config import ConnectionSettings
from bus.messages import (
    CoverEvent,
    GroundTruthPose,
    Heartbeat,
    Progress,
    RobotTruth,
    make_world_state,
)
from bus.router import start_router_process, stop_process
from deploy.monitor.app import RichScreen, Watcher, watch_live
from deploy.monitor.types import Record

STRIP_W = 400  # each robot snakes along its own 2-row strip of this many sub-cells


def _cell(robot: int, step: int) -> tuple[int, int]:
    row, col = divmod(step, STRIP_W)
    return (2 * robot + row % 2, col if row % 2 == 0 else STRIP_W - 1 - col)


async def publish(settings: ConnectionSettings, robots: int, rate: float,
                  seconds: float) -> None:
    """The fleet's publications at ``rate`` moves per robot per second."""
    async with Bus.connect(settings) as bus:
        m, free = bus.mission, np.ones((2 * robots, STRIP_W), dtype=bool)
        steps = [0] * robots

        def world(_request: object) -> object:
            visits = np.zeros(free.shape, dtype=np.int64)
            for r in range(robots):
                for s in range(steps[r] + 1):
                    visits[_cell(r, s)] = 1
            truth = tuple(RobotTruth(r, (*_cell(r, steps[r]), 1), True, False, False,
                                     steps[r] + 1) for r in range(robots))
            return make_world_state("bench", free, visits, truth, time.time(), 0.0)

        bus.declare_queryable(keys.world(m), world)
        await asyncio.sleep(1.0)
        start, beat, sent = time.monotonic(), 0.0, 0
        while (now := time.monotonic()) - start < seconds:
            due = int((now - start) * rate)
            for r in range(robots):
                while steps[r] < due:
                    steps[r] += 1
                    cell, stamp = _cell(r, steps[r]), time.time()
                    bus.publish(keys.sim_cover(m, r), CoverEvent(r, cell, stamp, 1))
                    bus.publish(keys.sim_pose(m, r), GroundTruthPose(r, (*cell, 1), stamp))
                    bus.publish(keys.progress(m, r), Progress(r, 1, steps[r], cell, stamp))
                    sent += 3
            if now - beat >= 0.2:
                beat = now
                for r in range(robots):
                    bus.publish(keys.heartbeat(m, r), Heartbeat(
                        r, 1, sent, (*_cell(r, steps[r]), 1), "covering", time.time()))
                    sent += 1
            await asyncio.sleep(0.005)
        print(f"sent {sent}", flush=True)
        await asyncio.sleep(0.5)


class LagWatcher(Watcher):
    """A Watcher that also measures publish-to-model lag (stamps are wall times)."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.lags: list[float] = []
        self.received = 0

    def feed(self, records: object) -> None:
        batch = list(records)  # type: ignore[call-overload]
        super().feed(batch)
        now = time.time()
        self.received += sum(1 for r in batch if r.via == "sub")
        self.lags += [now - r.msg.sim_time for r in batch if isinstance(r, Record)
                      and isinstance(r.msg, (CoverEvent, Heartbeat)) and r.via == "sub"]


async def watch(settings: ConnectionSettings, publisher: subprocess.Popen[str],
                record: Path) -> dict[str, float]:
    """Run the monitor until the publisher has finished (and half a second more)."""
    watcher = LagWatcher(RichScreen(Console(file=io.StringIO(), width=160, height=50,
                                            force_terminal=True)))
    stop = asyncio.Event()

    async def stop_after_publisher() -> None:
        await asyncio.to_thread(publisher.wait)
        await asyncio.sleep(0.5)
        stop.set()

    wall, cpu = time.monotonic(), time.process_time()
    async with asyncio.TaskGroup() as group:
        group.create_task(stop_after_publisher())
        stats = await watch_live(settings, watcher, stop=stop, record=record,
                                 world_period=2.0)
    wall, cpu = time.monotonic() - wall, time.process_time() - cpu
    lags = sorted(watcher.lags) or [0.0]
    return {"handled": watcher.received, "wall": wall, "cpu": cpu / wall,
            "drops": stats.dropped, "max_queue": stats.max_queue,
            "lag_median": statistics.median(lags), "lag_p99": lags[int(0.99 * (len(lags) - 1))],
            "lag_max": lags[-1]}


def run_scale(endpoint: str, robots: int, rate: float, seconds: float, index: int) -> None:
    mission = f"bench{index}"
    settings = ConnectionSettings(connect=(endpoint,), mission=mission)
    publisher = subprocess.Popen(
        [sys.executable, __file__, "--publish", "--connect", endpoint, "--mission", mission,
         "--robots", str(robots), "--moves-per-s", str(rate), "--seconds", str(seconds)],
        stdout=subprocess.PIPE, text=True)
    with tempfile.TemporaryDirectory() as tmp:
        got = asyncio.run(watch(settings, publisher, Path(tmp) / "rec.jsonl"))
    assert publisher.stdout is not None
    out = publisher.stdout.read()
    publisher.stdout.close()
    sent = int(out.split()[-1]) if out.strip() else 0
    offered = robots * (3 * rate + 5)
    print(f"{rate:6.0f} moves/s/robot  offered {offered:7.0f} msg/s  sent {sent:6d}  "
          f"received {int(got['handled']):6d}  drops {int(got['drops'])}  "
          f"max queue {int(got['max_queue']):5d}  lag median {1000 * got['lag_median']:6.1f} ms "
          f"p99 {1000 * got['lag_p99']:7.1f} ms max {1000 * got['lag_max']:7.1f} ms  "
          f"CPU {100 * got['cpu']:5.1f} %", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", type=int, default=30)
    parser.add_argument("--moves-per-s", type=float, default=20.0)
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--scales", default="1,2,4",
                        help="multiples of --moves-per-s to try (default 1,2,4)")
    parser.add_argument("--publish", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--connect", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--mission", default="bench", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.publish:
        settings = ConnectionSettings(connect=(args.connect,), mission=args.mission)
        asyncio.run(publish(settings, args.robots, args.moves_per_s, args.seconds))
        return
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{sock.getsockname()[1]}"
    router = start_router_process(endpoint)
    try:
        print(f"{args.robots} robots, {args.seconds:g} s per run, monitor with rich view "
              f"and recording", flush=True)
        for i, scale in enumerate(float(s) for s in args.scales.split(",")):
            run_scale(endpoint, args.robots, args.moves_per_s * scale, args.seconds, i)
    finally:
        stop_process(router)


if __name__ == "__main__":
    main()
