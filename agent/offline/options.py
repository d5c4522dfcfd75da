"""Options of the offline agents (``mstc agent --algo nb|bt|opt``): the a-priori map and the
spanning tree every robot plans on (no Zenoh here)."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from agent.core.errors import ConfigError
from agent.offline.apart import SHARE_MIN, SHARE_SUB_CELLS
from agent.offline.planshare import SHARE_FROM as PLAN_SHARE_FROM
from agent.offline.replan import SHARE_FROM
from bus.argtypes import positive_int
from planner.algorithms import Family, names
from planner.offline.rebalance import DEFAULT_RECOVERY, RECOVERIES, Recovery
from planner.trees import ALL_TREE_KINDS

DEFAULT_TREE = "dfs"


@dataclass(frozen=True)
class OfflineOptions:
    """The inputs of the plan besides the starts (and the seed, AgentConfig's)."""

    world: str
    cell_size: int | None = None
    tree: str = DEFAULT_TREE
    recovery: Recovery = DEFAULT_RECOVERY
    replan_share_from: int = SHARE_FROM
    plan_share_from: int = PLAN_SHARE_FROM


def add_arguments(parser: argparse.ArgumentParser) -> None:
    algos = "|".join(names(Family.OFFLINE, fleet=True))
    group = parser.add_argument_group(f"offline MSTC (--algo {algos})")
    group.add_argument("--world", metavar="FILE|NAME",
                       help="map file or builtin world name: the a-priori map of the offline "
                            "algorithms (required for them)")
    group.add_argument("--cell-size", type=positive_int, default=None, metavar="PX",
                       help="map pixels per sub-cell side (default 1)")
    group.add_argument("--recovery", choices=RECOVERIES, default=DEFAULT_RECOVERY,
                       help="after a death: rebalance (the survivors stop, exchange where "
                            "they are and re-split the remaining work; walks that cross wait "
                            "or step aside) or the papers' takeover (the robot behind walks "
                            "the dead one's rest after its own) "
                            f"(default {DEFAULT_RECOVERY})")
    group.add_argument("--replan-share-from", type=positive_int, default=SHARE_FROM,
                       metavar="N",
                       help="with --recovery rebalance, from N survivors on only the lowest "
                            "computes a re-plan and shares it; the others check it against "
                            "their own reports and walk it (computing it themselves if it "
                            "does not come). On a large map a survivor counts once per "
                            f"{SHARE_SUB_CELLS} sub-cells, from {SHARE_MIN} survivors "
                            f"(default {SHARE_FROM})")
    group.add_argument("--plan-share-from", type=positive_int, default=PLAN_SHARE_FROM,
                       metavar="N",
                       help="from N participants on only the lowest computes the first plan "
                            "and shares it; the others check it and fly it (computing it "
                            f"themselves if it does not come) (default {PLAN_SHARE_FROM})")


def from_args(args: argparse.Namespace) -> OfflineOptions:
    """ConfigError when the map is missing or ``--tree`` names no spanning tree kind."""
    if args.world is None:
        raise ConfigError(f"--algo {args.algo} needs --world (the a-priori map)")
    tree = DEFAULT_TREE if args.tree is None else args.tree
    if tree not in ALL_TREE_KINDS:
        raise ConfigError(f"argument --tree: invalid choice for --algo {args.algo}: {tree!r} "
                          f"(choose from {', '.join(ALL_TREE_KINDS)})")
    return OfflineOptions(world=args.world, cell_size=args.cell_size, tree=tree,
                          recovery=args.recovery, replan_share_from=args.replan_share_from,
                          plan_share_from=args.plan_share_from)
