"""When a tree agent may decide step t, and which dead robots leave the team there (sans I/O).

A robot's death is applied at the first step whose report from it never comes: every robot
removes it at that step's boundary, then the team replica's next step repairs the trail
(planner.treecover.team). Whether the dead robot sent its report of step t is a fact about
its transmissions, not about who heard of the death when, and the radio delivers a
transmission of step t to every robot in range at step t, however late it gets there, which
then floods it through its connected part of the team. So once a death is known, a robot waits
``settle`` seconds for the dead robot's report (the delivery bound we assume), and if it has
not come the robot is absent from step t on for everyone (docs/treecover.md, "Trail repair").

Missing reports from live robots are waited for, except from robots that cannot be heard at
step t: those whose node is not connected to ours through nodes of live robots (a dead robot
relays nothing, so it can cut the team until the repair step).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class StepVerdict:
    """``ready``: step t can be decided; ``absent``: dead robots with no report of t, removed
    at its boundary; ``waiting_for``: robots still expected; ``wake_in``: seconds until the
    next death settles (None: only a report can change the verdict)."""

    ready: bool
    absent: tuple[int, ...]
    waiting_for: tuple[int, ...]
    wake_in: float | None


def reachable_nodes(parent: Sequence[int], occupied: Collection[int], start: int) -> set[int]:
    """Nodes of ``occupied`` connected to ``start`` through occupied nodes (tree edges)."""
    inside = set(occupied)
    if start not in inside:
        return set()
    children: dict[int, list[int]] = {}
    for v in inside:
        if parent[v] in inside:
            children.setdefault(parent[v], []).append(v)
    seen = {start}
    stack = [start]
    while stack:
        v = stack.pop()
        for w in (parent[v], *children.get(v, ())):
            if w in inside and w not in seen:
                seen.add(w)
                stack.append(w)
    return seen


def judge_step(parent: Sequence[int], positions: Sequence[int], alive: Sequence[bool],
               me: int, heard: Collection[int], lost_since: Mapping[int, float], now: float,
               settle: float) -> StepVerdict:
    """The verdict on the current step for robot ``me``: ``positions``/``alive`` are the
    replica's at that step, ``heard`` the robots whose report of it has arrived,
    ``lost_since`` when each robot known dead was learnt to be so."""
    relaying = [v for r, v in enumerate(positions)
                if alive[r] and (r == me or r not in lost_since)]
    mine = reachable_nodes(parent, relaying, positions[me])
    absent: list[int] = []
    waiting: list[int] = []
    wake_in: float | None = None
    for robot, node in enumerate(positions):
        if robot == me or not alive[robot] or robot in heard:
            continue
        if robot in lost_since:
            left = settle - (now - lost_since[robot])
            if left <= 0:
                absent.append(robot)
            else:
                waiting.append(robot)
                wake_in = left if wake_in is None else min(wake_in, left)
        elif node in mine:
            waiting.append(robot)
    return StepVerdict(not waiting, tuple(absent), tuple(waiting), wake_in)
