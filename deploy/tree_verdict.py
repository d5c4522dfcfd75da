"""The verdict on a tree-coverage run, from what its robots reported: the figures beside the
lockstep simulator's for the same input and the same deaths, and "ok" or every problem found.
Pure; used by ``mstc tree-fleet`` at the end of its run and by ``mstc report`` on a recording
of one."""

from __future__ import annotations

from bus.messages import RadioStats
from deploy.tree_observer import ObservedRun
from planner.treecover.failures import run_with_failures
from planner.treecover.sim import run_coverage
from planner.treecover.types import CoverageResult, Tree


def lockstep_run(tree: Tree, robots: int, algo: str,
                 deaths: dict[int, int]) -> tuple[CoverageResult, int]:
    """The lockstep run to equal (with every robot removed at the step the fleet removed
    it), and at how many death steps it was cut."""
    if not deaths:
        return run_coverage(tree, robots, algo), 0
    repaired = run_with_failures(tree, robots, algo, deaths)
    return repaired.result, repaired.cut_at_death


def summarize(tree: Tree, lockstep: CoverageResult, seen: ObservedRun, *, ok: bool = True,
              message: str = "", lockstep_cuts: int = 0, radio: RadioStats | None = None,
              wall_seconds: float | None = None,
              mission_seconds: float | None = None) -> dict[str, object]:
    """The run's figures beside the lockstep run's (with the same failures, if any), and a
    verdict. ``ok``/``message``: whether the processes themselves ended well."""
    time = seen.coverage_time
    problems = [] if ok else [message]
    if time != lockstep.time:
        problems.append(f"fleet coverage time {time} != lockstep {lockstep.time}")
    if seen.visited != tree.n:
        problems.append(f"visited {seen.visited} of {tree.n} nodes")
    if not seen.connected or seen.jumps:
        problems.append(f"connected at every step: {seen.connected}, jumps: {seen.jumps}")
    if not lockstep.connected:
        problems.append("the lockstep run with these failures was not connected at every step")
    if seen.cut_at_death != lockstep_cuts:
        problems.append(f"cut at {seen.cut_at_death} death steps, lockstep {lockstep_cuts}")
    return {
        "tree": tree.name, "nodes": tree.n, "height": tree.height,
        "algo": lockstep.algo.value, "robots": lockstep.robots,
        "split_heights": list(lockstep.splits.heights),
        "coverage_time": time, "lockstep_time": lockstep.time,
        "speedup": round(lockstep.single_time / time, 4) if time else None,
        "visited": seen.visited, "connected_every_step": seen.connected,
        "deaths": {str(robot): step for robot, step in sorted(seen.deaths.items())},
        "cut_at_death": seen.cut_at_death,
        "wall_seconds": None if wall_seconds is None else round(wall_seconds, 2),
        "mission_seconds": None if mission_seconds is None else round(mission_seconds, 2),
        "transmissions": seen.transmissions,
        "deliveries": radio.deliveries if radio else None,
        "refused_out_of_range": radio.refused if radio else None,
        "radio_pending": radio.pending if radio else None,
        "radio_dropped": (radio.unlocated + radio.spoofed) if radio else None,
        "verdict": "ok" if not problems else "; ".join(problems),
    }


def format_verdict(summary: dict[str, object]) -> str:
    return "\n".join(f"{key:>22}: {value}" for key, value in summary.items())
