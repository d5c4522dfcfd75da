"""What ``mstc up`` is asked to run, as typed values: the planned mission and its kill
schedule. Built once from the command line by deploy.cmd_up and read by the launcher."""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass

from deploy.errors import UsageError
from deploy.summary import reachable_sub_cells
from planner.grid import cell_of, coarsen, validate_starts, work_area
from planner.maps import resolve_world
from planner.pipeline import make_plan
from planner.placement import parse_starts, random_starts
from planner.trees import build_tree
from planner.types import BoolArray, OccupancyGrid, SubCell

_KILL_RE = re.compile(
    r"^(?P<robot>\d+)@(?:(?:progress=)?(?P<pct>\d+(?:\.\d+)?)%|progress=(?P<pct2>\d+(?:\.\d+)?)"
    r"|(?P<sec>\d+(?:\.\d+)?)s?)$")


@dataclass(frozen=True)
class KillOrder:
    """Kill ``robot`` at ``seconds`` after the mission started, or at ``percent`` coverage.
    ``hw`` fails its body in simhw instead of killing its process."""

    robot: int
    seconds: float | None = None
    percent: float | None = None
    hw: bool = False

    def describe(self) -> str:
        when = f"{self.seconds:g} s" if self.seconds is not None else f"{self.percent:g} %"
        what = "fail body of" if self.hw else "SIGKILL agent"
        return f"{what} {self.robot} at {when}"


def parse_kill(text: str, hw: bool = False) -> KillOrder:
    """``ID@SECONDS``, ``ID@Ns``, ``ID@progress=P`` or ``ID@P%`` (coverage percent)."""
    match = _KILL_RE.match(text.strip())
    if match is None:
        raise argparse.ArgumentTypeError(
            f"expected ID@SECONDS or ID@progress=PERCENT (e.g. 2@3 or 2@progress=40), "
            f"got {text!r}")
    pct = match["pct"] or match["pct2"]
    if pct is not None:
        if not 0 <= float(pct) <= 100:
            raise argparse.ArgumentTypeError(f"coverage percent must be 0..100 in {text!r}")
        return KillOrder(int(match["robot"]), percent=float(pct), hw=hw)
    return KillOrder(int(match["robot"]), seconds=float(match["sec"]), hw=hw)


@dataclass(frozen=True)
class MissionSetup:
    """The mission as the launcher plans it before starting anything."""

    world: str
    cell_size: int | None
    grid: OccupancyGrid
    starts: tuple[SubCell, ...]
    algo: str
    tree: str
    seed: int
    time_scale: float
    reachable: BoolArray
    planned_makespan: int

    @property
    def k(self) -> int:
        return len(self.starts)

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> MissionSetup:
        """Load the map, place the robots and plan (PlannerError for user mistakes)."""
        grid = resolve_world(args.world, args.cell_size)
        if args.starts:
            starts = parse_starts(args.starts)
            if len(starts) != args.robots:
                raise UsageError(f"--starts gives {len(starts)} robots, -n says {args.robots}")
        else:
            starts = random_starts(grid, args.robots, args.seed)
        validate_starts(grid, coarsen(grid), starts)
        if args.algo == "ormstc":
            # ORMSTC plans nothing (its agents get no map); the lockstep simulator's coverage
            # time on the same world and starts stands in for the planned makespan, and it
            # rejects two robots in one cell before any process starts.
            from simhw.lockstep import simulate

            planned = simulate(grid, starts).makespan
        else:
            # The agents plan the same way (agent/plan.py); here it gives the planned
            # makespan and rejects unplannable missions before any process starts.
            area = work_area(grid, starts)
            tree = build_tree(area.cells, args.tree, seed=args.seed,
                              starts=[cell_of(s) for s in starts])
            planned = make_plan(area, tree, args.algo).makespan
        return cls(world=args.world, cell_size=args.cell_size, grid=grid, starts=starts,
                   algo=args.algo, tree=args.tree, seed=args.seed, time_scale=args.time_scale,
                   reachable=reachable_sub_cells(grid, starts),
                   planned_makespan=planned)
