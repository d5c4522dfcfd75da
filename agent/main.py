"""``mstc agent``: run one robot's offline MSTC agent process (see docs/agent.md).

Exit codes: 0 mission completed or left on SIGTERM/SIGINT; 1 hardware failure; 2 user
mistake (bad map, options, placement); 3 mission failed (missing robots, plan digest
mismatch, a peer's "failed" verdict); 4 fenced (this life was declared dead).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys

from agent.core.config import (
    DEFAULT_ANNOUNCE_PERIOD,
    DEFAULT_HW_TIMEOUT,
    DEFAULT_LINGER,
    DEFAULT_START_TIMEOUT,
    AgentConfig,
)
from bus.argtypes import index, non_negative, positive, positive_int
from bus.config import add_connection_arguments, settings_from_args
from planner.trees import ALL_TREE_KINDS

OFFLINE_ALGOS = ("nb", "bt", "opt")
# The on-line ORMSTC agent (agent/ormstc_*.py, another module's work) shares this command.
ONLINE_ALGO = "ormstc"
ALGOS = (*OFFLINE_ALGOS, ONLINE_ALGO)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--id", type=index, required=True, metavar="I",
                        help="this robot's id, 0..K-1 (its body in simhw)")
    parser.add_argument("--algo", choices=ALGOS, required=True,
                        help="offline MSTC: nb non-backtracking, bt backtracking, opt optimal "
                             "backtracking; ormstc: on-line robust MSTC (no map)")
    parser.add_argument("--world", metavar="FILE|NAME",
                        help="map file or builtin world name: the a-priori map of the offline "
                             "algorithms (required for nb, bt, opt)")
    parser.add_argument("--cell-size", type=positive_int, default=None, metavar="PX",
                        help="map pixels per sub-cell side (default 1)")
    parser.add_argument("--tree", choices=ALL_TREE_KINDS, default="dfs",
                        help="spanning tree kind (default dfs)")
    parser.add_argument("--seed", type=int, default=0, help="tree seed (default 0)")
    parser.add_argument("--robots", type=positive_int, required=True, metavar="K",
                        help="number of robots in the fleet")
    parser.add_argument("--start-timeout", type=positive, default=DEFAULT_START_TIMEOUT,
                        metavar="SECONDS",
                        help="how long to wait for simhw, every start and every plan digest "
                             "(default %(default)s)")
    parser.add_argument("--incarnation", type=positive_int, default=1, metavar="N",
                        help="this life's number; a restart must use a higher one (default 1)")
    parser.add_argument("--heartbeat-period", type=positive, default=0.2, metavar="SECONDS",
                        help="seconds between heartbeats (default %(default)s)")
    parser.add_argument("--dead-after", type=positive, default=3.0, metavar="SECONDS",
                        help="a robot silent this long is declared dead (default %(default)s)")
    parser.add_argument("--announce-period", type=positive, default=DEFAULT_ANNOUNCE_PERIOD,
                        metavar="SECONDS",
                        help="re-announce state and re-query peers this often "
                             "(default %(default)s)")
    parser.add_argument("--hw-timeout", type=positive, default=DEFAULT_HW_TIMEOUT,
                        metavar="SECONDS",
                        help="longest wait for one motion of the body, lost replies and "
                             "re-tries included (default %(default)s)")
    parser.add_argument("--linger", type=non_negative, default=DEFAULT_LINGER,
                        metavar="SECONDS",
                        help="stay after completion so peers can still query (default "
                             "%(default)s)")
    add_connection_arguments(parser)
    if importlib.util.find_spec("agent.ormstc.options") is not None:
        from agent.ormstc.options import add_ormstc_arguments

        add_ormstc_arguments(parser)


def config_from_args(args: argparse.Namespace) -> AgentConfig:
    return AgentConfig(
        robot=args.id, k=args.robots, algo=args.algo, world=args.world,
        cell_size=args.cell_size, tree=args.tree, seed=args.seed,
        incarnation=args.incarnation, start_timeout=args.start_timeout,
        heartbeat_period=args.heartbeat_period, dead_after=args.dead_after,
        announce_period=args.announce_period, hw_timeout=args.hw_timeout,
        linger=args.linger)


def run(args: argparse.Namespace) -> int:
    if args.algo == ONLINE_ALGO:
        from agent.ormstc.driver import run_ormstc

        return run_ormstc(args)
    if args.world is None:
        print(f"mstc agent: error: --algo {args.algo} needs --world (the a-priori map)",
              file=sys.stderr)
        return 2
    config = config_from_args(args)
    if config.robot >= config.k:
        print(f"mstc agent: error: --id {config.robot} is not below --robots {config.k}",
              file=sys.stderr)
        return 2
    settings = settings_from_args(args)
    # Imported here so that option mistakes are reported without loading Zenoh.
    from agent.core.lifecycle import run_agent
    from agent.offline.driver import Agent

    return run_agent(Agent(config), settings)
