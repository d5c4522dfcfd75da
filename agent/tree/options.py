"""Options of the tree coverage agents (``mstc agent --algo cocta|ncocta``, alias ``mstc
tree-agent``): the tree to cover and the patience of the step barrier (no Zenoh here)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from agent.core.errors import ConfigError
from bus.argtypes import positive
from planner.algorithms import Family, names

DEFAULT_STEP_TIMEOUT = 10.0
DEFAULT_SETTLE = 1.0  # the longest a dead robot's last report may still be on its way
TREE_HELP = "perfect:N=3,H=4 | general:... | office | FILE.tree (a-priori map)"


@dataclass(frozen=True)
class TreeOptions:
    tree: str  # the tree's spec (planner.treecover.trees.tree_from_spec)
    step_timeout: float = DEFAULT_STEP_TIMEOUT
    settle: float = DEFAULT_SETTLE


def add_arguments(parser: argparse.ArgumentParser) -> None:
    algos = "|".join(names(Family.TREE, fleet=True))
    group = parser.add_argument_group(f"tree coverage (--algo {algos})")
    group.add_argument("--step-timeout", type=positive, default=DEFAULT_STEP_TIMEOUT,
                       metavar="SECONDS",
                       help="longest wait for every report of one step (default %(default)s)")
    group.add_argument("--settle", type=positive, default=DEFAULT_SETTLE, metavar="SECONDS",
                       help="how long a dead robot's last report may still be on its way "
                            "(default %(default)s)")


def from_args(args: argparse.Namespace) -> TreeOptions:
    """ConfigError when the tree to cover is missing."""
    if args.tree is None:
        raise ConfigError(f"--algo {args.algo} needs --tree SPEC, the tree to cover: "
                          f"{TREE_HELP}")
    return TreeOptions(tree=args.tree, step_timeout=args.step_timeout, settle=args.settle)
