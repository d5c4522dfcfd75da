"""``mstc agent``: run one robot's agent process (see docs/agent.md).

Exit codes: 0 mission completed or left on SIGTERM/SIGINT; 1 hardware failure; 2 user
mistake (bad map, options, placement); 3 mission failed (missing robots, plan digest
mismatch, a peer's "failed" verdict); 4 fenced (this life was declared dead).
"""

from __future__ import annotations

import argparse
import sys

from agent.core.config import add_identity_arguments, add_life_arguments, config_from_args
from agent.core.errors import ConfigError
from agent.offline import options as offline_options
from agent.ormstc import options as ormstc_options
from bus.config import add_connection_arguments, settings_from_args
from planner.trees import ALL_TREE_KINDS

OFFLINE_ALGOS = ("nb", "bt", "opt")
ONLINE_ALGO = "ormstc"
ALGOS = (*OFFLINE_ALGOS, ONLINE_ALGO)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_identity_arguments(parser)
    parser.add_argument("--algo", choices=ALGOS, required=True,
                        help="offline MSTC: nb non-backtracking, bt backtracking, opt optimal "
                             "backtracking; ormstc: on-line robust MSTC (no map)")
    parser.add_argument("--tree", choices=ALL_TREE_KINDS, default=None,
                        help="spanning tree kind (default dfs)")
    add_life_arguments(parser)
    add_connection_arguments(parser)
    offline_options.add_arguments(parser)
    ormstc_options.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    command = getattr(args, "command", "agent")
    try:
        config = config_from_args(args)
        if args.algo == ONLINE_ALGO:
            ormstc = ormstc_options.from_args(args)
        else:
            offline = offline_options.from_args(args)
    except ConfigError as error:
        print(f"mstc {command}: error: {error}", file=sys.stderr)
        return 2
    settings = settings_from_args(args)
    # Imported here so that option mistakes are reported without loading Zenoh.
    if args.algo == ONLINE_ALGO:
        from agent.ormstc.driver import drive as drive_ormstc

        return drive_ormstc(config, ormstc, settings)
    from agent.offline.driver import drive

    return drive(config, offline, settings)
