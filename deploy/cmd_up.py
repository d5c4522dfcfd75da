"""``mstc up``: start a local fleet (router, simhw, K agents as separate processes), show its
progress, kill robots on schedule, print a summary, stop everything; exit 0 only if every
reachable free sub-cell was covered.

Exit codes: 0 complete; 1 incomplete (stalled, robots all lost, a process failed);
2 usage or start-up error (bad map, port in use); 129/130/143 interrupted by SIGHUP/SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import asyncio
import math
import os
import time
from pathlib import Path

from bus.argtypes import positive, positive_int, time_scale
from bus.config import DEFAULT_ENDPOINT, DEFAULT_LEASE_MS
from deploy.errors import FleetError, UsageError
from deploy.fleet import (
    check_port_free,
    default_run_dir,
    port_reachable,
    unique_mission,
)
from deploy.launch import launch
from deploy.settings import KillOrder, MissionSetup, parse_kill
from planner.trees import ALL_TREE_KINDS

ALGOS = ("nb", "bt", "opt", "ormstc")
# 40 simulated seconds per wall second: a forward step (1.93 s simulated) takes ~50 ms, so
# coverage visibly grows, and the office demo (6 robots, one killed: ~330 moves of ~2.5
# simulated seconds for the robot that takes over) ends in about 25 s of wall time.
DEFAULT_TIME_SCALE = 40.0
DEFAULT_STALL_S = 20.0
# Heartbeat timeout handed to the agents. A SIGKILL is seen through the closed link and a hung
# process through its lease (~0.75 s), whatever this is; 1 s heartbeats alone were missed by
# CPU-starved agents on a busy 2-core machine and healthy robots were fenced
# (docs/operations.md, "Detection against false suspicion").
DEFAULT_DEAD_AFTER_S = 3.0
# Beyond this many agents per CPU core, start-up and time-scale-0 missions starve processes
# for over a second: 30 agents on 2 cores lost every robot to lease expiry at a 1 s lease,
# none at 5 s. Crowded fleets get the long lease and heartbeat timeout.
CROWDED_AGENTS_PER_CORE = 6
CROWDED_LEASE_MS = 5000
CROWDED_DEAD_AFTER_S = 5.0
# A taker may walk this many already-covered sub-cells to reach a dead robot's section
# without covering anything new; the default stall timeout allows for it at any time scale.
STALL_MOVES = 100
MOVE_SIM_S = 2.5  # forward 1.93 s plus a share of turns (docs/simhw.md)
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-n", "--robots", type=positive_int, required=True, metavar="K",
                        help="number of robots (agent processes)")
    parser.add_argument("--world", default="office", metavar="FILE|NAME",
                        help="builtin world name or map file (default office)")
    parser.add_argument("--algo", choices=ALGOS, default="opt",
                        help="offline MSTC variant the agents run, or ormstc (on-line; "
                             "its agents read no map) (default opt)")
    parser.add_argument("--tree", choices=ALL_TREE_KINDS, default="dfs",
                        help="spanning tree kind (default dfs)")
    parser.add_argument("--cell-size", type=positive_int, default=None, metavar="PX",
                        help="map pixels per sub-cell side (default 1)")
    parser.add_argument("--starts", metavar="'r,c;r,c;...'",
                        help="robot start sub-cells (default: random, from --seed)")
    parser.add_argument("--seed", type=int, default=0,
                        help="seed of random starts and of the tree (default 0)")
    parser.add_argument("--time-scale", type=time_scale, default=DEFAULT_TIME_SCALE, metavar="X",
                        help="simulated seconds per wall second; 0 = as fast as possible "
                             "(default %(default)s)")
    parser.add_argument("--kill", action="append", default=[], metavar="ID@WHEN",
                        type=parse_kill,
                        help="SIGKILL agent ID at WHEN: seconds after the mission started "
                             "(2@3) or a coverage percent (2@progress=40); repeatable")
    parser.add_argument("--kill-hw", action="append", default=[], metavar="ID@WHEN",
                        type=lambda t: parse_kill(t, hw=True),
                        help="fail robot ID's body in simhw at WHEN (same syntax)")
    parser.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                        help="logs, PID files and fleet.json (default runs/<time>-<mission>)")
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--listen", default=DEFAULT_ENDPOINT, metavar="ENDPOINT",
                       help=f"endpoint of the router to start (default {DEFAULT_ENDPOINT})")
    where.add_argument("--connect", default=None, metavar="ENDPOINT",
                       help="use the router (zenohd or mstc router) at ENDPOINT instead of "
                            "starting one")
    parser.add_argument("--mission", default=None,
                        help="mission name (default: a unique fleet-<hex> per run)")
    parser.add_argument("--lease-ms", type=int, default=None,
                        help=f"Zenoh transport lease of every process (default "
                             f"{DEFAULT_LEASE_MS}, {CROWDED_LEASE_MS} with more than "
                             f"{CROWDED_AGENTS_PER_CORE} agents per CPU core)")
    parser.add_argument("--stall-timeout", type=positive, default=None, metavar="S",
                        help=f"fail if coverage does not grow for S wall seconds (default "
                             f"{DEFAULT_STALL_S:g} s plus the wall time of {STALL_MOVES} moves)")
    parser.add_argument("--start-timeout", type=positive, default=None, metavar="S",
                        help="fail if the agents are not all up after S wall seconds "
                             "(default 30 + 1 per robot)")
    parser.add_argument("--linger", type=positive, default=3.0, metavar="S",
                        help="after full coverage, wait up to S s for agents to report "
                             "completion (default %(default)s)")
    parser.add_argument("--dead-after", type=positive, default=None, metavar="S",
                        help=f"agents declare a robot dead after S s without its heartbeat "
                             f"(default {DEFAULT_DEAD_AFTER_S:g}, {CROWDED_DEAD_AFTER_S:g} with "
                             f"more than {CROWDED_AGENTS_PER_CORE} agents per CPU core)")
    parser.add_argument("--agent-arg", action="append", default=[], metavar="ARG",
                        help="extra argument for every agent, e.g. --agent-arg=--dead-after=2")
    parser.add_argument("--simhw-arg", action="append", default=[], metavar="ARG",
                        help="extra argument for simhw, e.g. --simhw-arg=--odometry-noise=0.05")
    parser.add_argument("--plain", action="store_true",
                        help="plain progress lines even on a terminal")
    parser.add_argument("--record", type=Path, default=None, metavar="FILE",
                        help="record every message of the mission to FILE (JSON Lines; "
                             "see mstc replay and mstc report)")


def check_kills(args: argparse.Namespace) -> list[KillOrder]:
    orders: list[KillOrder] = [*args.kill, *args.kill_hw]
    for order in orders:
        if order.robot >= args.robots:
            raise UsageError(f"--kill {order.robot}: robots are 0..{args.robots - 1}")
    return orders


def stall_timeout(args: argparse.Namespace) -> float:
    if args.stall_timeout is not None:
        return float(args.stall_timeout)
    if args.time_scale == 0 or math.isinf(args.time_scale):
        return DEFAULT_STALL_S
    return DEFAULT_STALL_S + STALL_MOVES * MOVE_SIM_S / args.time_scale


def liveness_defaults(args: argparse.Namespace, cores: int | None = None) -> None:
    """Fill in --lease-ms and --dead-after when not given, by agents per CPU core."""
    crowded = args.robots > CROWDED_AGENTS_PER_CORE * (cores or os.cpu_count() or 1)
    if args.lease_ms is None:
        args.lease_ms = CROWDED_LEASE_MS if crowded else DEFAULT_LEASE_MS
    if args.dead_after is None:
        args.dead_after = CROWDED_DEAD_AFTER_S if crowded else DEFAULT_DEAD_AFTER_S


def endpoint_of(args: argparse.Namespace) -> str:
    """The router endpoint the fleet uses; FleetError at once if it is unusable."""
    if args.connect is not None:
        if not port_reachable(args.connect):
            raise FleetError(f"no router answers at {args.connect} (start one with "
                             f"'mstc router --listen {args.connect}' or zenohd)")
        return str(args.connect)
    check_port_free(args.listen)
    return str(args.listen)


def run(args: argparse.Namespace) -> int:
    orders = check_kills(args)
    if args.record is not None and not args.record.parent.is_dir():
        raise UsageError(f"--record {args.record}: directory {args.record.parent} does not exist")
    args.stall_timeout = stall_timeout(args)
    liveness_defaults(args)
    setup = MissionSetup.from_args(args)  # loads the map and plans: user mistakes stop here
    endpoint = endpoint_of(args)
    mission = args.mission or unique_mission()
    run_dir = args.run_dir or default_run_dir(mission)
    started = time.monotonic()
    main = launch(setup, orders, endpoint, mission, Path(run_dir), args, started)
    if args.record is None:
        return asyncio.run(main)
    from bus.config import ConnectionSettings
    from deploy.monitor.app import recorded

    settings = ConnectionSettings(connect=(endpoint,), mission=mission, lease_ms=args.lease_ms)
    return asyncio.run(recorded(main, settings, args.record))
