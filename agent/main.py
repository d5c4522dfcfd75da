"""``mstc agent``: run one robot's agent process, of any family (see docs/agent.md).

``--algo`` names a registered algorithm (planner.algorithms) that runs as a fleet; its family
picks the options read and the driver run: offline (nb, bt, opt: a plan from ``--world``),
online (ormstc: no map) or tree (cocta, ncocta: the tree ``--tree SPEC``). ``mstc
tree-agent`` (agent.tree.command) is the older spelling of the tree family's command.

Exit codes: 0 mission completed or left on SIGTERM/SIGINT; 1 hardware failure; 2 user
mistake (bad map, options, placement); 3 mission failed (missing robots, plan digest
mismatch, a peer's "failed" verdict, a tree step never completed); 4 fenced (this life was
declared dead).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import Protocol

from agent.core.config import (
    add_body_arguments,
    add_identity_arguments,
    add_life_arguments,
    config_from_args,
)
from agent.core.errors import ConfigError
from agent.offline import options as offline_options
from agent.ormstc import options as ormstc_options
from agent.tree import options as tree_options
from bus.config import add_connection_arguments, settings_from_args
from planner.algorithms import Family, algorithm, choices_help, names
from planner.trees import ALL_TREE_KINDS


class FamilyOptions(Protocol):
    """A family's options module (agent/<family>/options.py: no Zenoh)."""

    def add_arguments(self, parser: argparse.ArgumentParser) -> None: ...

    def from_args(self, args: argparse.Namespace) -> object: ...


OPTIONS: dict[Family, FamilyOptions] = {
    Family.OFFLINE: offline_options, Family.ONLINE: ormstc_options, Family.TREE: tree_options}
# Each module's drive(config, options, settings) -> exit code runs one robot of the family;
# imported only once the options are good, so mistakes are reported without loading Zenoh.
DRIVERS: dict[Family, str] = {
    Family.OFFLINE: "agent.offline.driver", Family.ONLINE: "agent.ormstc.driver",
    Family.TREE: "agent.tree.driver"}


def agent_algorithms(family: Family | None = None) -> tuple[str, ...]:
    """The algorithms ``mstc agent`` runs: those that run as a fleet, of a family with a
    driver here (of ``family`` only, if given), in registry order."""
    return tuple(name for name in names(family, fleet=True)
                 if algorithm(name).family in DRIVERS)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_identity_arguments(parser)
    algos = agent_algorithms()
    parser.add_argument("--algo", choices=algos, required=True, help=choices_help(algos))
    parser.add_argument("--tree", default=None, metavar="KIND|SPEC",
                        help=f"offline: the spanning tree kind, one of "
                             f"{', '.join(ALL_TREE_KINDS)} (default dfs); tree coverage "
                             f"(required): the tree to cover, {tree_options.TREE_HELP}")
    add_life_arguments(parser)
    add_connection_arguments(parser)
    add_body_arguments(parser)
    for family in dict.fromkeys(algorithm(name).family for name in algos):
        OPTIONS[family].add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Run the robot of ``args`` (``mstc agent`` or ``mstc tree-agent``); its exit code."""
    family = algorithm(args.algo).family
    try:
        config = config_from_args(args)
        options = OPTIONS[family].from_args(args)
    except ConfigError as error:
        print(f"mstc {getattr(args, 'command', None) or 'agent'}: error: {error}",
              file=sys.stderr)
        return 2
    driver = importlib.import_module(DRIVERS[family])
    # Every robot logs in as itself: the router lets it write on its own keys only.
    settings = settings_from_args(args, default_role=f"robot_{config.robot}")
    return int(driver.drive(config, options, settings))
