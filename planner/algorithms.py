"""The one registry of coverage algorithms: name -> family, how it plans, its lockstep driver.

Every ``--algo`` choice list, dispatcher and help text reads this table, so adding an
algorithm is one module (its planner or state machine) plus one entry here. Entry points are
named as ``"module:function"`` and imported only when used: ``mstc plan --algo nb`` must not
pay for importing the balanced planner, and the table itself imports nothing heavy.

Families share drivers: every OFFLINE algorithm yields a :class:`planner.types.Plan` that the
offline agent walks and the offline lockstep replays; the ONLINE family is the ORMSTC state
machine (no plan, no map); the TREE family is connected coverage of a tree (NCOCTA/COCTA).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from planner.errors import UnknownAlgorithmError


class Family(StrEnum):
    OFFLINE = "offline"  # a plan from the a-priori map, walked by each robot (paper 003)
    ONLINE = "online"  # no map: the robots explore and build the tree as they go (paper 004)
    TREE = "tree"  # connected exploration of a tree by a team at its root (paper 001)


class Revisits(StrEnum):
    """What the algorithm promises about sub-cells covered more than once (fault-free)."""

    NONE = "none"  # every sub-cell entered once (nb; ORMSTC on coverage moves)
    BACKTRACK = "backtrack"  # at most twice, and only by the same robot walking back
    ANY = "any"  # no promise (planned walks that cross, tree traversals)


@dataclass(frozen=True)
class Algorithm:
    """One registered algorithm.

    ``machine`` names the robot's sans-I/O state machine, the one both the lockstep driver
    (``lockstep``) and the agent run; ``plan`` names ``f(area, tree, algo, seed) -> Plan`` for
    offline planners (None for the others); ``fleet`` says whether
    ``mstc up`` / ``mstc tree-fleet`` can run it as processes; ``one_robot_per_cell`` whether
    two robots may start in one coarse cell.
    """

    name: str
    family: Family
    summary: str
    machine: str
    lockstep: str
    plan: str | None = None
    fleet: bool = True
    revisits: Revisits = Revisits.ANY
    one_robot_per_cell: bool = False
    paper: str = ""

    def load_plan(self) -> Callable[..., Any]:
        if self.plan is None:
            raise UnknownAlgorithmError(f"{self.name} makes no offline plan")
        return _load(self.plan)

    def load_machine(self) -> Callable[..., Any]:
        return _load(self.machine)

    def load_lockstep(self) -> Callable[..., Any]:
        return _load(self.lockstep)


_OFFLINE = ("planner.offline.machine:OfflineRobot", "planner.offline.lockstep:simulate_failures")
_TREE = ("planner.treecover.step:decide", "planner.treecover.sim:run_coverage")

ALGORITHMS: dict[str, Algorithm] = {a.name: a for a in (
    Algorithm("nb", Family.OFFLINE, "non-backtracking MSTC", *_OFFLINE,
              plan="planner.offline.plan:plan_for", revisits=Revisits.NONE, paper="003"),
    Algorithm("bt", Family.OFFLINE, "backtracking MSTC", *_OFFLINE,
              plan="planner.offline.plan:plan_for", revisits=Revisits.BACKTRACK, paper="003"),
    Algorithm("opt", Family.OFFLINE, "optimal backtracking MSTC", *_OFFLINE,
              plan="planner.offline.plan:plan_for", revisits=Revisits.BACKTRACK, paper="003"),
    Algorithm("balanced", Family.OFFLINE, "balanced regions near the lower bound (ours)",
              "planner.balanced.machine:BalancedRobot",
              "planner.balanced.takeover:simulate_failures",
              plan="planner.balanced.plan:plan_for", fleet=False),
    Algorithm("ormstc", Family.ONLINE, "on-line robust MSTC (no map)",
              "planner.ormstc.machine:OrmstcMachine", "planner.ormstc.lockstep:simulate",
              revisits=Revisits.NONE, one_robot_per_cell=True, paper="004"),
    Algorithm("cocta", Family.TREE, "connected tree coverage, COCTA", *_TREE, paper="001"),
    Algorithm("ncocta", Family.TREE, "connected tree coverage, NCOCTA", *_TREE, paper="001"),
)}


def algorithm(name: str) -> Algorithm:
    """The registered algorithm ``name`` (UnknownAlgorithmError, a user mistake, otherwise)."""
    try:
        return ALGORITHMS[name]
    except KeyError:
        raise UnknownAlgorithmError(
            f"unknown algorithm {name!r}; choose one of {', '.join(ALGORITHMS)}") from None


def names(family: Family | None = None, *, fleet: bool | None = None,
          plans: bool | None = None) -> tuple[str, ...]:
    """Registered names in table order, filtered by family, by whether they run as a fleet
    and by whether they make an offline plan."""
    return tuple(a.name for a in ALGORITHMS.values()
                 if (family is None or a.family is family)
                 and (fleet is None or a.fleet == fleet)
                 and (plans is None or (a.plan is not None) == plans))


def choices_help(choices: tuple[str, ...]) -> str:
    """One line for ``--help``: ``nb non-backtracking MSTC; bt ...``."""
    return "; ".join(f"{name} {ALGORITHMS[name].summary}" for name in choices)


def _load(entry: str) -> Callable[..., Any]:
    module, _, function = entry.partition(":")
    loaded: Callable[..., Any] = getattr(importlib.import_module(module), function)
    return loaded
