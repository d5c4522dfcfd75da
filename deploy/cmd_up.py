"""``mstc up``: start a local fleet (router, simhw, K agents as separate processes), show its
progress, kill robots on schedule, print a summary, stop everything; exit 0 only if every
reachable free sub-cell was covered.

Exit codes: 0 complete; 1 incomplete (stalled, robots all lost, a process failed);
2 usage or start-up error (bad map, port in use); 129/130/143 interrupted by SIGHUP/SIGINT/SIGTERM.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

from bus import argtypes
from bus.argtypes import positive, positive_int, time_scale
from bus.config import DEFAULT_ENDPOINT, DEFAULT_LEASE_MS, ConnectionSettings
from deploy import security
from deploy.errors import FleetError, UsageError
from deploy.fleet import (
    ROUTER_WAIT_S,
    check_port_free,
    default_run_dir,
    router_answers_within,
    unique_mission,
)
from deploy.fleet_timing import (
    CROWDED_AGENTS_PER_CORE,
    CROWDED_DEAD_AFTER_S,
    CROWDED_LEASE_MS,
    DEFAULT_DEAD_AFTER_S,
    FLAT_OUT_AGENTS_PER_CORE,
    fleet_timing,
)
from deploy.launch import launch
from deploy.settings import (
    DEFAULT_STALL_S,
    DEFAULT_TIME_SCALE,
    REPLAN_S_PER_AGENT,
    STALL_MOVES,
    MissionSetup,
    UpSettings,
    check_kills,
    parse_kill,
    stall_timeout,
    with_allowances,
)
from deploy.supervisor import run_recorded
from planner.algorithms import Family, algorithm, choices_help, names
from planner.offline.rebalance import DEFAULT_RECOVERY, RECOVERIES
from planner.trees import ALL_TREE_KINDS

# what runs as a fleet on a grid: every offline and on-line algorithm that declares a fleet
ALGOS = names(Family.OFFLINE, fleet=True) + names(Family.ONLINE, fleet=True)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("-n", "--robots", type=positive_int, required=True, metavar="K",
                        help="number of robots (agent processes)")
    parser.add_argument("--world", "--map", dest="world", default="office", metavar="FILE|NAME",
                        help="builtin world name or map file (default office; --map: the "
                             "same option, as mstc plan spelled it)")
    parser.add_argument("--algo", choices=ALGOS, default="opt",
                        help=f"{choices_help(ALGOS)} (default opt)")
    parser.add_argument("--tree", choices=ALL_TREE_KINDS, default="dfs",
                        help="spanning tree kind (default dfs)")
    parser.add_argument("--recovery", choices=RECOVERIES, default=None,
                        help="offline algorithms, after a death: rebalance (the survivors "
                             "re-split the remaining work; crossing walks wait or step "
                             "aside) or takeover (the papers': the robot behind walks the "
                             f"dead one's rest after its own) (default {DEFAULT_RECOVERY})")
    parser.add_argument("--cell-size", type=positive_int, default=None, metavar="PX",
                        help="map pixels per sub-cell side (default 1)")
    parser.add_argument("--starts", metavar="'r,c;r,c;...'",
                        help="robot start sub-cells (default: random, from --seed)")
    parser.add_argument("--seed", type=argtypes.seed, default=0,
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
                             f"{DEFAULT_LEASE_MS}; with more than {CROWDED_AGENTS_PER_CORE} "
                             f"agents per CPU core, or {FLAT_OUT_AGENTS_PER_CORE} at time "
                             f"scale 0, at least {CROWDED_LEASE_MS}, growing with the fleet: "
                             f"docs/operations.md, 'Fleet scale')")
    parser.add_argument("--stall-timeout", type=positive, default=None, metavar="S",
                        help=f"fail if coverage does not grow for S wall seconds (default "
                             f"{DEFAULT_STALL_S:g} s plus the wall time of {STALL_MOVES} moves, "
                             f"and for the re-plan after a death {REPLAN_S_PER_AGENT:g} s per "
                             "agent per core in a crowded fleet, and by the map's size)")
    parser.add_argument("--start-timeout", type=positive, default=None, metavar="S",
                        help="fail if the agents are not all up after S wall seconds "
                             "(default 30 + 1 per robot; crowded fleets: their paced "
                             "start-up's)")
    parser.add_argument("--linger", type=positive, default=3.0, metavar="S",
                        help="after full coverage, wait up to S s for agents to report "
                             "completion (default %(default)s)")
    parser.add_argument("--dead-after", type=positive, default=None, metavar="S",
                        help=f"agents declare a robot dead after S s without its heartbeat "
                             f"(default {DEFAULT_DEAD_AFTER_S:g}; with more than "
                             f"{CROWDED_AGENTS_PER_CORE} agents per CPU core, or "
                             f"{FLAT_OUT_AGENTS_PER_CORE} at time scale 0, at least "
                             f"{CROWDED_DEAD_AFTER_S:g}, growing with the fleet)")
    parser.add_argument("--agent-arg", action="append", default=[], metavar="ARG",
                        help="extra argument for every agent, e.g. --agent-arg=--dead-after=2")
    parser.add_argument("--simhw-arg", action="append", default=[], metavar="ARG",
                        help="extra argument for simhw, e.g. --simhw-arg=--odometry-noise=0.05")
    parser.add_argument("--plain", action="store_true",
                        help="plain progress lines even on a terminal")
    parser.add_argument("--record", type=Path, default=None, metavar="FILE",
                        help="record every message of the mission to FILE (JSON Lines; "
                             "see mstc replay and mstc report)")
    parser.add_argument("--record-mcap", type=Path, default=None, metavar="OUT",
                        help="record the mission as MCAP for Foxglove (docs/robotics.md; "
                             "needs the robotics extra)")
    security.add_arguments(parser)


def up_settings(args: argparse.Namespace, cores: int | None = None) -> UpSettings:
    """The typed settings of the command line, defaults resolved (the one place that reads
    the namespace)."""
    kills = check_kills((*args.kill, *args.kill_hw), args.robots)
    if args.record is not None and not args.record.parent.is_dir():
        raise UsageError(f"--record {args.record}: directory {args.record.parent} does not exist")
    if args.record_mcap is not None:
        if not args.record_mcap.absolute().parent.is_dir():
            raise UsageError(f"--record-mcap {args.record_mcap}: directory "
                             f"{args.record_mcap.absolute().parent} does not exist")
        from deploy.robotics import require_extra

        require_extra()
    timing = fleet_timing(args.robots, cores, lease_ms=args.lease_ms,
                          dead_after=args.dead_after, start_timeout=args.start_timeout,
                          flat_out=args.time_scale == 0)
    mission = args.mission or unique_mission()
    if args.recovery is not None and algorithm(args.algo).family is not Family.OFFLINE:
        raise UsageError(f"--recovery {args.recovery} needs an offline algorithm, not "
                         f"{args.algo}")
    return UpSettings(
        robots=args.robots, world=args.world, cell_size=args.cell_size, starts=args.starts,
        algo=args.algo, tree=args.tree, recovery=args.recovery or DEFAULT_RECOVERY,
        seed=args.seed,
        time_scale=args.time_scale, kills=kills, mission=mission,
        run_dir=Path(args.run_dir or default_run_dir(mission)),
        listen=args.listen, connect=args.connect, lease_ms=timing.lease_ms,
        dead_after=timing.dead_after,
        stall_timeout=stall_timeout(args.time_scale, args.stall_timeout, args.robots),
        start_timeout=timing.start_timeout, linger=args.linger,
        timing_args=tuple(timing.agent_args()), booting=timing.booting,
        agent_nice=timing.agent_nice,
        agent_args=tuple(args.agent_arg), simhw_args=tuple(args.simhw_arg), plain=args.plain,
        record=args.record, record_mcap=args.record_mcap)


def endpoint_of(settings: UpSettings) -> str:
    """The router endpoint the fleet uses; FleetError at once if it is unusable."""
    if settings.connect is not None:
        endpoint = settings.connect

        def say_waiting() -> None:
            print(f"mstc up: no router answers at {endpoint} yet; waiting up to "
                  f"{ROUTER_WAIT_S:g} s", file=sys.stderr, flush=True)

        if not router_answers_within(endpoint, ROUTER_WAIT_S, say_waiting):
            raise FleetError(f"no router answers at {endpoint} after {ROUTER_WAIT_S:g} s "
                             f"(start one with 'mstc router --listen {endpoint}')")
        return settings.connect
    check_port_free(settings.listen)
    return settings.listen


def run(args: argparse.Namespace) -> int:
    settings = up_settings(args)
    # loads the map and plans: user mistakes stop here
    setup = MissionSetup.plan(settings, say=lambda text: print(text, flush=True))
    settings = with_allowances(settings, args.stall_timeout, setup)
    endpoint = endpoint_of(settings)
    started = time.monotonic()
    secured = security.prepare(args, settings.run_dir, settings.mission, settings.robots,
                               settings.own_router)
    settings = dataclasses.replace(settings, credentials=secured.credentials)
    connection = secured.observer(ConnectionSettings(
        connect=(endpoint,), mission=settings.mission, lease_ms=settings.lease_ms))
    return run_recorded(launch(setup, settings, endpoint, started), connection,
                        settings.record, "up", settings.record_mcap)
