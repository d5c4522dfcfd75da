"""The explored state of a connected tree coverage run, updated move by move.

Kept incrementally (robots per node, robots per subtree, unexplored and unfinished nodes per
subtree) so a step costs time proportional to the occupied nodes, not to the tree: a 4-ary
tree of height 8 has 87,381 nodes.
"""

from __future__ import annotations

from collections.abc import Iterable

from planner.treecover.types import Move, Tree


class CoverageState:
    """Where the robots are and what has been explored. Node ids are the tree's."""

    def __init__(self, tree: Tree, robots: int, need: list[int] | None = None) -> None:
        if robots < 1:
            raise ValueError("at least one robot is needed")
        self.tree = tree
        self.robots = robots
        self.parent: list[int] = tree.parent.tolist()
        self.level: list[int] = (tree.height - tree.depth).tolist()
        starts = tree.child_start.tolist()
        index = tree.child_index.tolist()
        self.children: list[list[int]] = [index[starts[v]:starts[v + 1]] for v in range(tree.n)]
        self.unexplored, reach = _subtree_sizes_and_heights(self.parent, self.children)
        self.unfinished_nodes = list(self.unexplored)  # w in T_v with unexplored[w] > 0
        self.need = need if need is not None else [r + 1 for r in reach]
        self.sub = [0] * tree.n
        self.sub[0] = robots
        self.at: dict[int, int] = {0: robots}
        self.visit_time = [-1] * tree.n
        self._inhabited: dict[int, int] | None = None
        self.time = 0
        self.remaining = tree.n
        self._visit(0)

    def finished(self, v: int) -> bool:
        """T_v explored and every robot of T_v (if any) standing on v."""
        return self.unexplored[v] == 0 and self.sub[v] == self.at.get(v, 0)

    def done(self) -> bool:
        return self.finished(0) and self.at.get(0, 0) == self.robots

    def useful(self, v: int) -> int:
        """Robots T_v can use while it has unexplored nodes: one per node of T_v that is not
        finished (paper 001, section 4.3), which counts the trail to every unexplored node as
        well as the nodes themselves; never fewer than ``need[v]``, the team that finishes T_v
        without stalling under the splits (a floor that almost never binds)."""
        if self.unexplored[v] == 0:
            return 0
        return max(self.not_finished(v), self.need[v])

    def not_finished(self, v: int) -> int:
        """Nodes w of T_v that are not finished: unexplored nodes below or at w, or robots
        strictly below w."""
        if self._inhabited is None:
            self._inhabited = self._explored_with_robots_below()
        return self.unfinished_nodes[v] + self._inhabited.get(v, 0)

    def apply(self, moves: Iterable[Move]) -> None:
        """Perform one synchronous step (all moves at once)."""
        self.time += 1
        self._inhabited = None
        parent, at, sub = self.parent, self.at, self.sub
        for move in moves:
            left = at[move.src] - move.count
            if left < 0 or move.count <= 0:
                raise ValueError(f"bad move {move}: {at[move.src]} robots at {move.src}")
            if left:
                at[move.src] = left
            else:
                del at[move.src]
            at[move.dst] = at.get(move.dst, 0) + move.count
            if parent[move.dst] == move.src:
                sub[move.dst] += move.count
            elif parent[move.src] == move.dst:
                sub[move.src] -= move.count
            else:
                raise ValueError(f"bad move {move}: not along a tree edge")
        for v in at:
            if self.visit_time[v] < 0:
                self._visit(v)

    def remove(self, v: int) -> None:
        """One robot standing on ``v`` is gone (it died): the counts on v's path to the root
        and the team size drop by one. Connectivity is the caller's to restore."""
        if self.at.get(v, 0) < 1:
            raise ValueError(f"no robot on node {v} to remove")
        if self.robots <= 1:
            raise ValueError("cannot remove the last robot")
        self._inhabited = None
        self.robots -= 1
        if self.at[v] == 1:
            del self.at[v]
        else:
            self.at[v] -= 1
        while v >= 0:
            self.sub[v] -= 1
            v = self.parent[v]

    def unvisit(self, v: int) -> None:
        """Node ``v`` was not visited after all (the robot meant to visit it died on the way):
        the exact inverse of the visit's bookkeeping."""
        if self.visit_time[v] < 0:
            raise ValueError(f"node {v} was not visited")
        self.visit_time[v] = -1
        self.remaining += 1
        self._inhabited = None
        parent, unexplored, unfinished = self.parent, self.unexplored, self.unfinished_nodes
        opened = 0  # the path nodes this reopens: a prefix from v up, as a visit closes them
        while v >= 0:
            if unexplored[v] == 0:
                opened += 1
            unexplored[v] += 1
            unfinished[v] += opened
            v = parent[v]

    def connected(self) -> bool:
        """Lemma 4.1: occupied nodes induce one connected subtree (exactly one has its parent
        unoccupied, or is the root)."""
        at, parent = self.at, self.parent
        tops = sum(1 for v in at if parent[v] < 0 or parent[v] not in at)
        return tops == 1

    def _visit(self, v: int) -> None:
        self.visit_time[v] = self.time
        self.remaining -= 1
        parent, unexplored, unfinished = self.parent, self.unexplored, self.unfinished_nodes
        closed = 0  # the path nodes whose subtree this visit completes: a prefix from v up
        while v >= 0:
            unexplored[v] -= 1
            if unexplored[v] == 0:
                closed += 1
            unfinished[v] -= closed
            v = parent[v]

    def _explored_with_robots_below(self) -> dict[int, int]:
        """Per subtree, its explored nodes that still have robots strictly below them (the
        paper's inhabited nodes): exactly the explored proper ancestors of occupied nodes."""
        parent, unexplored = self.parent, self.unexplored
        ancestors: set[int] = set()
        for x in self.at:
            w = parent[x]
            while w >= 0 and w not in ancestors:
                ancestors.add(w)
                w = parent[w]
        counts: dict[int, int] = {}
        for w in ancestors:
            if unexplored[w] == 0:
                while w >= 0:
                    counts[w] = counts.get(w, 0) + 1
                    w = parent[w]
        return counts


def _subtree_sizes_and_heights(parent: list[int],
                               children: list[list[int]]) -> tuple[list[int], list[int]]:
    size = [1] * len(parent)
    reach = [0] * len(parent)
    for v in range(len(parent) - 1, 0, -1):  # children come after parents
        p = parent[v]
        size[p] += size[v]
        if reach[v] + 1 > reach[p]:
            reach[p] = reach[v] + 1
    return size, reach
