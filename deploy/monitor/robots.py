"""The robots as the monitor knows them: what their own messages, liveliness tokens and
simhw's ground truth said about each, and which robot a message is about. Pure; owned and
updated by the fleet model."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from bus import keys
from bus.messages import DeathNotice
from deploy.monitor.types import Record
from planner.offline.traffic import TrafficCounts
from planner.types import SubCell

Pose = tuple[int, int, int]


@dataclass
class RobotView:
    """One robot as far as the wire tells."""

    robot: int
    incarnation: int = 0
    start: SubCell | None = None
    algo: str = ""
    state: str = "unknown"
    pose: Pose | None = None
    path: list[SubCell] = field(default_factory=list)  # sub-cells entered (ground truth)
    truth_moves: int = 0  # moves from a WorldState answer (late joiners)
    reported_moves: int = 0  # the agent's own count (Progress, agent state)
    revisits: int = 0
    look_steps: int = 0  # entries made only to sense (ORMSTC's looks from beside)
    token: bool | None = None
    last_heartbeat: float | None = None
    token_lost: float | None = None
    death: DeathNotice | None = None
    failed: bool = False
    frozen: bool = False
    done: bool = False
    left: bool = False
    ended: str = ""  # "stopped" or "fenced": this life ended on an error
    took_over: list[int] = field(default_factory=list)
    # deconflicted walks (--recovery rebalance): waits, detours, bumps from its completion
    traffic: TrafficCounts | None = None
    messages: int = 0
    tree_kind: str = ""  # offline plans: the tree kind and seed from the agent's state
    seed: int = 0
    plan_digest: str = ""  # offline plans: the digest the agent announced (its first)

    @property
    def moves(self) -> int:
        return max(len(self.path) - 1, self.truth_moves, self.reported_moves, 0)

    @property
    def dead(self) -> bool:
        return not self.left and (self.failed or self.death is not None
                                  or self.token_lost is not None)

    @property
    def gone_by_token_only(self) -> bool:
        """Counted over only because its liveliness token vanished: no death notice, no
        failure, no completion, no leave (a link that dropped for a moment looks the same)."""
        return self.dead and not self.done and not self.failed and self.death is None


class Roster:
    """The robots heard of, by id; messages naming no valid robot are counted, not kept."""

    def __init__(self, invalid: Counter[str]) -> None:
        self.robots: dict[int, RobotView] = {}
        self._invalid = invalid  # the fleet model's counter of messages that make no sense
        self._parsed: dict[str, keys.ParsedKey | None] = {}

    def robot(self, robot: int) -> RobotView:
        view = self.robots.get(robot)
        if view is None:
            view = self.robots[robot] = RobotView(robot)
        return view

    def valid(self, record: Record, robot: Any, what: str) -> RobotView | None:
        """The robot a message is about, or None (counted) if the id or key disagree."""
        if isinstance(robot, bool) or not isinstance(robot, int) or robot < 0:
            self._invalid[f"{what}.robot"] += 1
            return None
        parsed = self.parse(record.key)
        if parsed is not None and parsed.robot is not None and parsed.robot != robot \
                and parsed.kind not in ("state", "death"):
            self._invalid[f"{what}.key"] += 1
            return None
        view = self.robot(robot)
        if record.via == "sub":
            view.messages += 1
        return view

    def verdict_of_the_dead(self, notice: DeathNotice, about: RobotView) -> bool:
        """A death notice of a robot already declared dead about one that is not: the fleet
        does not act on it (the far side of a healed partition), so neither does the picture."""
        by = notice.detected_by
        detector = None if by is None or by == notice.robot else self.robots.get(by)
        return detector is not None and detector.death is not None and about.death is None \
            and detector.death.incarnation >= detector.incarnation

    def parse(self, key: str) -> keys.ParsedKey | None:
        """keys.parse, cached: a mission has few distinct keys and each is heard often."""
        try:
            return self._parsed[key]
        except KeyError:
            parsed = self._parsed[key] = keys.parse(key)
            return parsed

    def positions(self) -> list[SubCell]:
        """Where robots started or stand: the seeds of what counts as reachable."""
        where = [v.start for v in self.robots.values() if v.start is not None]
        return where + [(v.pose[0], v.pose[1]) for v in self.robots.values() if v.pose]

    def counts(self) -> tuple[int, int, int, int]:
        """Robots (known, alive, dead, done)."""
        views = list(self.robots.values())
        dead = sum(v.dead for v in views)
        alive = sum(not v.dead and not v.left for v in views)
        return len(views), alive, dead, sum(v.done for v in views)
