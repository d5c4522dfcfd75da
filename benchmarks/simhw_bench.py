"""Throughput of the simulated hardware: commands per second, in process and over Zenoh.

    .venv/bin/python benchmarks/simhw_bench.py            # in-process HwService only
    .venv/bin/python benchmarks/simhw_bench.py --zenoh    # also through a router + mstc simhw
    .venv/bin/python benchmarks/simhw_bench.py --plot docs/img/simhw_profile.png

Prints figures; asserts nothing (speed goals are recorded in docs/simhw.md).
"""

from __future__ import annotations

import argparse
import asyncio
import socket
import statistics
import subprocess
import sys
import time

import numpy as np

from bus.codec import encode
from bus.messages import HwCommand
from planner.types import OccupancyGrid
from simhw.clock import FastClock
from simhw.kinematics import Kinematics
from simhw.service import HwService
from simhw.types import Heading, Pose
from simhw.world import World

ACTIONS = ("forward", "turn_left", "forward", "turn_right", "sense")


def _cmd(robot: int, i: int) -> HwCommand:
    action = ACTIONS[i % len(ACTIONS)]
    sensors = ("front", "left", "right") if action == "sense" else ()
    return HwCommand(cmd_id=i, robot=robot, incarnation=0, action=action,  # type: ignore[arg-type]
                     sensors=sensors)  # type: ignore[arg-type]


async def in_process(k: int, per_robot: int) -> float:
    grid = OccupancyGrid(np.ones((64, 64), dtype=bool))
    world = World(grid, [Pose(2 * i, 0, Heading.E) for i in range(k)])
    svc = HwService(world, FastClock(), Kinematics(), "bench", lambda key, msg: None)

    async def drive(robot: int) -> None:
        for i in range(per_robot):
            await svc.command(robot, encode(_cmd(robot, i)))

    start = time.perf_counter()
    await asyncio.gather(*(drive(r) for r in range(k)))
    return k * per_robot / (time.perf_counter() - start)


async def over_zenoh(k: int, per_robot: int) -> tuple[float, float]:
    from bus import keys
    from bus.bridge import Bus
    from bus.config import ConnectionSettings
    from bus.messages import HwReply
    from bus.router import start_router_process, stop_process

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        endpoint = f"tcp/127.0.0.1:{sock.getsockname()[1]}"
    router = start_router_process(endpoint)
    starts = ";".join(f"{2 * i},0" for i in range(k))
    simhw = subprocess.Popen(
        [sys.executable, "-m", "deploy.cli", "simhw", "--world", "open-room", "--robots",
         starts, "--headings", ",".join("E" * k), "--time-scale", "0", "--connect",
         endpoint, "--mission", "bench"], stdout=subprocess.PIPE, text=True)
    try:
        assert simhw.stdout is not None
        simhw.stdout.readline()
        latencies: list[float] = []
        async with Bus.connect(ConnectionSettings(connect=(endpoint,), mission="bench")) as bus:
            async def drive(robot: int) -> None:
                for i in range(per_robot):
                    t0 = time.perf_counter()
                    await bus.query(keys.hw_cmd("bench", robot), _cmd(robot, i), HwReply)
                    latencies.append(time.perf_counter() - t0)

            start = time.perf_counter()
            await asyncio.gather(*(drive(r) for r in range(k)))
            rate = k * per_robot / (time.perf_counter() - start)
        return rate, statistics.median(latencies) * 1e3
    finally:
        simhw.terminate()
        simhw.wait(10)
        stop_process(router)


def speed_at(t: float, distance: float, v: float, a: float) -> float:
    """Speed at time t of the rest-to-rest profile that simhw.kinematics times."""
    top = min(v, (a * distance) ** 0.5)  # triangular profiles peak below v
    total = distance / top + top / a
    return max(0.0, min(top, a * t, a * (total - t)))


def plot(path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    k = Kinematics()
    fig, axes = plt.subplots(1, 2, figsize=(7, 2.4), dpi=80)
    for ax, (title, dist, v, a, dur, unit) in zip(axes, (
            (f"forward one sub-cell ({k.sub_cell_m} m)", k.sub_cell_m, k.speed,
             k.acceleration, k.forward_s(), "m/s"),
            ("turn 90 degrees", np.pi / 2, k.turn_rate, k.angular_acceleration, k.turn_s(),
             "rad/s")), strict=True):
        ts = np.linspace(0, dur, 200)
        ax.plot(ts, [speed_at(t, dist, v, a) for t in ts])
        ax.set_title(f"{title}: {dur:.2f} s", fontsize=9)
        ax.set_xlabel("s", fontsize=8)
        ax.set_ylabel(unit, fontsize=8)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(path)
    print(f"wrote {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--zenoh", action="store_true")
    parser.add_argument("-k", type=int, default=8)
    parser.add_argument("-n", type=int, default=200, help="commands per robot")
    parser.add_argument("--plot", metavar="PNG", help="also draw the velocity profiles")
    args = parser.parse_args()
    if args.plot:
        plot(args.plot)
    rate = asyncio.run(in_process(args.k, args.n))
    print(f"in-process HwService, k={args.k}: {rate:,.0f} commands/s")
    if args.zenoh:
        rate, p50 = asyncio.run(over_zenoh(args.k, args.n))
        print(f"over Zenoh via router, k={args.k}: {rate:,.0f} commands/s, "
              f"median round trip {p50:.2f} ms")


if __name__ == "__main__":
    main()
