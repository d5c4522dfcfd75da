"""ORMSTC on the wire: figures for docs/ormstc.md (not a test; nothing is asserted).

    .venv/bin/python benchmarks/bench_ormstc_fleet.py latency [--samples 2000]
    .venv/bin/python benchmarks/bench_ormstc_fleet.py fleet [--world example --robots 4 --runs 3]

latency: claim round trip between two processes through a local ``mstc router``: this
process publishes an OrmstcClaim as robot 0 (real codec and QoS), an echo process answers
each with a claim of robot 1, and the round trip is timed; half of it bounds the one-way
delay the claim window must exceed twice. fleet: full missions (router, ``mstc simhw
--time-scale X`` (default 0), k ``mstc agent --algo ormstc``) from seeded random starts (one
robot per cell), against ``planner.ormstc.lockstep.simulate`` on the same world and starts:
coverage time in moves (most moves of any robot) distributed / lockstep, ORMSTC messages and
bytes per robot per move (every message heard on ``ormstc/*``, bytes as encoded), the same for
the sonar rays told to peers (``sonar/*``), and wall time; each robot's look steps (LookStep:
steps aside and back, or into a cell given up from inside and back, made only to sense, which
the lockstep model does not make), the looks from beside and the cells given up from inside of
all robots (their "completed" events) and the ratio without look steps. Which robot takes a
contested cell depends on how long claims take against moves, so each run also prints the
lockstep's coverage time under other such timings (claims deciding after 3 or 6 steps rather
than 1, messages taking 1-3 steps rather than 1): the spread the same starts give the
algorithm itself.
"""

from __future__ import annotations

import argparse
import asyncio
import random
import re
import socket
import statistics
import subprocess
import sys
import time
from collections import Counter
from typing import Any

import numpy as np

from agent.ormstc.wire import WIRE_TYPES
from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.codec import encode
from bus.config import ConnectionSettings
from bus.messages import (
    LookStep,
    OrmstcClaim,
    OrmstcStart,
    OrmstcTreeEdge,
    OrmstcWire,
    RobotEvent,
    SonarRays,
    WorldState,
    world_visits,
)
from bus.router import start_router_process, stop_process
from planner.grid import coarsen
from planner.maps import resolve_world
from planner.ormstc.lockstep import SimConfig, simulate
from planner.ormstc.types import SenseMode
from planner.types import OccupancyGrid, SubCell

MISSION = "bench-ormstc"
_LOOKS_BESIDE = re.compile(r"\((\d+) looks from beside\)")
_GIVEN_UP = re.compile(r"(\d+) cells given up from inside")


def pick_free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def pct(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


# ---- claim round trip ------------------------------------------------------------------------

async def echo(endpoint: str) -> None:
    """Answer every claim of robot 0 with a claim of robot 1 (the second process)."""
    async with Bus.connect(ConnectionSettings(connect=(endpoint,), mission=MISSION)) as bus:
        def answer(_key: str, claim: OrmstcClaim) -> None:
            bus.publish(keys.ormstc_claim(MISSION, 1),
                        OrmstcClaim(1, 1, claim.seq, claim.cell, claim.covered))

        bus.subscribe(keys.ormstc_claim(MISSION, 0), OrmstcClaim, answer, BoundedFifo(65536))
        print("echo ready", flush=True)
        await asyncio.Event().wait()


async def latency(endpoint: str, samples: int) -> list[float]:
    sent: dict[int, float] = {}
    rtts: list[float] = []
    got = asyncio.Event()
    async with Bus.connect(ConnectionSettings(connect=(endpoint,), mission=MISSION)) as bus:
        def back(_key: str, claim: OrmstcClaim) -> None:
            if claim.seq in sent:
                rtts.append(time.perf_counter() - sent.pop(claim.seq))
                got.set()

        bus.subscribe(keys.ormstc_claim(MISSION, 1), OrmstcClaim, back, BoundedFifo(65536))
        await asyncio.sleep(0.5)
        for seq in range(1, samples + 1):
            got.clear()
            sent[seq] = time.perf_counter()
            bus.publish(keys.ormstc_claim(MISSION, 0), OrmstcClaim(0, 1, seq, (seq, 0), 3))
            try:
                async with asyncio.timeout(1.0):
                    await got.wait()
            except TimeoutError:
                print(f"claim {seq}: no echo within 1 s", flush=True)
            await asyncio.sleep(random.uniform(0.0, 0.004))  # like claims between moves
    return rtts


def run_latency(args: argparse.Namespace) -> None:
    endpoint = f"tcp/127.0.0.1:{pick_free_port()}"
    router = start_router_process(endpoint)
    responder = subprocess.Popen([sys.executable, __file__, "echo", endpoint],
                                 stdout=subprocess.PIPE, text=True)
    try:
        assert responder.stdout is not None
        responder.stdout.readline()
        rtts = [1000 * x for x in asyncio.run(latency(endpoint, args.samples))]
    finally:
        stop_process(responder)
        stop_process(router)
    print(f"claim round trip over {len(rtts)} of {args.samples}: median {pct(rtts, 50):.2f} ms, "
          f"p95 {pct(rtts, 95):.2f} ms, p99 {pct(rtts, 99):.2f} ms, max {max(rtts):.2f} ms")


# ---- fleet against lockstep ------------------------------------------------------------------

def cell_starts(grid: OccupancyGrid, k: int, seed: int) -> tuple[SubCell, ...]:
    """k random sub-cells in k distinct free cells."""
    rng = random.Random(seed)
    cells = [tuple(int(v) for v in rc) for rc in np.argwhere(coarsen(grid).free)]
    return tuple((2 * r + rng.randrange(2), 2 * c + rng.randrange(2))
                 for r, c in rng.sample(cells, k))


# lockstep timings besides the default (claims decided after 1 step, messages take 1), all
# safe windows (>= 2 x the largest delay - 1): what the same starts give when claims cost more
# against moves (SimConfig keywords)
LOCKSTEP_TIMINGS: tuple[dict[str, Any], ...] = (
    {"claim_wait": 3}, {"claim_wait": 6},
    {"delay": (1, 3), "claim_wait": 5, "seed": 1}, {"delay": (1, 3), "claim_wait": 5, "seed": 2})

Outcome = tuple[WorldState, Counter[int], Counter[int], float, int, dict[int, int],
                tuple[dict[int, int], dict[int, int]], tuple[Counter[int], Counter[int]]]


async def mission(endpoint: str, world: str, starts: tuple[SubCell, ...], name: str,
                  sonar: str, scale: float, extra: tuple[str, ...] = ()) -> Outcome:
    counts: Counter[int] = Counter()
    looks: dict[int, int] = {}  # each robot's steps made only to sense (highest LookStep seq)
    beside: dict[int, int] = {}  # each robot's looks from beside (its "completed" event)
    given_up: dict[int, int] = {}  # each robot's cells given up from inside (the same event)
    told: Counter[int] = Counter()  # SonarRays heard per robot (not on ormstc/*), and bytes
    told_bytes: Counter[int] = Counter()
    sizes: Counter[int] = Counter()
    owners: dict[tuple[int, int], set[int]] = {}
    settings = ConnectionSettings(connect=(endpoint,), mission=name)
    async with Bus.connect(settings) as bus:
        def heard(_key: str, wire: OrmstcWire) -> None:
            counts[wire.robot] += 1
            sizes[wire.robot] += len(encode(wire))
            if isinstance(wire, OrmstcTreeEdge):
                owners.setdefault(wire.child, set()).add(wire.robot)
            elif isinstance(wire, OrmstcStart):
                owners.setdefault((wire.sub[0] // 2, wire.sub[1] // 2), set()).add(wire.robot)

        def looked(_key: str, step: LookStep) -> None:
            looks[step.robot] = max(looks.get(step.robot, 0), step.seq)

        def rays(_key: str, msg: SonarRays) -> None:
            told[msg.robot] += 1
            told_bytes[msg.robot] += len(encode(msg))

        def event(_key: str, ev: RobotEvent) -> None:
            found = _LOOKS_BESIDE.search(ev.detail) if ev.kind == "completed" else None
            if found is not None:
                beside[ev.robot] = int(found.group(1))
            found = _GIVEN_UP.search(ev.detail) if ev.kind == "completed" else None
            if found is not None:
                given_up[ev.robot] = int(found.group(1))

        bus.subscribe(keys.all_ormstc(name), WIRE_TYPES, heard, BoundedFifo(1 << 20))
        bus.subscribe(keys.all_look_steps(name), LookStep, looked, BoundedFifo(1 << 16))
        bus.subscribe(keys.all_events(name), RobotEvent, event, BoundedFifo(1 << 12))
        bus.subscribe(keys.all_sonar_rays(name), SonarRays, rays, BoundedFifo(1 << 16))
        await asyncio.sleep(0.3)
        conn = ["--connect", endpoint, "--mission", name]
        robots = ";".join(f"{r},{c}" for r, c in starts)
        simhw = subprocess.Popen([sys.executable, "-m", "deploy.cli", "simhw", "--world", world,
                                  "--robots", robots, "--time-scale", str(scale), "--sonar-mode",
                                  sonar, *conn], stdout=subprocess.DEVNULL)
        single = ["--sense-mode", "single"] if sonar != "all" else []
        t0 = time.monotonic()
        agent = [sys.executable, "-m", "deploy.cli", "agent", "--algo", "ormstc", "--robots",
                 str(len(starts)), *conn, "--linger", "0.2", "--dead-after", "3", *single, *extra]
        agents = [subprocess.Popen([*agent, "--id", str(i)], stdout=subprocess.DEVNULL)
                  for i in range(len(starts))]
        codes = [await asyncio.to_thread(a.wait) for a in agents]
        wall = time.monotonic() - t0
        await asyncio.sleep(0.2)
        state = (await bus.query(keys.world(name), None, WorldState, timeout=5.0))[0].msg
        stop_process(simhw)  # type: ignore[arg-type]
        if any(codes):
            print(f"  agent exit codes {codes}", flush=True)
    shared = sum(len(robots) > 1 for robots in owners.values())  # nobody dies here
    return state, counts, sizes, wall, shared, looks, (beside, given_up), (told, told_bytes)


def run_fleet(args: argparse.Namespace) -> None:
    grid = resolve_world(args.world)
    endpoint = f"tcp/127.0.0.1:{pick_free_port()}"
    router = start_router_process(endpoint)
    ratios, walk_ratios, per_move, bytes_move = [], [], [], []
    try:
        for run in range(args.runs):
            starts = cell_starts(grid, args.robots, args.seed + run)
            mode = SenseMode.SINGLE if args.sonar != "all" else SenseMode.ALL
            lock = simulate(grid, starts, SimConfig(sense_mode=mode))
            timings = [simulate(grid, starts, SimConfig(sense_mode=mode, **t)).makespan
                       for t in LOCKSTEP_TIMINGS]
            state, counts, sizes, wall, shared, looks, (beside, given_up), (told, told_bytes) = \
                asyncio.run(mission(endpoint, args.world, starts, f"{MISSION}-{run}",
                                    args.sonar, args.time_scale,
                                    tuple(args.agent_args.split())))
            moves = [t.covered - 1 for t in state.robots]
            visits = world_visits(state)
            ratio = max(moves) / lock.makespan
            ratios.append(ratio)
            # the lockstep model senses a cell at once: its moves have no steps aside
            walks = [m - looks.get(r, 0) for r, m in enumerate(moves)]
            walk_ratios.append(max(walks) / lock.makespan)
            msgs = [counts[r] / max(m, 1) for r, m in enumerate(moves)]
            rays = [told[r] / max(m, 1) for r, m in enumerate(moves)]
            ray_bytes = [told_bytes[r] / max(m, 1) for r, m in enumerate(moves)]
            size = [sizes[r] / max(m, 1) for r, m in enumerate(moves)]
            per_move.extend(msgs)
            bytes_move.extend(size)
            twice = int((visits > 1).sum())
            print(f"run {run}: starts {starts}: moves {moves} (lockstep {list(lock.moves)}; "
                  f"other claim timings {min(timings)}-{max(timings)} against "
                  f"{lock.makespan}: ratio {max(walks) / max(timings):.3f}-"
                  f"{max(walks) / min(timings):.3f} without look steps), "
                  f"ratio {ratio:.3f}; look steps {[looks.get(r, 0) for r in range(len(moves))]}"
                  f" ({sum(beside.values())} looks from beside, "
                  f"{sum(given_up.values())} cells given up from inside)"
                  f", ratio without them {walk_ratios[-1]:.3f}; "
                  f"messages/move {statistics.mean(msgs):.2f}, "
                  f"bytes/move {statistics.mean(size):.1f}; sonar rays to peers: messages/move "
                  f"{statistics.mean(rays):.2f}, bytes/move {statistics.mean(ray_bytes):.1f}; "
                  f"sub-cells entered twice {twice}; "
                  f"cells owned by two robots {shared}; "
                  f"wall {wall:.1f} s", flush=True)
    finally:
        stop_process(router)
    print(f"{args.world}, {args.robots} robots, {args.runs} runs, sonar {args.sonar}, time "
          f"scale {args.time_scale:g}: moves "
          f"ratio mean {statistics.mean(ratios):.3f} (min {min(ratios):.3f}, max "
          f"{max(ratios):.3f}); without look steps mean {statistics.mean(walk_ratios):.3f} "
          f"(max {max(walk_ratios):.3f}); per robot per move: "
          f"{statistics.mean(per_move):.2f} messages, "
          f"{statistics.mean(bytes_move):.1f} bytes")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="what", required=True)
    lat = sub.add_parser("latency")
    lat.add_argument("--samples", type=int, default=2000)
    fleet = sub.add_parser("fleet")
    fleet.add_argument("--world", default="example")
    fleet.add_argument("--robots", type=int, default=4)
    fleet.add_argument("--runs", type=int, default=3)
    fleet.add_argument("--seed", type=int, default=0)
    fleet.add_argument("--sonar", choices=["all", "one-at-a-time"], default="all")
    fleet.add_argument("--time-scale", type=float, default=0.0)
    fleet.add_argument("--agent-args", default="", metavar="ARGS",
                       help="more options for every agent, e.g. '--claim-wait 0.1'")
    ech = sub.add_parser("echo")
    ech.add_argument("endpoint")
    args = parser.parse_args()
    if args.what == "latency":
        run_latency(args)
    elif args.what == "fleet":
        run_fleet(args)
    else:
        asyncio.run(echo(args.endpoint))


if __name__ == "__main__":
    main()
