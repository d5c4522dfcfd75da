"""Tree environments: perfect N-ary trees, perfect trees with random subtrees removed, and
trees read from ``.tree`` files (the one file loader in this package).

``.tree`` format: one edge ``parent child`` per line, names without spaces; ``#`` starts a
comment; blank lines are ignored. The root is the one name that never appears as a child.
Every other name must appear exactly once as a child and be reachable from the root.
"""

from __future__ import annotations

import re
from collections import deque
from importlib import resources
from pathlib import Path

import numpy as np

from planner.errors import PlannerError, TreeFormatError
from planner.treecover.types import Tree

_SPEC_KEYS = {"perfect": {"N", "H"}, "general": {"N", "H", "remove", "at", "seed"}}


def from_parents(parent: np.ndarray, labels: tuple[str, ...] = (), name: str = "tree",
                 branching: int = 0) -> Tree:
    """A Tree from a parent array already in an order where parents precede children."""
    parent = np.asarray(parent, dtype=np.int64)
    n = parent.shape[0]
    if n == 0 or parent[0] != -1 or np.any(parent[1:] < 0) or np.any(parent[1:] >= np.arange(1, n)):
        raise ValueError("parent array must start with the root and list parents first")
    depth = np.zeros(n, dtype=np.int64)
    for v in range(1, n):  # parents precede children, so one forward pass suffices
        depth[v] = depth[parent[v]] + 1
    child_index = np.argsort(parent[1:], kind="stable") + 1
    counts = np.bincount(parent[1:], minlength=n)
    child_start = np.concatenate(([0], np.cumsum(counts)))
    return Tree(parent, depth, child_start, child_index.astype(np.int64), labels, name, branching)


def perfect_tree(branching: int, height: int) -> Tree:
    """The perfect ``branching``-ary tree of ``height`` (leaves at height 0), in BFS order."""
    if branching < 1 or height < 0:
        raise PlannerError(f"a perfect tree needs N >= 1 and H >= 0 (got N={branching}, "
                           f"H={height})")
    sizes = branching ** np.arange(height + 1)
    n = int(sizes.sum())
    if n > 5_000_000:
        raise PlannerError(f"perfect tree N={branching}, H={height} has {n} nodes (> 5e6)")
    parent = (np.arange(n) - 1) // branching
    parent[0] = -1
    depth = np.repeat(np.arange(height + 1), sizes)
    child_start = np.minimum(branching * np.arange(n + 1), n - 1)
    return Tree(parent.astype(np.int64), depth.astype(np.int64), child_start.astype(np.int64),
                np.arange(1, n, dtype=np.int64), (), f"perfect N={branching} H={height}",
                branching)


def general_tree(branching: int, height: int, remove: int, at_height: int,
                 seed: int) -> Tree:
    """A perfect tree with ``remove`` random nodes of height ``at_height`` cut off, each with
    its whole subtree (the paper's imperfect trees)."""
    full = perfect_tree(branching, height)
    if not 0 <= at_height < height:
        raise PlannerError(f"remove height must be in [0, {height - 1}] (got {at_height})")
    candidates = np.flatnonzero(full.depth == height - at_height)
    if not 0 <= remove < candidates.size:
        raise PlannerError(f"can remove 0..{candidates.size - 1} nodes at height {at_height} "
                           f"(got {remove})")
    rng = np.random.default_rng(seed)
    removed = np.zeros(full.n, dtype=bool)
    removed[rng.choice(candidates, size=remove, replace=False)] = True
    for d in range(height - at_height + 1, height + 1):  # propagate cuts one level at a time
        level = np.flatnonzero(full.depth == d)
        removed[level] |= removed[full.parent[level]]
    kept = np.flatnonzero(~removed)
    new_id = np.full(full.n, -1, dtype=np.int64)
    new_id[kept] = np.arange(kept.size)
    parent = np.where(full.parent[kept] >= 0, new_id[np.maximum(full.parent[kept], 0)], -1)
    name = f"general N={branching} H={height} remove={remove}@{at_height} seed={seed}"
    return from_parents(parent, (), name, branching)


def parse_tree(text: str, source: str = "<text>") -> Tree:
    """Parse the ``.tree`` edge-list format; errors name the source, line and expectation."""
    parent_of: dict[str, tuple[str, int]] = {}
    order: list[str] = []
    children: dict[str, list[str]] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) != 2:
            raise TreeFormatError(source, f"expected 'parent child', got {line!r}", number)
        parent, child = parts
        if parent == child:
            raise TreeFormatError(source, f"node {child!r} cannot be its own parent", number)
        if child in parent_of:
            first = parent_of[child][1]
            raise TreeFormatError(source, f"node {child!r} already has a parent (line {first});"
                                  " a tree node has exactly one", number)
        parent_of[child] = (parent, number)
        for node in parts:
            if node not in children:
                children[node] = []
                order.append(node)
        children[parent].append(child)
    if not order:
        raise TreeFormatError(source, "expected at least one 'parent child' edge, found none")
    roots = [node for node in order if node not in parent_of]
    if len(roots) != 1:
        culprit = parent_of[order[0]][1] if not roots else None
        what = "no root (every node has a parent: a cycle)" if not roots else \
            f"expected one root, found {len(roots)}: {', '.join(roots[:5])}"
        raise TreeFormatError(source, what, culprit)
    return _bfs_tree(roots[0], children, parent_of, source)


def _bfs_tree(root: str, children: dict[str, list[str]],
              parent_of: dict[str, tuple[str, int]], source: str) -> Tree:
    index = {root: 0}
    names = [root]
    parents = [-1]
    queue = deque([root])
    while queue:
        node = queue.popleft()
        for child in children[node]:
            index[child] = len(names)
            names.append(child)
            parents.append(index[node])
            queue.append(child)
    if len(names) != len(children):
        stray = next(node for node in children if node not in index)
        raise TreeFormatError(source, f"node {stray!r} is not reachable from root {root!r} "
                              "(edges form a cycle)", parent_of[stray][1])
    return from_parents(np.array(parents), tuple(names), Path(source).stem)


def load_tree(path: str | Path) -> Tree:
    """Read a ``.tree`` file."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as error:
        raise PlannerError(f"{path}: cannot read tree file ({error.strerror})") from error
    except UnicodeDecodeError as error:
        raise TreeFormatError(str(path), "expected UTF-8 text") from error
    return parse_tree(text, str(path))


def office_tree() -> Tree:
    """The sample office floor shipped as ``planner/data/trees/office.tree``."""
    text = resources.files("planner.data.trees").joinpath("office.tree").read_text("utf-8")
    return parse_tree(text, "office.tree")


def tree_from_spec(spec: str) -> Tree:
    """``perfect:N=3,H=7``, ``general:N=2,H=10,remove=5,at=3,seed=1``, ``office`` or a path."""
    kind, _, rest = spec.partition(":")
    if kind == "office" and not rest:
        return office_tree()
    if kind not in _SPEC_KEYS or not rest:
        return load_tree(spec)
    values: dict[str, int] = {}
    for item in rest.split(","):
        match = re.fullmatch(r"\s*(\w+)\s*=\s*(-?\d+)\s*", item)
        if match is None or match.group(1) not in _SPEC_KEYS[kind]:
            raise PlannerError(f"tree spec {spec!r}: expected KEY=INT with KEY in "
                               f"{sorted(_SPEC_KEYS[kind])}, got {item!r}")
        values[match.group(1)] = int(match.group(2))
    missing = {"N", "H"} - values.keys()
    if missing:
        raise PlannerError(f"tree spec {spec!r}: missing {', '.join(sorted(missing))}")
    if kind == "perfect":
        return perfect_tree(values["N"], values["H"])
    return general_tree(values["N"], values["H"], values.get("remove", 0),
                        values.get("at", 0), values.get("seed", 0))
