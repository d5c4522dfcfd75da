"""``mstc tree-agent``: the older spelling of ``mstc agent --algo cocta|ncocta`` (same flags,
``--algo`` defaulting to cocta and ``--tree SPEC`` required); kept for launchers and scripts."""

from __future__ import annotations

import argparse
import sys

from agent.core.config import add_identity_arguments, add_life_arguments, config_from_args
from agent.core.errors import ConfigError
from agent.tree import options as tree_options
from bus.config import add_connection_arguments, settings_from_args
from planner.treecover.types import Algo


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_identity_arguments(parser)
    parser.add_argument("--tree", required=True, metavar="SPEC", help=tree_options.TREE_HELP)
    parser.add_argument("--algo", choices=[a.value for a in Algo], default="cocta")
    add_life_arguments(parser)
    add_connection_arguments(parser)
    tree_options.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    try:
        config = config_from_args(args)
        options = tree_options.from_args(args)
    except ConfigError as error:
        print(f"mstc tree-agent: error: {error}", file=sys.stderr)
        return 2
    from agent.tree.driver import drive

    return drive(config, options, settings_from_args(args))
