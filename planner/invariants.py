"""Shared invariant checkers for trees, cycles, paths and plans (in the style of Fields2Cover).

Every checker returns None when the invariant holds and raises InvariantViolation (an
AssertionError, so pytest shows it as a failed assertion) with a message naming the first
offending edge, cell, step or robot. They are used by the tests of every planner module.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence

import numpy as np

from planner.geometry import cell_of
from planner.grid import WorkArea, expand, label_linked
from planner.types import BoolArray, Cycle, Plan, SpanningTree, SubCell

_SHOWN = 5  # how many offending items a message lists


class InvariantViolation(AssertionError):
    """An invariant of a tree, cycle, path or plan does not hold."""


def check_tree(tree: SpanningTree) -> None:
    """The tree spans exactly ``tree.cells``: edges between free cells, connected, acyclic."""
    cells = tree.cells
    if tree.right.shape != cells.shape or tree.down.shape != cells.shape:
        raise InvariantViolation(
            f"edge arrays {tree.right.shape}/{tree.down.shape} differ from cells {cells.shape}")
    if tree.right[:, -1].any() or tree.down[-1, :].any():
        raise InvariantViolation("an edge leaves the grid (last column of right / row of down)")
    bad_right = tree.right[:, :-1] & ~(cells[:, :-1] & cells[:, 1:])
    bad_down = tree.down[:-1, :] & ~(cells[:-1, :] & cells[1:, :])
    for name, bad, step in (("right", bad_right, (0, 1)), ("down", bad_down, (1, 0))):
        if bad.any():
            r, c = (int(x) for x in np.argwhere(bad)[0])
            raise InvariantViolation(
                f"{name} edge ({r}, {c})-({r + step[0]}, {c + step[1]}) touches a cell outside "
                "tree.cells")
    n = tree.cell_count
    if n == 0:
        raise InvariantViolation("the tree has no cells")
    if tree.edge_count != n - 1:
        raise InvariantViolation(
            f"{tree.edge_count} edges over {n} cells: a spanning tree has exactly {n - 1}")
    _, parts = label_linked(cells, tree.right, tree.down)
    if parts != 1:
        raise InvariantViolation(f"the tree's edges leave its {n} cells in {parts} parts")
    # n - 1 edges joining n cells into one part cannot contain a cycle.


def check_path_moves(path: Sequence[SubCell], *, allow_wait: bool = False) -> None:
    """Consecutive sub-cells are 4-adjacent: one step of one sub-cell, no teleport.

    Staying still (a sub-cell repeated) is rejected unless ``allow_wait``: plans and executed
    walks list moves only, waiting is time, not a step of the walk.
    """
    if len(path) < 2:
        return
    steps = np.abs(np.diff(np.asarray(path, dtype=np.int64).reshape(-1, 2), axis=0)).sum(axis=1)
    allowed = (steps == 1) | ((steps == 0) & allow_wait)
    if not allowed.all():
        i = int(np.flatnonzero(~allowed)[0])
        what = "stays still" if steps[i] == 0 else "is not a 4-adjacent move"
        raise InvariantViolation(f"step {i}: {tuple(path[i])} -> {tuple(path[i + 1])} {what}")


def check_cycle(cycle: Cycle, tree: SpanningTree) -> None:
    """The cycle visits every sub-cell of the tree's cells once, closes, and circles the tree.

    Besides 4-adjacent steps (last -> first included), every step from one cell into another
    must cross a tree edge: the STC walk never cuts through the tree.
    """
    want = expand(tree.cells)
    n = int(want.sum())
    if cycle.n != n:
        raise InvariantViolation(f"cycle has {cycle.n} sub-cells, the tree's cells have {n}")
    path = [(int(r), int(c)) for r, c in cycle.path]
    repeated = [s for s, count in Counter(path).items() if count > 1]
    if repeated:
        raise InvariantViolation(f"cycle visits {repeated[:_SHOWN]} more than once")
    outside = [s for s in path
               if not (0 <= s[0] < want.shape[0] and 0 <= s[1] < want.shape[1] and want[s])]
    if outside:
        raise InvariantViolation(f"cycle visits {outside[:_SHOWN]}, not sub-cells of the tree")
    check_path_moves([*path, path[0]])
    for i, s in enumerate(path):
        if cycle.position(s) != i:
            raise InvariantViolation(f"cycle.index{s} is {cycle.position(s)}, path has it at {i}")
    if int((cycle.index >= 0).sum()) != n:
        raise InvariantViolation("cycle.index marks sub-cells that are not on the path")
    for i, s in enumerate(path):
        t = path[(i + 1) % n]
        a, b = cell_of(s), cell_of(t)
        if a != b and not _has_edge(tree, a, b):
            raise InvariantViolation(
                f"cycle step {i}: {s} -> {t} crosses from cell {a} to {b} without a tree edge")


def _has_edge(tree: SpanningTree, a: tuple[int, int], b: tuple[int, int]) -> bool:
    (r1, c1), (r2, _) = sorted((a, b))
    if r1 == r2:
        return bool(tree.right[r1, c1])
    return bool(tree.down[r1, c1])


def check_coverage(covered_sub_cells: BoolArray | Iterable[SubCell],
                   area: WorkArea | BoolArray) -> None:
    """Every sub-cell of ``area`` (a WorkArea or a sub-cell mask) is in ``covered_sub_cells``."""
    want = area.sub_cells if isinstance(area, WorkArea) else np.asarray(area, dtype=bool)
    got = np.zeros(want.shape, dtype=bool)
    if isinstance(covered_sub_cells, np.ndarray):
        mask = covered_sub_cells.astype(bool)
        got[: mask.shape[0], : mask.shape[1]] |= mask[: want.shape[0], : want.shape[1]]
    else:
        for r, c in covered_sub_cells:
            if 0 <= r < want.shape[0] and 0 <= c < want.shape[1]:
                got[r, c] = True
    missing = np.argwhere(want & ~got)
    if missing.size:
        shown = [(int(r), int(c)) for r, c in missing[:_SHOWN]]
        raise InvariantViolation(
            f"{len(missing)} of {int(want.sum())} sub-cells not covered, e.g. {shown}")


def check_plan(plan: Plan, area: WorkArea | None = None, *, max_visits: int = 1,
               own_revisits_only: bool = True) -> None:
    """A plan's walks start at the robots' starts, move 4-adjacently and cover the area.

    The target is ``area``'s sub-cells when given, else the cycle's. No walk may leave the
    target, no sub-cell may be visited more than ``max_visits`` times in total, and with
    ``own_revisits_only`` a sub-cell visited twice must be visited by one robot only (MSTC
    robots backtrack only over their own steps).
    """
    want = area.sub_cells if area is not None else plan.cycle.index >= 0
    visits: Counter[SubCell] = Counter()
    visitors: dict[SubCell, set[int]] = {}
    for rp in plan.robots:
        path = [(int(r), int(c)) for r, c in rp.path]
        if not path:
            raise InvariantViolation(f"robot {rp.robot} has an empty path")
        if path[0] != tuple(rp.start):
            raise InvariantViolation(
                f"robot {rp.robot} path begins at {path[0]}, not at its start {rp.start}")
        if area is not None and tuple(area.starts[rp.robot]) != path[0]:
            raise InvariantViolation(
                f"robot {rp.robot} starts at {path[0]}, the work-area says {area.starts[rp.robot]}")
        if plan.cycle.position(path[0]) != rp.start_index:
            raise InvariantViolation(
                f"robot {rp.robot} start {path[0]} is at cycle index "
                f"{plan.cycle.position(path[0])}, not its start_index {rp.start_index}")
        try:
            check_path_moves(path)
        except InvariantViolation as exc:
            raise InvariantViolation(f"robot {rp.robot}: {exc}") from exc
        for s in path:
            if not (0 <= s[0] < want.shape[0] and 0 <= s[1] < want.shape[1] and want[s]):
                raise InvariantViolation(f"robot {rp.robot} visits {s}, outside the target")
            visits[s] += 1
            visitors.setdefault(s, set()).add(rp.robot)
    check_coverage(list(visits), want)
    over = [(s, v) for s, v in visits.items() if v > max_visits]
    if over:
        raise InvariantViolation(
            f"{len(over)} sub-cells visited more than {max_visits} times, e.g. {over[:_SHOWN]}")
    if own_revisits_only:
        shared = [(s, sorted(r)) for s, r in visitors.items() if len(r) > 1]
        if shared:
            raise InvariantViolation(
                f"{len(shared)} sub-cells visited by several robots, e.g. {shared[:_SHOWN]}")
