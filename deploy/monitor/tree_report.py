"""``mstc report`` on a recording of ``mstc tree-fleet``: the robots' own reports replayed
into the launcher's TeamObserver, and the same verdict the launcher gives (deploy.tree_verdict)
against the lockstep run with the same deaths. The tree, algorithm and team size come from
the mission status the launcher repeats while the mission runs."""

from __future__ import annotations

from dataclasses import dataclass

from bus import keys
from bus.messages import DeathNotice, MissionStatus
from bus.tree_messages import TreeReport
from deploy.errors import RecordingError
from deploy.monitor.types import Recording
from deploy.tree_observer import TeamObserver
from deploy.tree_verdict import lockstep_run, summarize
from planner.treecover.trees import tree_from_spec


@dataclass(frozen=True)
class TreeSetup:
    tree: str
    algo: str
    robots: int


def tree_setup(recording: Recording) -> TreeSetup | None:
    """The tree mission's set-up, or None if this is not a recording of a tree mission."""
    for record in recording.records:
        msg = record.msg
        if isinstance(msg, MissionStatus) and "tree" in msg.summary:
            info = msg.summary
            return TreeSetup(str(info["tree"]), str(info.get("algo", "cocta")),
                             int(info.get("robots", 0)))
    if any(isinstance(r.msg, TreeReport) for r in recording.records):
        raise RecordingError("a tree-coverage recording without the launcher's mission status "
                             "(which tree, algorithm, team): it cannot be judged")
    return None


def build_tree_report(recording: Recording, setup: TreeSetup) -> dict[str, object]:
    """The tree-fleet summary (figures and verdict) recomputed from the recording alone."""
    tree = tree_from_spec(setup.tree)
    observer = TeamObserver(tree, setup.robots)
    dead: set[int] = set()
    for record in recording.records:
        msg = record.msg
        if isinstance(msg, TreeReport) and record.via == "sub":
            parsed = keys.parse(record.key)
            # what each robot transmitted, as the launcher hears it (not the radio's copies)
            if parsed is not None and parsed.kind == "tree/outbox":
                observer.on_transmission(msg)
        elif isinstance(msg, DeathNotice) and msg.reason != "leaving":
            dead.add(msg.robot)
    observer.finish(dead)
    seen = observer.run()
    lockstep, cuts = lockstep_run(tree, setup.robots, setup.algo, seen.deaths)
    return summarize(tree, lockstep, seen, lockstep_cuts=cuts)
