"""A tree-coverage mission as the wire shows it: the set-up the launcher repeats as its mission
status (tree, algorithm, team) and the robots' own reports, fed to the TeamObserver that
``mstc tree-fleet`` itself judges the run with. Pure; owned and fed by the fleet model."""

from __future__ import annotations

from dataclasses import dataclass

from bus import keys
from bus.messages import MissionStatus, TreeReport
from deploy.monitor.types import Record
from deploy.tree_observer import TeamObserver
from planner.errors import PlannerError
from planner.treecover.trees import tree_from_spec

# reports heard before the set-up: kept to be replayed once the tree is known
MAX_PENDING = 1 << 16


@dataclass(frozen=True)
class TreeSetup:
    tree: str
    algo: str
    robots: int


class TreeMission:
    """The tree run seen so far; ``observer`` is None until the set-up has been heard."""

    def __init__(self) -> None:
        self.setup: TreeSetup | None = None
        self.observer: TeamObserver | None = None
        self.unusable = ""  # why the announced tree cannot be built, if it cannot
        self.joined_at: int | None = None  # the first step heard, when it was not step 0
        self._pending: list[TreeReport] = []

    def on_status(self, status: MissionStatus) -> bool:
        """Take the set-up from a launcher's mission status; True when it is new."""
        info = status.summary
        if self.setup is not None or "tree" not in info:
            return False
        self.setup = TreeSetup(str(info["tree"]), str(info.get("algo", "cocta")),
                               int(info.get("robots", 0)))
        try:
            self.observer = TeamObserver(tree_from_spec(self.setup.tree), self.setup.robots)
        except (PlannerError, ValueError) as error:
            self.unusable = str(error)
            return True
        for report in self._pending:
            self._observe(report)
        self._pending.clear()
        return True

    def _observe(self, report: TreeReport) -> None:
        assert self.observer is not None
        if self.observer.complete == -1 and self.joined_at is None and report.step > 0:
            # A late joiner: the steps before are lost, and the first heard may be partly
            # so; judge from the next one on (coverage time and visits are then unknown).
            self.joined_at = report.step
            self.observer.complete = report.step
        self.observer.on_transmission(report)

    def on_report(self, record: Record, report: TreeReport) -> None:
        """A robot's transmission as the launcher hears it (the radio's deliveries, on the
        inboxes, are copies of these)."""
        parsed = keys.parse(record.key)
        if record.via != "sub" or parsed is None or parsed.kind != "tree/outbox":
            return
        if self.observer is not None:
            self._observe(report)
        elif self.setup is None and len(self._pending) < MAX_PENDING:
            self._pending.append(report)

    def line(self) -> str:
        """One line of figures ("" for a mission that is not a tree mission)."""
        seen = self.observer
        if self.setup is None:
            return ""
        if seen is None:
            return f"tree {self.setup.tree}: cannot be built ({self.unusable})"
        covered = "" if seen.coverage_time is None else f", covered at step {seen.coverage_time}"
        late = "" if self.joined_at is None else f" (heard from step {self.joined_at} on)"
        return (f"tree {self.setup.tree} ({self.setup.algo}, {self.setup.robots} robots): "
                f"step {max(seen.complete, 0)}, visited {seen.visited}/{len(seen.seen)} "
                f"nodes{late}{covered}")
