"""An independent oracle of offline MSTC takeovers (paper 003, Alg. 2 and Alg. 4).

Written from the papers' rules and docs/trees-and-metrics.md (rules 5 and 6), not from
planner.offline: no OfflineRobot, no region_of, no shared time loop. It is one global
simulation over the cycle with every region held as an explicit set of cycle indices, so a
wrong takeover decision in the state machine the agents run shows up as a difference here.

The rules, as the papers state them and the project refines them:

- Each robot walks its own section (its plan's path) one move per unit step; a robot that
  fails at time f has made exactly f moves and never moves again (fail-stop).
- A robot with nothing left to walk watches the robot after it along the cycle (ordered by
  start index: Alg. 2 line 2, ``t <- i + 1``). While coverage is incomplete and the watched
  robot is known dead (``f + delay <= t``) it takes that robot's role over (Alg. 2 lines 8-11,
  Alg. 4 lines 13-16): it walks counter-clockwise from where it stands to the last sub-cell of
  the dead robot's region that is still uncovered, and then watches the dead robot's
  successor. A dead robot whose region is complete costs no walk; the chain goes on.
- Everyone knows the coverage as it was at the start of the step (perfect knowledge, moves of
  one step are simultaneous).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from planner.types import Plan, SubCell

NEVER = 1 << 60


@dataclass(frozen=True)
class OracleRun:
    """``walks[r]``: the cycle indices robot r stood on, start first; ``takeovers``:
    (taker, dead, time) in decision order; ``first_time[i]``: when index i was first covered;
    ``arrivals[r]``: (time, index) of each of robot r's moves."""

    order: tuple[int, ...]
    walks: dict[int, list[int]]
    takeovers: list[tuple[int, int, int]]
    first_time: dict[int, int]
    n: int
    arrivals: dict[int, list[tuple[int, int]]]

    @property
    def complete(self) -> bool:
        return len(self.first_time) == self.n

    @property
    def coverage_time(self) -> int | None:
        return max(self.first_time.values()) if self.complete else None

    def visits(self) -> dict[int, int]:
        out = dict.fromkeys(range(self.n), 0)
        for walk in self.walks.values():
            for i in walk:
                out[i] += 1
        return out


def region_first(region: set[int], n: int) -> int:
    """The index of an arc of the n-cycle whose predecessor is outside the arc."""
    if len(region) == n:
        return min(region)
    heads = [i for i in region if (i - 1) % n not in region]
    assert len(heads) == 1, f"region {sorted(region)} is not one arc of the {n}-cycle"
    return heads[0]


def run(n: int, starts: Mapping[int, int], own_walks: Mapping[int, Sequence[int]],
        failures: Mapping[int, int], delay: int = 0) -> OracleRun:
    """Replay robots ``starts`` (id -> start index) walking ``own_walks`` (id -> indices after
    the start, one per move) over the n-cycle with ``failures`` (id -> time of death)."""
    ids = list(starts)
    regions = {r: {starts[r], *own_walks[r]} for r in ids}
    seen: set[int] = set()
    for r in ids:
        assert not regions[r] & seen, f"regions overlap at robot {r}"
        seen |= regions[r]
    assert seen == set(range(n)), "regions do not tile the cycle"
    # Robots "after" each other along the cycle, i.e. by start index.
    by_start = sorted(ids, key=lambda r: starts[r])
    after = {r: by_start[(j + 1) % len(by_start)] for j, r in enumerate(by_start)}

    def last_uncovered(robot: int, covered: set[int]) -> int | None:
        first = region_first(regions[robot], n)
        size = len(regions[robot])
        for offset in range(size - 1, -1, -1):
            if (first + offset) % n not in covered:
                return (first + offset) % n
        return None

    position = dict(starts)
    todo: dict[int, list[int]] = {r: list(own_walks[r]) for r in ids}
    watched = dict(after)
    walks = {r: [starts[r]] for r in ids}
    arrivals: dict[int, list[tuple[int, int]]] = {r: [] for r in ids}
    first_time = {starts[r]: 0 for r in ids}
    takeovers: list[tuple[int, int, int]] = []
    death = {r: failures.get(r, NEVER) for r in ids}
    t = 0
    while True:
        covered = set(first_time)
        known_dead = {r for r in ids if death[r] + delay <= t}
        moving = []
        for r in ids:
            if death[r] <= t:
                continue
            if not todo[r] and len(covered) < n:
                while watched[r] != r and watched[r] in known_dead:
                    dead = watched[r]
                    watched[r] = after[dead]
                    takeovers.append((r, dead, t))
                    target = last_uncovered(dead, covered)
                    if target is not None:
                        steps = (target - position[r]) % n
                        todo[r] = [(position[r] + j) % n for j in range(1, steps + 1)]
                        break
            if todo[r]:
                moving.append(r)
        for r in moving:
            at = todo[r].pop(0)
            position[r] = at
            walks[r].append(at)
            arrivals[r].append((t + 1, at))
            first_time.setdefault(at, t + 1)
        if moving:
            t += 1
            continue
        if len(first_time) == n:
            break
        later = [death[r] + delay for r in ids if t < death[r] + delay < NEVER]
        if not later:
            break
        t = min(later)
    return OracleRun(tuple(ids), walks, takeovers, first_time, n, arrivals)


def run_plan(plan: Plan, failures: Mapping[int, int], delay: int = 0) -> OracleRun:
    """:func:`run` on a plan: its robots' starts and walked paths as cycle indices."""
    cycle = plan.cycle
    starts = {rp.robot: rp.start_index for rp in plan.robots}
    own = {rp.robot: [cycle.position((int(r), int(c))) for r, c in rp.path[1:]]
           for rp in plan.robots}
    return run(cycle.n, starts, own, failures, delay)


def walks_as_subcells(plan: Plan, result: OracleRun) -> dict[int, list[SubCell]]:
    return {r: [plan.cycle.at(i) for i in walk] for r, walk in result.walks.items()}


def ordered_walks(plan: Plan, result: OracleRun) -> list[list[SubCell]]:
    """The oracle's walks as sub-cells, in the plan's robot order."""
    by_robot = walks_as_subcells(plan, result)
    return [by_robot[rp.robot] for rp in plan.robots]


def fit_failures(plan: Plan, moves: Mapping[int, int]) -> dict[int, int]:
    """Failure times under which the oracle gives each dead robot ``moves`` moves (earlier
    deaths first; a robot that died waiting or taking over is fitted by search)."""
    failures: dict[int, int] = {}
    for robot in sorted(moves, key=lambda r: moves[r]):
        for when in range(moves[robot], 4 * plan.cycle.n):
            if len(run_plan(plan, {**failures, robot: when}).walks[robot]) - 1 == moves[robot]:
                failures[robot] = when
                break
        else:
            raise AssertionError(f"no failure time gives robot {robot} {moves[robot]} moves")
    return failures
