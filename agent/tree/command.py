"""``mstc tree-agent``: the older spelling of ``mstc agent --algo cocta|ncocta``, kept for
launchers and scripts (``mstc tree-fleet`` spawns it). Same options and exit codes; here
``--algo`` defaults to cocta and ``--tree SPEC`` is required."""

from __future__ import annotations

import argparse

from agent import main
from agent.core.config import add_identity_arguments, add_life_arguments
from agent.tree import options as tree_options
from bus.config import add_connection_arguments
from planner.algorithms import Family, choices_help


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_identity_arguments(parser)
    algos = main.agent_algorithms(Family.TREE)
    parser.add_argument("--tree", required=True, metavar="SPEC", help=tree_options.TREE_HELP)
    parser.add_argument("--algo", choices=algos, default="cocta",
                        help=f"{choices_help(algos)} (default %(default)s)")
    add_life_arguments(parser)
    add_connection_arguments(parser)
    tree_options.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    return main.run(args)
