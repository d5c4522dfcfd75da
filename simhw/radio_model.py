"""The radio of connected tree coverage, sans I/O: who hears a transmission (paper 001).

Robots stand on tree nodes and hear only robots on the same or an adjacent node. The
algorithms are synchronous, so the radio is slotted by step: a transmission made at step t
reaches the robots whose node *at step t* is in range of the sender's node at step t. A robot's
node at step t is learnt from its own report for t (``locate``); a transmission for a robot not
located at that step yet is held until it is (a robot still finishing step t - 1 must not be
judged by where it stood then), so no robot's speed decides what it hears.

Generic over the payload so the rule can be tested without the wire.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Generic, TypeVar

P = TypeVar("P")


def in_range(parent: Sequence[int], a: int, b: int) -> bool:
    """Robots on nodes ``a`` and ``b`` hear each other: same node or one tree edge apart."""
    return a == b or parent[a] == b or parent[b] == a


@dataclass
class RadioCounters:
    transmissions: int = 0
    deliveries: int = 0
    refused: int = 0
    unlocated: int = 0


@dataclass
class _Held(Generic[P]):
    """A transmission of one step still waiting for robots not located at that step."""

    sender: int
    node: int
    payload: P
    waiting: set[int] = field(default_factory=set)


class RadioModel(Generic[P]):
    """Decides deliveries for ``robots`` robots (ids 0..robots-1) on a tree given by its
    parent array. Every method returns the deliveries it makes now as (robot, payload)."""

    def __init__(self, parent: Sequence[int], robots: int) -> None:
        if robots < 1:
            raise ValueError("the radio needs at least one robot")
        self.parent = list(parent)
        self.robots = robots
        self.counters = RadioCounters()
        self._nodes: dict[int, dict[int, int]] = {}  # step -> robot -> node
        self._latest = [-1] * robots  # latest step each robot was located at
        self._held: dict[int, list[_Held[P]]] = {}  # step -> transmissions held

    @property
    def pending(self) -> int:
        """(transmission, robot) pairs held for robots not located yet."""
        return sum(len(h.waiting) for held in self._held.values() for h in held)

    def node_of(self, robot: int, step: int) -> int | None:
        return self._nodes.get(step, {}).get(robot)

    def locate(self, robot: int, step: int, node: int) -> list[tuple[int, P]]:
        """``robot`` stands on ``node`` at ``step``; release what was held for it."""
        self._check(robot, node)
        self._nodes.setdefault(step, {})[robot] = node
        self._latest[robot] = max(self._latest[robot], step)
        out: list[tuple[int, P]] = []
        held = self._held.get(step, [])
        for item in held:
            if robot in item.waiting:
                item.waiting.discard(robot)
                self._judge(item.node, robot, node, item.payload, out)
        self._held[step] = [h for h in held if h.waiting]
        self._forget_old_steps()
        return out

    def transmit(self, sender: int, step: int, payload: P) -> list[tuple[int, P]]:
        """``sender`` transmits ``payload`` at ``step`` from where it stands at that step."""
        self.counters.transmissions += 1
        nodes = self._nodes.get(step, {})
        node = nodes.get(sender)
        if node is None:
            self.counters.unlocated += 1
            return []
        out: list[tuple[int, P]] = []
        waiting: set[int] = set()
        for robot in range(self.robots):
            if robot == sender:
                continue
            where = nodes.get(robot)
            if where is None:
                waiting.add(robot)
            else:
                self._judge(node, robot, where, payload, out)
        if waiting:
            self._held.setdefault(step, []).append(_Held(sender, node, payload, waiting))
        return out

    def _judge(self, node: int, robot: int, where: int, payload: P,
               out: list[tuple[int, P]]) -> None:
        if in_range(self.parent, node, where):
            self.counters.deliveries += 1
            out.append((robot, payload))
        else:
            self.counters.refused += 1

    def _check(self, robot: int, node: int) -> None:
        if not 0 <= robot < self.robots:
            raise ValueError(f"robot {robot} is not one of 0..{self.robots - 1}")
        if not 0 <= node < len(self.parent):
            raise ValueError(f"node {node} is not in the tree (0..{len(self.parent) - 1})")

    def _forget_old_steps(self) -> None:
        # Every robot transmits only at its latest step, so no transmission can come for a
        # step below the slowest robot's: positions and held copies of those steps are dead.
        oldest = min(self._latest)
        for step in [s for s in self._nodes if s < oldest]:
            del self._nodes[step]
            self._held.pop(step, None)
