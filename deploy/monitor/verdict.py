"""A mission's verdict as a watcher can give it: the one its robots published, or, for the
families whose robots publish none (ORMSTC: each robot only announces its own completion;
tree coverage: each robot reports "done"), the one their own messages imply.

- Published: an offline robot that knows every sub-cell covered (or cannot plan) says so as
  the mission status; that verdict stands.
- Otherwise the mission is over once every robot heard of is done, dead or gone, and it is
  complete when the ground truth says so (every reachable sub-cell, every node of a tree),
  failed when it says some are left. Without any ground truth (no world state heard), the
  robots' own completions are the verdict, and the message says so.

Pure: reads a FleetModel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from deploy.monitor.model import FleetModel

VerdictState = Literal["complete", "failed"]


@dataclass(frozen=True)
class Verdict:
    state: VerdictState
    message: str
    published: bool  # True: a robot said it; False: read off the robots' messages


def mission_verdict(model: FleetModel) -> Verdict | None:
    """The final verdict, or None while the mission is still running (or nothing is known)."""
    published = model.mission
    if published is not None and published.state != "running":
        return Verdict(published.state, published.message, True)
    views = list(model.robots.values())
    if not views or not all(v.done or v.dead or v.left for v in views):
        return _tree_covered(model)
    done = sum(v.done for v in views)
    tree = _tree_covered(model)
    if tree is not None:
        return tree
    if model.tree.setup is not None:
        seen = model.tree.observer
        if model.tree.joined_at is not None and done == len(views):
            return Verdict("complete", f"every robot completed (heard from step "
                                       f"{model.tree.joined_at} on: coverage not judged)", False)
        visited = "" if seen is None else f" ({seen.visited}/{len(seen.seen)} nodes visited)"
        return Verdict("failed", f"every robot ended before the tree was covered{visited}",
                       False)
    total = model.total()
    ended = f"{done} of {len(views)} robots completed, the others are dead or gone"
    if done == len(views):
        ended = f"every robot completed ({done})"
    if model.cover.complete_at is not None:
        return Verdict("complete", f"{ended}; every reachable sub-cell is covered", False)
    if total:
        missing = total - model.covered_count()
        return Verdict("failed", f"{ended}; {missing} reachable sub-cells uncovered", False)
    if done == 0:
        return Verdict("failed", "every robot is dead or gone, none completed", False)
    return Verdict("complete", f"{ended} (coverage unknown: no world state heard)", False)


def _tree_covered(model: FleetModel) -> Verdict | None:
    seen, setup = model.tree.observer, model.tree.setup
    if seen is None or setup is None or seen.coverage_time is None:
        return None
    return Verdict("complete", f"every node of tree {setup.tree} visited by step "
                               f"{seen.coverage_time}", False)


def verdict_word(model: FleetModel) -> str:
    """"complete", "failed" or "running" (a word for one-line views)."""
    verdict = mission_verdict(model)
    return "running" if verdict is None else verdict.state
