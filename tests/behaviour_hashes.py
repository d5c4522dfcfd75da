"""Hashes of plans and lockstep traces on a fixed instance set, for every algorithm family.

Restructuring must not change behaviour: tests/golden/behaviour_hashes.json was written
before the move to one home per concept (issue 10) and test_behaviour_hashes.py holds every
later commit to it. Regenerate only for an intended change of behaviour:
``python tests/behaviour_hashes.py --write`` (and say why in the commit).
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run as a script from anywhere

GOLDEN = Path(__file__).parent / "golden" / "behaviour_hashes.json"
WORLDS = ("example", "office", "grid30x20", "cave")


def _digest(value: object) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _plans() -> Iterator[tuple[str, object]]:
    from planner.allocation import ALGORITHMS
    from planner.balanced.plan import balanced_plan
    from planner.balanced.takeover import simulate_failures as balanced_failures
    from planner.geometry import cell_of
    from planner.grid import work_area
    from planner.maps import resolve_world
    from planner.offline.lockstep import simulate_failures
    from planner.offline.plan import make_plan
    from planner.placement import random_starts
    from planner.trees import build_tree

    for world in WORLDS:
        grid = resolve_world(world, None)
        for k, seed in ((3, 1), (6, 2)):
            starts = random_starts(grid, k, seed)
            area = work_area(grid, starts)
            for tree_kind in ("dfs", "bfs", "kruskal"):
                tree = build_tree(area.cells, tree_kind, seed=seed,
                                  starts=[cell_of(s) for s in starts])
                for algo in ALGORITHMS:
                    plan = make_plan(area, tree, algo)
                    key = f"{algo}/{world}/k{k}/{tree_kind}"
                    yield key, [list(map(list, rp.path)) for rp in plan.robots]
                    failures = {plan.robots[1].robot: 5, plan.robots[-1].robot: 17}
                    result = simulate_failures(plan, failures, detection_delay=2,
                                               recovery="takeover")
                    yield key + "/takeover", [list(map(list, w)) for w in result.walks]
            plan = balanced_plan(area, seed=seed)
            key = f"balanced/{world}/k{k}"
            yield key, [list(map(list, rp.path)) for rp in plan.robots]
            result = balanced_failures(plan, {plan.robots[0].robot: 7}, detection_delay=1,
                                       recovery="takeover")
            yield key + "/takeover", [list(map(list, w)) for w in result.walks]


def _ormstc() -> Iterator[tuple[str, object]]:
    from planner.maps import resolve_world
    from planner.ormstc.lockstep import SimConfig, simulate
    from planner.placement import random_starts

    for world in WORLDS:
        grid = resolve_world(world, None)
        for k, seed in ((3, 1), (5, 4)):
            starts = _distinct_cells(random_starts(grid, k, seed))
            for config in (SimConfig(seed=seed),
                           SimConfig(seed=seed, delay=(1, 4), failures=((0, 30),))):
                result = simulate(grid, starts, config)
                key = f"ormstc/{world}/k{len(starts)}/d{config.delay[1]}"
                yield key, {"paths": [list(map(list, p)) for p in result.paths],
                            "trees": [[list(map(list, e)) for e in t] for t in result.trees],
                            "claims": [[s, r, list(c)] for s, r, c in result.claims],
                            "steps": result.steps, "turns": list(result.sense_turns)}


def _distinct_cells(starts: tuple[tuple[int, int], ...]) -> tuple[tuple[int, int], ...]:
    seen: set[tuple[int, int]] = set()
    kept = []
    for r, c in starts:
        if (r // 2, c // 2) not in seen:
            seen.add((r // 2, c // 2))
            kept.append((r, c))
    return tuple(kept)


def _treecover() -> Iterator[tuple[str, object]]:
    from planner.treecover.sim import run_coverage
    from planner.treecover.trees import tree_from_spec

    for spec, robots in (("perfect:N=3,H=4", 8), ("perfect:N=2,H=6", 6)):
        tree = tree_from_spec(spec)
        for algo in ("cocta", "ncocta"):
            result = run_coverage(tree, robots, algo)
            yield f"{algo}/{spec}/k{robots}", {"time": result.time,
                                               "visits": result.visit_time.tolist()}


def compute() -> dict[str, str]:
    out: dict[str, str] = {}
    for source in (_plans, _ormstc, _treecover):
        for key, value in source():
            out[key] = _digest(value)
    return out


if __name__ == "__main__":
    hashes = compute()
    if "--write" in sys.argv:
        GOLDEN.write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n")
    print(f"{len(hashes)} hashes, digest {_digest(hashes)}")
