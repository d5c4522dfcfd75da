"""What ``mstc up`` is asked to run, as typed values: the settings, the kill schedule and
the planned mission. Built once from the command line by deploy.cmd_up and read by the
launcher; nothing downstream sees the argparse namespace."""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from agent.offline.apart import shared_by_one
from agent.offline.planshare import SHARE_FROM as PLAN_SHARE_FROM
from agent.offline.replan import SHARE_FROM as REPLAN_SHARE_FROM
from bus.config import DEFAULT_LEASE_MS
from deploy.errors import UsageError
from deploy.fleet_timing import DEFAULT_DEAD_AFTER_S, core_count, crowded
from deploy.monitor.coverage import reachable_sub_cells
from planner.algorithms import Family, algorithm
from planner.geometry import cell_of
from planner.grid import coarsen, validate_starts, work_area
from planner.maps import resolve_world
from planner.offline.rebalance import DEFAULT_RECOVERY
from planner.placement import parse_starts, random_starts
from planner.trees import build_tree
from planner.types import BoolArray, OccupancyGrid, Plan, SubCell

# 40 simulated seconds per wall second: a forward step (1.93 s simulated) takes ~50 ms, so
# coverage visibly grows, and the office demo (6 robots, one killed: ~330 moves of ~2.5
# simulated seconds for the robot that takes over) ends in about 25 s of wall time.
DEFAULT_TIME_SCALE = 40.0
DEFAULT_STALL_S = 20.0
# A taker may walk this many already-covered sub-cells to reach a dead robot's section
# without covering anything new; the default stall timeout allows for it at any time scale.
STALL_MOVES = 100
MOVE_SIM_S = 2.5  # forward 1.93 s plus a share of turns (docs/simhw.md)
# After a death every survivor of a crowded fleet computes the same re-plan at once, and the
# fleet covers nothing meanwhile: 40 agents on 2 cores took 53 s from the death known to the
# first re-plan, 60 of them 114 s, 100 of them 147-180 s to the last, and 179-211 s since
# the re-plan is refined (docs/operations.md), so a crowded fleet's stall timeout allows
# this much per agent per core beyond the default (60 robots: 200 s, 100 robots: 320 s;
# about half as much again as those runs needed, for a loaded host). Since a crowd computes
# the re-plan once and its own traffic was cut (docs/operations.md, "The crowd's own
# traffic"), 60 and 100 robots re-plan 7-15 s after a death on an idle host; the allowance
# stays for hosts shared with other work, where the agents, niced, yield.
REPLAN_S_PER_AGENT = 6.0
# The re-plan's CPU also grows with the map, and unless one computes it for all
# (agent.offline.apart.shared_by_one) each survivor computes it: 12 robots on city
# 120 x 120 (40 392 sub-cells) at time scale 40, one killed at 30 %, stalled out after the
# default 26 s (2026-12-06), when each of the 11 survivors still computed it. One re-plan
# there costs a survivor 7.2 s of CPU alone (0.18 ms per sub-cell; 0.17 on 28 000 sub-cells
# of 30 % obstacles), and the 11 survivors' re-plans took 62-67 s on the 2 cores, 0.29 ms
# per sub-cell and survivor. So the default stall timeout also allows this much per
# sub-cell for each survivor that computes it, shared by the cores they can use: about half
# as much again as that run needed, for a loaded host (1.1 s for the office and 6 robots).
# Where one computes for all, it does so on one core (a 45 420 sub-cell re-plan of 99
# survivors: 8.8 s of CPU; the crowd's own delays are REPLAN_S_PER_AGENT's): 20 s there.
REPLAN_S_PER_SUB_CELL = 0.5e-3
# Nothing is covered while the agents make their first plan: rooms:120x120:1 with 20
# balanced robots planned for 30 s or more (the launcher's own plan, the same one, took
# 30 s of CPU), and the default stall timeout (26 s) failed such missions before a move.
# Until the first move it also allows this many times the launcher's plan per agent that
# computes it, shared by the cores: a loaded host, the agents' process starts.
PLAN_SLACK = 3.0
# From this many free sub-cells `mstc up` says it is planning: a balanced plan there can take
# tens of seconds before anything else is printed.
LARGE_MAP_SUB_CELLS = 8_000

_KILL_RE = re.compile(
    r"^(?P<robot>\d+)@(?:(?:progress=)?(?P<pct>\d+(?:\.\d+)?)%|progress=(?P<pct2>\d+(?:\.\d+)?)"
    r"|(?P<sec>\d+(?:\.\d+)?)s?)$")


# How `mstc up` lists the kills a mission ended before (deploy/launch.py; read back by the
# chaos campaign, deploy/chaos/trial.py).
NOT_CARRIED_OUT = "not carried out (the mission ended first): "
# What `mstc up` prints once every sub-cell is covered (read by the chaos injector, which
# then carries out no more faults: deploy/chaos/inject.py).
MISSION_COVERED = "every reachable sub-cell covered"


@dataclass(frozen=True)
class KillOrder:
    """Kill ``robot`` at ``seconds`` after the mission started, at ``percent`` coverage, or
    once ``step`` steps are complete (tree missions). ``hw`` fails its body in simhw instead
    of killing its process."""

    robot: int
    seconds: float | None = None
    percent: float | None = None
    hw: bool = False
    step: int | None = None

    def is_due(self, elapsed: float | None, coverage: float | None,
               step: int | None) -> bool:
        return ((self.seconds is not None and elapsed is not None and elapsed >= self.seconds)
                or (self.percent is not None and coverage is not None
                    and coverage >= self.percent)
                or (self.step is not None and step is not None and step >= self.step))

    def describe(self) -> str:
        when = (f"{self.seconds:g} s" if self.seconds is not None else
                f"{self.percent:g} %" if self.percent is not None else f"step {self.step}")
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


def mission_starts(settings: UpSettings, grid: OccupancyGrid) -> tuple[SubCell, ...]:
    """Where the robots start: ``--starts``, or free sub-cells drawn from ``--seed``."""
    if settings.starts:
        starts = parse_starts(settings.starts)
        if len(starts) != settings.robots:
            raise UsageError(f"--starts gives {len(starts)} robots, -n says {settings.robots}")
    else:
        starts = random_starts(grid, settings.robots, settings.seed,
                               one_per_cell=algorithm(settings.algo).one_robot_per_cell)
    validate_starts(grid, coarsen(grid), starts)
    return starts


def offline_plan(settings: UpSettings, grid: OccupancyGrid, starts: tuple[SubCell, ...]) -> Plan:
    """The plan of an offline algorithm from these starts, as ``mstc up`` makes it."""
    area = work_area(grid, starts)
    tree = build_tree(area.cells, settings.tree, seed=settings.seed,
                      starts=[cell_of(start) for start in starts])
    plan_for = algorithm(settings.algo).load_plan()
    return plan_for(area, tree, settings.algo, settings.seed)


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
    plan_cpu_s: float = 0.0  # CPU seconds the offline plan took here (the agents plan it again)

    @property
    def k(self) -> int:
        return len(self.starts)

    @classmethod
    def plan(cls, settings: UpSettings, say: Callable[[str], None] | None = None
             ) -> MissionSetup:
        """Load the map, place the robots and plan (PlannerError for user mistakes);
        ``say`` hears that a large map's plan has begun (it can take a minute)."""
        grid = resolve_world(settings.world, settings.cell_size)
        starts = mission_starts(settings, grid)
        plan_cpu_s = 0.0  # the agents' own plan: an on-line fleet's agents make none
        if algorithm(settings.algo).family is Family.ONLINE:
            # An on-line algorithm plans nothing (its agents get no map); its lockstep
            # simulator's coverage time on the same world and starts stands in for the planned
            # makespan, and it rejects two robots in one cell before any process starts.
            planned = algorithm(settings.algo).load_lockstep()(grid, starts).makespan
        else:
            # The agents plan the same way (the offline agent's plan); here it gives the planned
            # makespan and rejects unplannable missions before any process starts.
            free = int(grid.free.sum())
            if say is not None and free >= LARGE_MAP_SUB_CELLS:
                say(f"planning {settings.algo} for {settings.robots} robots on {free} free "
                    f"sub-cells of {settings.world}")
            began = time.process_time()
            planned = offline_plan(settings, grid, starts).makespan
            plan_cpu_s = time.process_time() - began
        return cls(world=settings.world, cell_size=settings.cell_size, grid=grid,
                   starts=starts, algo=settings.algo, tree=settings.tree, seed=settings.seed,
                   time_scale=settings.time_scale, reachable=reachable_sub_cells(grid, starts),
                   planned_makespan=planned, plan_cpu_s=plan_cpu_s)


@dataclass(frozen=True)
class UpSettings:
    """Every setting of one ``mstc up`` run, defaults resolved."""

    robots: int
    world: str = "office"
    cell_size: int | None = None
    starts: str | None = None  # "r,c;r,c;..." as given, or None for random starts
    algo: str = "opt"
    tree: str = "dfs"
    recovery: str = DEFAULT_RECOVERY  # offline agents' --recovery
    seed: int = 0
    time_scale: float = DEFAULT_TIME_SCALE
    kills: tuple[KillOrder, ...] = ()
    mission: str = ""
    run_dir: Path = Path("runs")
    listen: str = ""
    connect: str | None = None  # an existing router; None: start one on ``listen``
    lease_ms: int = DEFAULT_LEASE_MS
    dead_after: float = DEFAULT_DEAD_AFTER_S
    stall_timeout: float = DEFAULT_STALL_S
    plan_allowance: float = 0.0  # more stall timeout until the first move (plan_allowance)
    start_timeout: float = 30.0
    linger: float = 3.0
    timing_args: tuple[str, ...] = ()  # FleetTiming.agent_args(), before agent_args
    booting: int = 0  # FleetTiming.booting: 0 starts every agent at once
    agent_nice: int = 0  # FleetTiming.agent_nice
    agent_args: tuple[str, ...] = ()
    simhw_args: tuple[str, ...] = ()
    plain: bool = False
    record: Path | None = None
    record_mcap: Path | None = None
    credentials: Path | None = None  # the mission's credentials (deploy.security); None: insecure

    @property
    def own_router(self) -> bool:
        return self.connect is None


def stall_timeout(time_scale: float, given: float | None = None, robots: int = 1,
                  cores: int | None = None) -> float:
    """--stall-timeout, by default long enough for STALL_MOVES moves at ``time_scale`` and,
    in a crowded fleet of ``robots`` on ``cores``, for the survivors' re-plan after a death."""
    if given is not None:
        return float(given)
    base = DEFAULT_STALL_S
    if crowded(robots, cores):
        base += REPLAN_S_PER_AGENT * robots / core_count(cores)
    if time_scale == 0 or math.isinf(time_scale):
        return base
    return base + STALL_MOVES * MOVE_SIM_S / time_scale


def replan_allowance(sub_cells: int, robots: int, cores: int | None = None) -> float:
    """Seconds the survivors of ``robots`` may take to re-plan ``sub_cells`` after a death,
    beyond what stall_timeout allows (REPLAN_S_PER_SUB_CELL)."""
    survivors = max(robots - 1, 0)
    computers = 1 if shared_by_one(survivors, sub_cells, REPLAN_SHARE_FROM) else survivors
    if computers == 0:
        return 0.0
    return REPLAN_S_PER_SUB_CELL * sub_cells * computers / min(computers, core_count(cores))


def with_replan_allowance(settings: UpSettings, given: float | None, sub_cells: int,
                          cores: int | None = None) -> UpSettings:
    """``settings`` with the default stall timeout lengthened by the re-plan of a map of
    ``sub_cells`` (unchanged when --stall-timeout was ``given``)."""
    if given is not None:
        return settings
    extra = replan_allowance(sub_cells, settings.robots, cores)
    return dataclasses.replace(settings, stall_timeout=settings.stall_timeout + extra)


def plan_allowance(plan_cpu_s: float, sub_cells: int, robots: int,
                   cores: int | None = None) -> float:
    """Seconds the agents' first plan may add to the stall timeout before the first move:
    PLAN_SLACK times the launcher's own plan (the same plan) for each agent that computes
    it (one, where one computes it for all: agent.offline.apart.shared_by_one), shared by
    the cores they can use."""
    computers = 1 if shared_by_one(robots, sub_cells, PLAN_SHARE_FROM) else max(robots, 1)
    return PLAN_SLACK * plan_cpu_s * computers / min(computers, core_count(cores))


def with_allowances(settings: UpSettings, given: float | None, setup: MissionSetup,
                    cores: int | None = None) -> UpSettings:
    """``settings`` with the default stall timeout lengthened by the re-plan of the map
    (with_replan_allowance; a ``given`` --stall-timeout is kept) and, until the first move,
    by the agents' first plan (plan_allowance), given or not: before the plan no sub-cell
    can be covered, so that time is no stall (a chaos trial's 25 s ran out while 12 agents
    each planned a balanced plan of 8 076 sub-cells for 27 s)."""
    sub_cells = int(setup.reachable.sum())
    settings = with_replan_allowance(settings, given, sub_cells, cores)
    return dataclasses.replace(settings, plan_allowance=plan_allowance(
        setup.plan_cpu_s, sub_cells, settings.robots, cores))


def check_kills(orders: tuple[KillOrder, ...], robots: int) -> tuple[KillOrder, ...]:
    for order in orders:
        if order.robot >= robots:
            raise UsageError(f"--kill {order.robot}: robots are 0..{robots - 1}")
    return orders
